"""Issue 38: python-fcl checks the safety corridors again (``faults.checker: fcl``), through
boolean box-box ``collide`` in AABB-tree managers, never the GJK/EPA signed distance that
aborted (issue 13). The closed form measures what fcl finds, so both checkers must give the
same intrusions and depths to the bit, and the same set of intruding pairs as shapely.

Every fcl query on random or degenerate poses runs in a worker subprocess
(``fcl_worker.py``): an abort shows as a failed example with the worker's exit status,
never as a dead pytest.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys import load_scenario
from warerover_phys.config import FaultsSpec
from warerover_phys.faults import (
    IntrusionChecker,
    box_rect_signed_distance,
    intrusions_shapely,
    make_checker,
)
from warerover_phys.faults.corridors import Corridor
from warerover_phys.sim import Simulation

ROOT = Path(__file__).resolve().parents[2]
EXE = Path(sys.executable).parent / "warerover"
WORKER = Path(__file__).resolve().parent / "fcl_worker.py"

ABORT_CMD = ["run", "layouts/paper_fault.yaml", "--executor", "physics", "--planner", "cbs",
             "--set", "executor.delays.model=bernoulli", "--set", "executor.delays.prob=0.1",
             "--set", "faults.random.prob_per_tick=0.02", "--seed", "2"]
ABORT_SETS = [("executor.name", "physics"), ("planner.name", "cbs"),
              ("executor.delays.model", "bernoulli"), ("executor.delays.prob", 0.1),
              ("faults.random.prob_per_tick", 0.02)]
"""The overrides of the issue 13 abort command, for in-process episodes."""


# --------------------------------------------------------------------------- the worker


class Worker:
    """One long-lived ``fcl_worker.py`` process; restarted after it dies."""

    def __init__(self) -> None:
        self.proc: subprocess.Popen | None = None
        self.err = tempfile.TemporaryFile(mode="w+")

    def ask(self, scene: dict) -> list:
        if self.proc is None or self.proc.poll() is not None:
            self.proc = subprocess.Popen([sys.executable, str(WORKER)], cwd=ROOT, text=True,
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                         stderr=self.err)
        line = json.dumps(scene)
        try:
            self.proc.stdin.write(line + "\n")
            self.proc.stdin.flush()
            out = self.proc.stdout.readline()
        except BrokenPipeError:
            out = ""
        if not out:
            rc = self.proc.wait(timeout=60)
            self.err.seek(0)
            tail = self.err.read()[-2000:]
            self.err.seek(0)
            self.err.truncate()
            self.proc = None
            raise AssertionError(f"fcl worker died with exit {rc} on scene {line}\n{tail}")
        return json.loads(out)

    def close(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.stdin.close()
            self.proc.wait(timeout=60)
        self.err.close()


@pytest.fixture(scope="module")
def worker():
    w = Worker()
    yield w
    w.close()


def corridors_of(scene: dict) -> list[Corridor]:
    out = []
    for c in scene["corridors"]:
        poly = shapely.box(*c["rects"][0])
        out.append(Corridor(id=c["id"], agv=0, access=(0, 0), route=((0, 0),),
                            rects=tuple(tuple(r) for r in c["rects"]), margin_m=c["margin"],
                            polygon=poly, zone=poly, cells=frozenset()))
    return out


# ----------------------------------------------------------------------------- scenes

# Micrometre grids give exact ties (shared centres, touching and collinear edges) often;
# sizes include zero (a segment or a point) and nanometre slivers; a whole scene may be
# shifted to huge coordinates.
coord = st.integers(-50_000_000, 50_000_000).map(lambda i: i / 1e6)
size = st.one_of(st.just(0.0), st.sampled_from([1e-9, 1e-7]),
                 st.integers(0, 3_000_000).map(lambda i: i / 1e6))
margin = st.one_of(st.sampled_from([0.0, 0.2]), st.integers(0, 500_000).map(lambda i: i / 1e6))
angle = st.one_of(st.sampled_from([0.0, math.pi / 2, math.pi, -math.pi, math.pi / 4,
                                   -3.0708, 1e-12, 2 * math.pi]),
                  st.floats(-10.0, 10.0, allow_nan=False))
axis_angle = st.sampled_from([0.0, math.pi / 2, math.pi, -math.pi, 2 * math.pi])
offset = st.sampled_from([0.0, 0.0, 0.0, 1e4, -1e6, 1e7])


@st.composite
def rects(draw, before: list) -> list:
    out = []
    for _ in range(draw(st.integers(1, 3))):
        if before and draw(st.booleans()):  # share a corner / an edge line with another
            px0, py0, px1, py1 = draw(st.sampled_from(before))
            x0, y0 = draw(st.sampled_from([(px1, py0), (px0, py1), (px1, py1), (px0, py0)]))
        else:
            x0, y0 = draw(coord), draw(coord)
        r = (x0, y0, x0 + 2 * draw(size), y0 + 2 * draw(size))
        out.append(r)
        before.append(r)
    return out


@st.composite
def pose(draw, half: tuple, placed: list, corridors: list) -> list:
    """A pose for a body of ``half``: free, centred on a rectangle, touching its grown
    edge or corner, diagonally off its grown corner at any heading, or the same as another
    body's."""
    how = draw(st.sampled_from(["free", "centred", "touch_x", "touch_y", "corner", "diagonal",
                                "same"]))
    c = draw(st.sampled_from(corridors))
    x0, y0, x1, y1 = draw(st.sampled_from(c["rects"]))
    m = c["margin"] if draw(st.booleans()) else 0.0
    if how == "same" and placed:
        return list(draw(st.sampled_from(placed)))
    if how == "centred":
        return [(x0 + x1) / 2, (y0 + y1) / 2, draw(angle)]
    if how == "touch_x":
        a = draw(axis_angle)
        hx = half[1] if abs(math.sin(a)) > 0.5 else half[0]
        return [x1 + m + hx, (y0 + y1) / 2 + draw(coord) / 20, a]
    if how == "touch_y":
        a = draw(axis_angle)
        hy = half[0] if abs(math.sin(a)) > 0.5 else half[1]
        return [(x0 + x1) / 2 + draw(coord) / 20, y0 - m - hy, a]
    if how == "corner":
        a = draw(axis_angle)
        hx, hy = (half[1], half[0]) if abs(math.sin(a)) > 0.5 else half
        return [x1 + m + hx, y1 + m + hy, a]
    if how == "diagonal":  # off the grown corner, turned: only the box's rotation decides
        t = draw(st.sampled_from([0.0, 0.1, 0.3])) * max(half)
        return [x1 + m + t, y1 + m + t, draw(st.one_of(st.just(math.pi / 4), angle))]
    return [draw(coord), draw(coord), draw(angle)]


@st.composite
def scenes(draw) -> dict:
    """AGVs and corridors, often degenerate, and two pose sets: the second moves, turns or
    keeps each body (the fcl checker moves only what changed)."""
    seen: list = []
    corridors = [{"id": 3 * k + 1, "rects": draw(rects(seen)), "margin": draw(margin)}
                 for k in range(draw(st.integers(1, 3)))]
    n = draw(st.integers(1, 6))
    half = [(draw(size), draw(size)) for _ in range(n)]
    first: list = []
    for i in range(n):
        first.append(draw(pose(half[i], first, corridors)))
    second = []
    for i in range(n):
        change = draw(st.sampled_from(["keep", "new", "turn", "shift"]))
        p = list(first[i])
        if change == "new":
            p = draw(pose(half[i], first, corridors))
        elif change == "turn":
            p[2] = draw(angle)
        elif change == "shift":
            p[0] += draw(st.sampled_from([1e-6, -1e-9, 0.5]))
        second.append(p)
    skip = sorted(draw(st.sets(st.integers(0, n - 1), max_size=n)))
    if skip and draw(st.booleans()):  # a skipped body may stand nowhere
        second[skip[0]] = [math.nan, math.nan, math.nan]
    shift = draw(offset)
    for c in corridors:
        c["rects"] = [[x0 + shift, y0 + shift, x1 + shift, y1 + shift]
                      for x0, y0, x1, y1 in c["rects"]]
    poses = [[[x + shift, y + shift, a] for x, y, a in ps] for ps in (first, second)]
    return {"half": half, "corridors": corridors, "poses": poses, "skip": skip}


def closed_form_sd(scene: dict, poses: np.ndarray, live: list[int]) -> dict:
    """(agv, corridor id) -> (closed-form signed distance, margin), every live pair."""
    half = np.array(scene["half"], dtype=float).reshape(-1, 2)
    out = {}
    for c in scene["corridors"]:
        for a in live:
            r = np.array(c["rects"], dtype=float)
            m = len(r)
            sd = box_rect_signed_distance(np.repeat(poses[a:a + 1, :2], m, 0),
                                          np.repeat(poses[a, 2], m), np.repeat(half[a:a + 1], m, 0),
                                          r)
            out[(a, c["id"])] = (float(sd.min()), c["margin"])
    return out


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                   HealthCheck.data_too_large])
@given(scenes())
def test_fcl_checker_never_aborts_and_agrees_on_degenerate_scenes(worker, scene):
    """The fcl checker, in a subprocess, on degenerate scenes: it answers (no abort), its
    intrusions equal the numpy checker's exactly (pairs and depths), and its set of
    intruding pairs equals shapely's wherever a pair is not within rounding of the margin
    (``|sd - margin| <= 1e-9 x scale``: there either answer is right)."""
    got = worker.ask(scene)  # fails with the exit status if fcl took the worker down
    half = np.array(scene["half"], dtype=float).reshape(-1, 2)
    corridors = corridors_of(scene)
    numpy_chk = IntrusionChecker(half)
    numpy_chk.set_corridors(corridors)
    skip = set(scene["skip"])
    live = [a for a in range(len(half)) if a not in skip]
    for poses_l, fcl_hits in zip(scene["poses"], got, strict=True):
        poses = np.array(poses_l, dtype=float).reshape(-1, 3)
        want = [[h.agv, h.corridor, h.depth_m] for h in numpy_chk.check(poses, skip)]
        assert fcl_hits == want
        scale = 1.0 + float(np.abs(poses[np.isfinite(poses)]).max(initial=0.0) + max(
            np.abs(np.array(c["rects"])).max() for c in scene["corridors"]))
        sd = closed_form_sd(scene, poses, live)
        band = {k for k, (d, m) in sd.items() if abs(d - m) <= 1e-9 * scale}
        ref_poses = np.where(np.isfinite(poses), poses, 0.0)
        ref = {(h.agv, h.corridor): h.depth_m
               for h in intrusions_shapely(ref_poses, half, corridors, skip)}
        mine = {(a, c): d for a, c, d in fcl_hits}
        assert set(mine) - band == set(ref) - band
        for k in set(mine) & set(ref):
            assert mine[k] == pytest.approx(ref[k], abs=1e-9 * scale)


def test_the_issue_13_pose_through_fcl(worker):
    """The pose libccd's GJK/EPA aborted on (a 0.7 m box centred on the 1 m footprint
    rectangle, heading ~ -3.07 rad) through fcl's box-box path: measured, not aborted."""
    ang = math.atan2(-0.07073720166770651463, -0.99749498660405411243)
    scene = {"half": [[0.35, 0.35], [0.35, 0.35]],
             "corridors": [{"id": 0, "rects": [[8.0, 3.0, 9.0, 4.0], [8.0, 0.0, 9.0, 4.0]],
                            "margin": 0.2}],
             "poses": [[[8.5, 3.5, ang], [8.4999999999999982236, 3.5, ang]]], "skip": [0]}
    ((hit,),) = worker.ask(scene)
    half_x = 0.35 * (abs(math.cos(ang)) + abs(math.sin(ang)))
    assert hit[:2] == [1, 0]
    assert hit[2] == pytest.approx(0.2 + 0.5 + half_x, abs=1e-9)


HAIRS = [  # (rectangle, margin, pose, half size): touching at the margin, heading 2 pi
    ((-5.507324, -25.184618, -2.789026, -22.318699000000002), 0.2,
     (-0.9742829999999996, -20.522249000000002, 2 * math.pi), (1.614743, 1.79645)),
    ((-2.631712, -6.462714, -1.3387969999999998, -4.0605329999999995), 0.0,
     (-1.2253219999999998, -5.698403271547247, 2 * math.pi), (0.113475, 0.99102)),
    ((-10.278186, 7.648672, -7.618385, 8.195439), 0.3,
     (-6.4797780000000005, 9.959497, 2 * math.pi), (0.838607, 1.764058)),
]
"""Found by a search with the fcl rectangles grown by the margin alone (no slack): the
closed form puts these bodies 1e-16 m inside the margin, fcl's rounding puts its box just
outside the grown rectangle."""


@pytest.mark.parametrize("rect, margin, pose, half", HAIRS)
def test_pairs_a_rounding_hair_inside_the_margin_are_found(worker, rect, margin, pose, half):
    """fcl's rectangles reach ``slack_m`` beyond the margin, so a pair the closed form puts
    a rounding error inside is still proposed (without the slack fcl missed these)."""
    scene = {"half": [list(half)], "corridors": [{"id": 4, "rects": [list(rect)],
                                                   "margin": margin}],
             "poses": [[list(pose)]], "skip": []}
    ((hit,),) = worker.ask(scene)
    assert hit[:2] == [0, 4] and 0 < hit[2] < 1e-15


def test_fcl_checker_follows_moves_turns_and_corridor_changes():
    """One fcl checker over a sequence: bodies that only turn, only move, stand still or
    leave; corridors replaced; a body turning in place into the margin (only its new
    rotation reaches it); a body at 45 degrees off a corner and its mirror image (a box
    turned the wrong way misses). Each answer equals a fresh numpy checker's (a checker that forgot
    a turn or a move would keep a stale box and miss a pair)."""
    half = np.array([[0.45, 0.05], [0.3, 0.3], [0.45, 0.05]])
    a = make_checker("fcl", half)
    rect = (0.0, 0.0, 2.0, 1.0)
    poly = shapely.box(*rect)
    cor = Corridor(id=5, agv=9, access=(0, 0), route=((0, 0),), rects=(rect,), margin_m=0.1,
                   polygon=poly, zone=poly, cells=frozenset())
    far = Corridor(id=6, agv=9, access=(0, 0), route=((0, 0),), rects=((10.0, 0.0, 11.0, 1.0),),
                   margin_m=0.1, polygon=poly, zone=poly, cells=frozenset())
    steps = [  # edges at x = 2 (+ margin 0.1)
        ([cor], [[2.3, 0.5, 0.0], [5.0, 5.0, 0.0], [2.56, 0.5, 0.0]]),  # 0 in, 2 0.11 off
        ([cor], [[2.3, 0.5, math.pi / 2], [5.0, 5.0, 0.0], [2.56, 0.5, 0.0]]),  # 0 turns out
        ([cor], [[2.3, 0.5, math.pi / 2], [2.35, 0.5, 0.0], [2.54, 0.5, 0.0]]),  # 1, 2 move in
        ([cor], [[2.3, 0.5, 0.0], [2.35, 0.5, 0.0], [2.54, 0.5, math.pi / 2]]),  # 0 in, 2 out
        ([far], [[2.3, 0.5, 0.0], [10.5, 1.2, 0.0], [2.54, 0.5, math.pi / 2]]),  # new corridor
        ([cor], [[1.0, 1.5, 0.0], [5.0, 5.0, 0.0], [5.0, 8.0, 0.0]]),  # 0 above, 0.45 m off
        ([cor], [[1.0, 1.5, math.pi / 2], [5.0, 5.0, 0.0], [5.0, 8.0, 0.0]]),  # 0 turns: 0.05 m in
        ([cor], [[2.3, 1.3, math.pi / 4], [5.0, 5.0, 0.0], [5.0, 8.0, 0.0]]),  # 0 at the corner
        ([cor], [[2.3, 1.3, 3 * math.pi / 4], [5.0, 5.0, 0.0], [5.0, 8.0, 0.0]]),  # mirrored: out
    ]
    seen = []
    for cors, poses in steps:
        a.set_corridors(cors)
        ref = IntrusionChecker(half)
        ref.set_corridors(cors)
        got = a.check(np.array(poses))
        assert got == ref.check(np.array(poses))
        seen.append([(h.agv, h.corridor) for h in got])
    assert seen == [[(0, 5)], [], [(1, 5), (2, 5)], [(0, 5), (1, 5)], [(1, 6)], [],
                    [(0, 5)], [(0, 5)], []]


def _box_corridor(cid: int, rect: tuple, margin: float) -> Corridor:
    poly = shapely.box(*rect)
    return Corridor(id=cid, agv=99, access=(0, 0), route=((0, 0),), rects=(rect,),
                    margin_m=margin, polygon=poly, zone=poly, cells=frozenset())


@pytest.mark.parametrize("kind", ["fcl", "numpy"])
def test_the_boundary_rule_is_strict_for_both_checkers(kind):
    """A pair intrudes when ``sd < margin`` (binary fractions: no rounding). Margin 0.25:
    an edge exactly 0.25 m off is out, 2^-20 m nearer is in; a corner 0.2 m off on both
    axes (0.28 m away) is out although it is inside the rectangle grown by the margin (fcl's
    box). Margin 0: touching along an edge or at a corner is out, 2^-20 m of overlap is in."""
    eps = 2.0 ** -20
    chk = make_checker(kind, np.tile([0.5, 0.25], (6, 1)))
    chk.set_corridors([_box_corridor(1, (0.0, 0.0, 2.0, 1.0), 0.25),
                       _box_corridor(2, (10.0, 0.0, 12.0, 1.0), 0.0)])
    poses = np.array([[2.75, 0.5, 0.0], [2.75 - eps, 0.5, 0.0], [2.7, 1.45, 0.0],
                      [12.5, 0.5, 0.0], [12.5 - eps, 0.5, 0.0], [12.5, 1.25, math.pi]])
    got = [(h.agv, h.corridor, h.depth_m) for h in chk.check(poses)]
    assert got == [(1, 1, pytest.approx(eps, abs=1e-15)), (4, 2, pytest.approx(eps, abs=1e-15))]


def test_make_checker_and_the_config_field():
    half = np.array([[0.3, 0.2]])
    assert make_checker("fcl", half).name == "fcl"
    assert make_checker("numpy", half).name == "numpy"
    with pytest.raises(ValueError, match="faults.checker"):
        make_checker("gjk", half)
    assert FaultsSpec().checker == "numpy"  # the faster one (tools/bench_intrusion.py)
    sc = load_scenario(str(ROOT / "layouts/paper_fault.yaml"), [("faults.checker", "fcl")])
    assert sc.faults.checker == "fcl"


def test_a_bad_checker_name_is_one_clear_line():
    r = subprocess.run([str(EXE), "run", "layouts/paper_fault.yaml", "--set",
                        "faults.checker=gjk", "--quiet"], capture_output=True, text=True,
                       cwd=ROOT, timeout=120)
    assert r.returncode == 2
    assert "faults.checker" in r.stderr and "gjk" in r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1


# --------------------------------------------------------------------------- episodes

TIMING = {"wall_s", "real_time_factor"}


def episode(sets: list, checker: str, seed: int, max_ticks: int | None = None) -> dict:
    """One in-process episode with ``faults.checker = checker``: its metrics (wall-clock
    figures left out), events and every corridor check's hits (full precision)."""
    extra = [("faults.checker", checker)]
    if max_ticks is not None:
        extra.append(("max_ticks", max_ticks))
    sim = Simulation(load_scenario(str(ROOT / "layouts/paper_fault.yaml"), sets + extra), seed)
    checks: list = []

    def keep(*_):
        checks.extend([list(c) for c in sim.last_report.intrusion_checks])

    res = sim.run(progress=keep)
    used = sim.executor.acc._checker
    return {"metrics": {k: v for k, v in res.metrics.items()
                        if k not in TIMING and not k.startswith("ct_")},
            "events": res.events, "checks": checks,
            "checker": None if used is None else used.name}


def assert_same_episode(sets: list, seed: int, max_ticks: int | None = None) -> int:
    """Both checkers on one episode: identical; returns the hits of all its checks (and
    prints the seed's figures: ``pytest -s`` shows them)."""
    a = episode(sets, "fcl", seed, max_ticks)
    b = episode(sets, "numpy", seed, max_ticks)
    assert (a["checker"], b["checker"]) == ("fcl", "numpy")
    assert a["checks"] == b["checks"]
    assert a["events"] == b["events"]
    assert a["metrics"] == b["metrics"]
    hits = sum(len(c) for c in a["checks"])
    depth = max((d for c in a["checks"] for _, _, d in c), default=0.0)
    print(f"seed {seed}: {hits} hits in {len(a['checks'])} checks, deepest {depth:.4f} m, "
          f"{a['metrics']['corridor_intrusions']} intrusions, "
          f"{a['metrics']['corridor_intrusion_agv_s']} intrusion AGV-s; identical")
    return hits


@pytest.mark.slow  # whole fault episodes, once per checker: make test-all
def test_fault_episodes_identical_with_either_checker():
    """Three short episodes (80 ticks) of the issue 13 abort configuration (physics, CBS,
    delays, frequent failures): every corridor check's hits, every event and every metric
    equal with either checker; every episode finds AGVs inside corridors."""
    hits = [assert_same_episode(ABORT_SETS, seed, max_ticks=80) for seed in (0, 2, 3)]
    assert min(hits) > 0, hits


@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_issue_13_command_identical_with_either_checker(tmp_path):
    """The exact issue 13 command with ``faults.checker`` fcl and numpy: both exit 0, same
    events, same metrics but for wall-clock figures; intrusions found."""
    outs = {}
    for checker in ("fcl", "numpy"):
        out = tmp_path / checker
        r = subprocess.run([str(EXE), *ABORT_CMD, "--set", f"faults.checker={checker}",
                            "--out", str(out), "--quiet"], capture_output=True, text=True,
                           cwd=ROOT, timeout=900)
        assert r.returncode == 0, (checker, r.returncode, r.stderr[-2000:])
        metrics = json.loads((out / "metrics.json").read_text())
        outs[checker] = ({k: v for k, v in metrics.items()
                          if k not in TIMING and not k.startswith("ct_")},
                         (out / "events.jsonl").read_text())
    assert outs["fcl"] == outs["numpy"]
    assert outs["fcl"][0]["corridor_intrusions"] > 0


@pytest.mark.slow
@pytest.mark.timeout(7200)
@pytest.mark.parametrize("sets", [ABORT_SETS, [("executor.name", "physics")]],
                         ids=["abort-config", "paper-fault-physics"])
def test_fault_scenarios_20_seeds_identical_with_either_checker(sets):
    """The abort configuration and the paper's fault scenario on physics, 20 seeds each,
    whole episodes: identical checks, events and metrics with either checker."""
    hits = [assert_same_episode(sets, seed) for seed in range(20)]
    assert sum(hits) > 0
