"""Turning sweeps (issue 13, fault 2): the swept-disc geometry, the ADG's ordering of
turns, and the physics executor with bodies whose turns leave their cell."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from warerover_phys import scenario_from_dict
from warerover_phys.executors.adg import ActionGraph, build
from warerover_phys.executors.physics import PhysicsExecutor
from warerover_phys.planning import TimedPath
from warerover_phys.planning.sweep import (
    BodyShape,
    Sweep,
    disc_overlaps_rect,
    discs_overlap,
    sweep_offsets,
    turn_locks,
    turn_sweeps,
)
from warerover_phys.planning.sweep_checks import check_fleet_sweeps, sweep_conflicts
from warerover_phys.sim import step_executor
from warerover_phys.world import World

# ----------------------------------------------------------------------------- geometry

coord = st.floats(-3, 3, allow_nan=False)
size = st.floats(0.01, 2, allow_nan=False)


@given(coord, coord, st.floats(0.01, 2), coord, coord, size, size)
def test_disc_rect_overlap_matches_dense_sampling(cx, cy, r, x0, y0, w, h):
    """Exact disc / rectangle test against points of the rectangle (a sampled point inside
    the disc means overlap; overlap means the nearest point is inside)."""
    x1, y1 = x0 + w, y0 + h
    got = disc_overlaps_rect(cx, cy, r, x0, y0, x1, y1)
    xs, ys = np.meshgrid(np.linspace(x0, x1, 41), np.linspace(y0, y1, 41))
    inside = np.hypot(xs - cx, ys - cy) < r - 1e-6
    if inside.any():
        assert got
    nx, ny = min(max(cx, x0), x1), min(max(cy, y0), y1)
    assert got == (math.hypot(nx - cx, ny - cy) < r - 1e-9)


@given(coord, coord, st.floats(0.01, 2), coord, coord, st.floats(0.01, 2))
def test_discs_overlap_is_symmetric_and_exact(ax, ay, ar, bx, by, br):
    assert discs_overlap(ax, ay, ar, bx, by, br) == discs_overlap(bx, by, br, ax, ay, ar)
    assert discs_overlap(ax, ay, ar, bx, by, br) == (math.hypot(ax - bx, ay - by)
                                                     < ar + br - 1e-9)


bodies = st.builds(lambda k, fl, fw, turns: BodyShape(k, round(fl * k, 2), round(fw * k, 2),
                                                      turns),
                   st.sampled_from([1, 2]), st.floats(0.3, 1.0), st.floats(0.3, 1.0),
                   st.booleans())


@settings(max_examples=60, deadline=None)
@given(bodies, bodies)
def test_every_reachable_straight_body_holds_a_swept_cell(a, b):
    """Soundness of the cell rule: for any placement of a non-turning body B (standing or
    driving one cell straight) that does not use the turner's cells, if B overlaps the
    turner's disc then B holds one of the swept cells. Checked by sampling B's rectangle."""
    if not a.turns:
        return
    fleet = tuple({a, b})
    cells = set(sweep_offsets(a, fleet, 1.0))
    k = a.k
    cx = cy = k / 2
    own = {(i, j) for i in range(k) for j in range(k)}
    hl, hw = b.length_m / 2, b.width_m / 2
    for ar in range(-4, k + 4):
        for ac in range(-4, k + 4):
            for dr, dc in ((0, 0), (0, 1), (1, 0), (0, -1), (-1, 0)):
                held = {(ar + i + x, ac + j + y) for x, y in ((0, 0), (dr, dc))
                        for i in range(b.k) for j in range(b.k)}
                if held & own:
                    continue
                qx, qy = ac + b.k / 2, ar + b.k / 2
                ex, ey = (hl, hw) if (dc or not b.turns) else (hw, hl)
                if b.turns and (dr, dc) == (0, 0):
                    continue  # a diff body standing may turn: the lock rule covers it
                x0, x1 = min(qx, qx + dc) - ex, max(qx, qx + dc) + ex
                y0, y1 = min(qy, qy + dr) - ey, max(qy, qy + dr) + ey
                if disc_overlaps_rect(cx, cy, a.radius_m, x0, y0, x1, y1):
                    assert cells & held, (a, b, ar, ac, dr, dc)


@settings(max_examples=60, deadline=None)
@given(bodies, bodies)
def test_turn_locks_are_mutual_and_cover_every_overlapping_turn(a, b):
    if not (a.turns and b.turns):
        return
    fleet = tuple({a, b})
    la, lb = set(turn_locks(a, fleet, 1.0)), set(turn_locks(b, fleet, 1.0))
    for ar in range(-4, 5):
        for ac in range(-4, 5):
            fa = {(i, j) for i in range(a.k) for j in range(a.k)}
            fb = {(ar + i, ac + j) for i in range(b.k) for j in range(b.k)}
            if fa & fb:
                continue
            if discs_overlap(a.k / 2, a.k / 2, a.radius_m, ac + b.k / 2, ar + b.k / 2,
                             b.radius_m):
                # A turn at (0, 0) and one at (ar, ac) share a lock.
                assert (ar, ac) in la and (-ar, -ac) in lb


def test_default_bodies_sweep_nothing_and_big_ones_do():
    d7 = BodyShape(1, 0.7, 0.7, True)
    assert sweep_offsets(d7, (d7,), 1.0) == () and turn_locks(d7, (d7,), 1.0) == ()
    d8 = BodyShape(1, 0.8, 0.8, True)
    assert turn_locks(d8, (d8,), 1.0) == ((-1, 0), (0, -1), (0, 0), (0, 1), (1, 0))
    d9 = BodyShape(1, 0.9, 0.9, True)  # 0.636 m: reaches an aligned neighbour's body
    assert sweep_offsets(d9, (d9,), 1.0) == ((-1, 0), (0, -1), (0, 1), (1, 0))
    big = BodyShape(2, 1.6, 1.6, True)
    assert len(turn_locks(big, (big,), 1.0)) > 1
    omni = BodyShape(2, 1.6, 1.6, False)
    assert sweep_offsets(omni, (omni, d8), 1.0) == () == turn_locks(omni, (omni, d8), 1.0)


# ----------------------------------------------------------------------------- ADG

SWEEP8 = Sweep((), ((-1, 0), (0, -1), (0, 0), (0, 1), (1, 0)))


def test_adg_orders_two_neighbours_turning_at_once():
    """AGVs 0 and 1 stand side by side facing east and both go north at tick 0: without
    sweeps both may start; with 0.8 m bodies the second waits until the first has moved."""
    cols = 4
    paths = {0: TimedPath(0, 0, ((5, 5), (1, 1))), 1: TimedPath(1, 0, ((6, 6), (2, 2)))}
    plain = build(paths, {0: 1, 1: 1}, cols)
    assert plain.ready(0) and plain.ready(1)
    g = ActionGraph(cols, {0: 1, 1: 1}, sweeps={0: SWEEP8, 1: SWEEP8}, rows=3)
    for agv in sorted(paths):
        g.set_plan(agv, paths[agv])
    g.check_acyclic()
    assert g.ready(0) and not g.ready(1)
    g.start(0)
    assert not g.ready(1)
    g.finish(0)
    assert g.ready(1)


def test_adg_no_sweep_for_a_straight_move():
    g = ActionGraph(4, {0: 1, 1: 1}, sweeps={0: SWEEP8, 1: SWEEP8}, rows=3)
    g.set_plan(0, TimedPath(0, 0, ((5, 5), (6, 6))))  # east: it already faces east
    g.set_plan(1, TimedPath(1, 0, ((9, 9), (5, 5))))  # north after 0 left: a turn
    assert g.next_action(0).sweeps == ()
    assert g.next_action(1).sweeps != ()


@settings(max_examples=80, deadline=None)
@given(st.data())
def test_adg_with_sweeps_stays_acyclic_and_orders_overlapping_turns(data):
    """Random plans on a 4 x 5 open grid that keep every turn's locks free of other turns
    at the same tick (the planner rule): the ADG has no cycle exactly when the plain one
    has none, and any two turns that share a lock are ordered (one's move finishes before
    the other's may start)."""
    rows, cols, n = 4, 5, data.draw(st.integers(2, 4))
    starts = data.draw(st.lists(st.integers(0, rows * cols - 1), min_size=n, max_size=n,
                                unique=True))
    paths = {}
    for agv, s in enumerate(starts):
        states = [(s, s)]
        for _ in range(data.draw(st.integers(1, 5))):
            here = states[-1][0]
            r, c = divmod(here, cols)
            opts = [here] + [(r + dr) * cols + c + dc for dr, dc in
                             ((0, 1), (1, 0), (0, -1), (-1, 0))
                             if 0 <= r + dr < rows and 0 <= c + dc < cols]
            nxt = data.draw(st.sampled_from(opts))
            states.append((nxt, nxt))
        paths[agv] = TimedPath(agv, 0, tuple(states))
    horizon = max(len(p.states) for p in paths.values()) + 1
    states = {a: [p.state_at(t) for t in range(horizon)] for a, p in paths.items()}
    from warerover_phys.validate import validate_states
    if validate_states(states, np.zeros((rows, cols), bool)):
        return
    turns = {a: turn_sweeps(s, cols) for a, s in states.items()}
    for a in turns:
        for b in turns:
            if a < b:
                for ta, na in turns[a]:
                    for tb, nb in turns[b]:
                        ra, ca = divmod(na, cols)
                        rb, cb = divmod(nb, cols)
                        if ta == tb and abs(ra - rb) + abs(ca - cb) <= 1:
                            return  # two overlapping turns at one tick: not a valid plan
    sizes = {a: 1 for a in paths}
    try:
        build(paths, sizes, cols)
        plain_ok = True
    except ValueError:
        plain_ok = False
    g = ActionGraph(cols, sizes, sweeps={a: SWEEP8 for a in paths}, rows=rows)
    for a in sorted(paths):
        g.set_plan(a, paths[a])
    try:
        g.check_acyclic()
        ok = True
    except ValueError:
        ok = False
    assert ok == plain_ok
    if not ok:
        return
    # Every pair of turns sharing a lock sits in one lock queue: ordered.
    actions = {a: [x for x in g.upcoming(a) if x.sweeps] for a in paths}
    for a in actions:
        for b in actions:
            if a < b:
                for x in actions[a]:
                    for y in actions[b]:
                        common = set(k for k in x.sweeps if k < 0) & set(
                            k for k in y.sweeps if k < 0)
                        for key in common:  # one queue orders them
                            assert {a, b} <= {v.agv for v in g.visits(key)}


# ----------------------------------------------------------------------------- validator

def test_sweep_conflicts_flag_a_turn_next_to_a_standing_agv():
    cols = 4
    traj = {0: [(5, 5), (1, 1)], 1: [(6, 6), (6, 6)]}
    off = {0: ((-1, 0), (0, -1), (0, 1), (1, 0))}
    found = sweep_conflicts(traj, 3, cols, {0: 1, 1: 1}, off)
    assert found and found[0].agvs == (0, 1) and found[0].cell == (1, 2)
    # Moving east (the heading it was placed with) is no turn: nothing to check.
    assert sweep_conflicts({0: [(5, 5), (6, 6)], 1: [(9, 9)]}, 3, cols, {}, off) == []


# ----------------------------------------------------------------------------- physics

OPEN = ["S....R",
        "......",
        "......",
        "......",
        "......"]
BARE = {"size": [5, 9], "stations": [[0, 5]],  # only a 2x2 shelf: 1x1 AGVs carry none
        "shelf_blocks": [{"origin": [0, 0], "size": 2}]}


def _two_turning(body: float) -> tuple[World, PhysicsExecutor]:
    w = World.build(scenario_from_dict({
        "layout": BARE,
        "fleet": {"types": {"t": {"body_m": [body, body], "max_turn_rate_radps": 1.0},
                            "big": {"footprint": 2, "body_m": [1.4, 1.4]}},
                  "agvs": [{"type": "t", "count": 2, "starts": [[3, 2], [3, 3]]},
                           {"type": "big", "count": 1, "starts": [[3, 7]]}]},
        "executor": {"name": "physics"}}))
    ex = PhysicsExecutor(w.scenario.executor)
    from warerover_phys.sim import executor_setup
    ex.bind(executor_setup(w))
    # Both face east and go north at tick 0: both turn in place next to each other.
    for agv, (r, c) in enumerate([(3, 2), (3, 3)]):
        path = [(r, c), (r - 1, c), (r - 2, c)]
        nodes = [w.node(x) for x in path]
        w.reservations.commit(TimedPath(agv, 0, tuple((n, n) for n in nodes)), 1)
    return w, ex


def _run(w: World, ex: PhysicsExecutor, ticks: int = 12) -> int:
    contacts = 0
    for _ in range(ticks):
        contacts += step_executor(w, ex).collisions
        w.tick += 1
    return contacts


def test_neighbours_turning_with_0_8_m_bodies_never_touch():
    """Fails before issue 13's sweep fix: two 0.8 m bodies turning at once side by side
    collided (and pushed each other)."""
    w, ex = _two_turning(0.8)
    assert _run(w, ex) == 0
    assert all(ex.adg.done(a) for a in (0, 1))


def test_check_fleet_sweeps_accepts_shipped_sizes():
    from warerover_phys.config import AgvTypeSpec
    assert check_fleet_sweeps({"a": AgvTypeSpec(body_m=(0.8, 0.8)),
                               "b": AgvTypeSpec(footprint=2, body_m=(1.6, 1.6))}, 1.0) == []


def test_check_command_rejects_a_sweep_into_the_static_world(tmp_path):
    from typer.testing import CliRunner

    from warerover_phys.cli import app

    runner = CliRunner()
    ok = runner.invoke(app, ["check", "layouts/paper_homogeneous.yaml"])
    assert ok.exit_code == 0, ok.output
    bad = runner.invoke(app, ["check", "layouts/paper_homogeneous.yaml", "--set",
                              "fleet.types.agv.body_m=[0.8,0.8]"])
    assert bad.exit_code != 0
    text = " ".join(bad.output.split())
    assert "fleet.types.agv" in text and "0.566 m" in text and "1.0 m cells" in text
    assert "Traceback" not in bad.output


# ----------------------------------------------------------------------------- carried shelves

def test_sweeps_hold_cells_where_a_carried_shelf_could_be_hit():
    """A 0.8 m body's disc (0.566 m) misses an aligned neighbour's 0.8 m body but reaches
    1.6 cm into the 0.9 m shelf it may carry (kept parallel to the grid): with shelves the
    turn holds the four edge neighbours; the default 0.7 m bodies still hold nothing."""
    d8 = BodyShape(1, 0.8, 0.8, True, shelf_m=0.9)
    assert sweep_offsets(d8, (d8,), 1.0) == ((-1, 0), (0, -1), (0, 1), (1, 0))
    d7 = BodyShape(1, 0.7, 0.7, True, shelf_m=0.9)
    assert sweep_offsets(d7, (d7,), 1.0) == () == turn_locks(d7, (d7,), 1.0)
    big = BodyShape(2, 1.4, 1.4, True, shelf_m=1.8)  # the paper's 2x2 AGVs
    assert sweep_offsets(big, (big, d7), 1.0) == ()
    from warerover_phys.executors.bodies import SHELF_SIDE
    from warerover_phys.planning.sweep import SHELF_BOX
    assert SHELF_BOX == SHELF_SIDE  # one shelf size for planners and physics


@settings(max_examples=60, deadline=None)
@given(bodies, bodies, st.sampled_from([0.0, 0.9]))
def test_every_reachable_carried_shelf_holds_a_swept_cell(a, b, frac):
    """Soundness with shelves: for any placement of a loaded neighbour (its shelf's box,
    axis-aligned, standing or driving one cell straight) outside the turner's cells, if the
    box overlaps the turner's disc then it holds one of the swept cells."""
    if not a.turns:
        return
    b = BodyShape(b.k, b.length_m, b.width_m, b.turns, shelf_m=frac * b.k)
    fleet = tuple({a, b})
    cells = set(sweep_offsets(a, fleet, 1.0))
    k = a.k
    cx = cy = k / 2
    own = {(i, j) for i in range(k) for j in range(k)}
    hs = b.shelf_m / 2
    if hs == 0:
        return
    for ar in range(-4, k + 4):
        for ac in range(-4, k + 4):
            for dr, dc in ((0, 0), (0, 1), (1, 0), (0, -1), (-1, 0)):
                held = {(ar + i + x, ac + j + y) for x, y in ((0, 0), (dr, dc))
                        for i in range(b.k) for j in range(b.k)}
                if held & own:
                    continue
                qx, qy = ac + b.k / 2, ar + b.k / 2
                x0, x1 = min(qx, qx + dc) - hs, max(qx, qx + dc) + hs
                y0, y1 = min(qy, qy + dr) - hs, max(qy, qy + dr) + hs
                if disc_overlaps_rect(cx, cy, a.radius_m, x0, y0, x1, y1):
                    assert cells & held, (a, b, ar, ac, dr, dc)


def test_turn_beside_a_loaded_neighbour_waits_for_it():
    """Fails on main before the carried-shelf sweeps: an 0.8 m body turning in place
    beside a neighbour that carries a 0.9 m shelf reached 1.6 cm into the shelf
    (``min_clearance_m`` -0.0157). Now the turn holds the neighbour's cell against loaded
    AGVs: the validator flags the plan that turns beside it, and the dependency graph lets
    the AGV turn only once the neighbour has driven off."""
    w = World.build(scenario_from_dict({
        "layout": {"grid": OPEN},
        "fleet": {"types": {"t": {"body_m": [0.8, 0.8], "max_turn_rate_radps": 1.0},
                            "slow": {"body_m": [0.8, 0.8], "max_speed_mps": 0.25}},
                  "agvs": [{"type": "t", "count": 2, "starts": [[3, 2], [3, 3]]},
                           {"type": "slow", "count": 1, "starts": [[3, 4]]}]},
        "executor": {"name": "physics", "shelf_sweeps": True}}))
    from warerover_phys.sim import executor_setup
    from warerover_phys.testing import plan_turn_conflicts
    from warerover_phys.world import Trip
    loaded = w.agvs[1]
    loaded.loaded, loaded.trip = True, Trip(0, 1, 0, (), ())
    ex = PhysicsExecutor(w.scenario.executor)
    ex.bind(executor_setup(w))
    n = w.node
    # AGV 0 faces east and goes north at tick 0 (a turn); AGV 1, loaded, stands beside it
    # until the slow AGV 2 has cleared (3, 4) (4 ticks), then follows it east.
    paths = {0: TimedPath(0, 0, tuple((n(c), n(c)) for c in [(3, 2), (2, 2), (1, 2)])),
             1: TimedPath(1, 0, ((n((3, 3)), n((3, 3))),) * 5 + ((n((3, 4)), n((3, 4))),)),
             2: TimedPath(2, 0, ((n((3, 4)), n((3, 4))),) + ((n((3, 4)), n((3, 5))),) * 3
                          + ((n((3, 5)), n((3, 5))),))}
    for p in paths.values():
        w.reservations.commit(p, 1)
    assert plan_turn_conflicts(w, paths, 0) == []  # no body is reached
    found = plan_turn_conflicts(w, paths, 0, loaded={0: False, 1: True, 2: False})
    assert [(c.kind, c.agvs, c.cell) for c in found][:1] == [("shelf_sweep", (0, 1), (3, 3))]
    assert plan_turn_conflicts(w, paths, 0, loaded={0: False, 1: False, 2: False}) == []
    assert _run(w, ex, 14) == 0
    assert all(ex.adg.done(a) for a in (0, 1, 2))
    clear = ex.acc.summary()["min_clearance_m"]
    assert clear is not None and clear > 0.01, clear


def test_agv_sweeps_hold_shelf_cells_apart():
    """On a floor with shelves the 0.8 m body's edge neighbours are shelf cells (held only
    against loaded AGVs), not cells; 0.7 m bodies hold nothing; no shelves, no shelf cells."""
    from warerover_phys.config import AgvTypeSpec
    from warerover_phys.planning.sweep import agv_sweeps
    w = World.build(scenario_from_dict({"layout": {"grid": OPEN}, "fleet": {
        "types": {"t": {"body_m": [0.8, 0.8]}},
        "agvs": [{"type": "t", "count": 1, "starts": [[3, 2]]}]}}))
    d8, d7 = AgvTypeSpec(body_m=(0.8, 0.8)), AgvTypeSpec(body_m=(0.7, 0.7))
    edge = ((-1, 0), (0, -1), (0, 1), (1, 0))
    assert agv_sweeps([d8], 1.0, w.layout) == {0: Sweep((), ((-1, 0), (0, -1), (0, 0),
                                                              (0, 1), (1, 0)), edge)}
    assert agv_sweeps([d8], 1.0)[0].shelf_cells == ()
    assert agv_sweeps([d7, d7], 1.0, w.layout) == {}


def test_adg_shelf_cells_hold_back_only_loaded_agvs():
    """AGV 0 turns (east -> north) beside AGV 1 standing east of it: with the neighbour
    unloaded it may go; loaded (or never told), it waits for the neighbour to leave; and a
    loaded AGV planned into a shelf cell after the turn waits for it, an unloaded one not."""
    sw = Sweep((), (), ((-1, 0), (0, -1), (0, 1), (1, 0)))
    cols = 4

    def graph():
        g = ActionGraph(cols, {0: 1, 1: 1}, sweeps={0: sw}, rows=3)
        g.set_plan(0, TimedPath(0, 0, ((5, 5), (1, 1))))
        g.set_plan(1, TimedPath(1, 0, ((6, 6), (6, 6), (7, 7))))
        return g

    g = graph()
    assert not g.ready(0)  # loads unknown: loaded
    g.set_loaded([False, False])
    assert g.ready(0) and g.ready(1)
    g.set_loaded([False, True])
    assert not g.ready(0) and g.ready(1)
    assert g.waiting_for() == {0: {1}}
    g.start(1)
    g.finish(1)
    assert g.ready(0)
    # AGV 1 comes to (1, 2) after the turn: loaded it waits for the turn, unloaded not.
    g = ActionGraph(cols, {0: 1, 1: 1}, sweeps={0: sw}, rows=3)
    g.set_plan(0, TimedPath(0, 0, ((5, 5), (1, 1))))
    g.set_plan(1, TimedPath(1, 0, ((7, 7), (7, 7), (6, 6))))
    g.set_loaded([False, True])
    g.check_acyclic()
    assert g.ready(0) and not g.ready(1)
    g.set_loaded([False, False])
    assert g.ready(1)


def test_check_rejects_loaded_turns_at_side_by_side_stations():
    """With 0.9 m shelves and ``executor.shelf_sweeps`` an 0.8 m body cannot turn beside a
    loaded neighbour: `check` says so for stations side by side (the padded floor: 0.8 m
    bodies clear its walls)."""
    from typer.testing import CliRunner

    from warerover_phys.cli import app

    runner = CliRunner()
    path = "tools/scenarios/paper_homogeneous_padded.yaml"
    assert runner.invoke(app, ["check", path]).exit_code == 0
    big = ["--set", "fleet.types.agv.body_m=[0.8,0.8]"]
    # Without executor.shelf_sweeps such turns go ahead (the overlap is reported): accepted.
    assert runner.invoke(app, ["check", path, *big]).exit_code == 0
    bad = runner.invoke(app, ["check", path, *big, "--set", "executor.shelf_sweeps=true"])
    assert bad.exit_code == 2
    text = " ".join(bad.output.split())
    assert "1.6 cm into the 0.9 m shelf" in text and "(4, 1) and (5, 1)" in text
    assert "Traceback" not in bad.output
