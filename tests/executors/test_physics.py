"""The physics executor: kinematic limits against analytic times, ADG-safe execution under
random delays, naive following for comparison, outputs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys import load_scenario, scenario_from_dict
from warerover_phys.executors.physics import PhysicsExecutor
from warerover_phys.planning import TimedPath
from warerover_phys.sim import executor_setup, run_episode, step_executor
from warerover_phys.world import World

CORRIDOR = ["P...........R",
            "P.SS.........",
            "P............"]


def world(n: int = 1, drive: str = "diff", **agv) -> World:
    spec = {"max_speed_mps": 1.5, "max_accel_mps2": 1.0, "max_turn_rate_radps": 2.5,
            "drive": drive, **agv}
    return World.build(scenario_from_dict({
        "layout": {"grid": CORRIDOR},
        "fleet": {"types": {"t": spec}, "agvs": [{"type": "t", "count": n}]},
        "executor": {"name": "physics"}}))


def force(w: World, agv: int, cells: list[tuple[int, int]], tick: int = 0) -> None:
    nodes = [w.node(c) for c in cells]
    w.reservations.commit(TimedPath(agv, tick, tuple((n, n) for n in nodes)), w.agvs[agv].k)


def drive_until_done(w: World, ex: PhysicsExecutor, agv: int, max_ticks: int = 60) -> float:
    """Step until the AGV has no action left and stands still; return the simulated time at
    which its last action finished."""
    for _ in range(max_ticks):
        step_executor(w, ex)
        w.tick += 1
        if ex.adg.done(agv) and ex.mode[agv] == 0:
            return ex.last_finish[agv]
    raise AssertionError("AGV did not finish")


def trapezoid_time(d: float, v: float, a: float) -> float:
    if d >= v * v / a:
        return d / v + v / a
    return 2 * math.sqrt(d / a)


@pytest.mark.parametrize(("v", "a"), [(1.5, 1.0), (1.0, 0.5), (2.0, 2.0)])
def test_straight_ten_cells_matches_the_trapezoidal_profile(v, a):
    w = world(max_speed_mps=v, max_accel_mps2=a)
    start = w.cell(w.agvs[0].node)
    assert start == (0, 0)
    # Down the parking column first would turn; go right along row 0.
    force(w, 0, [(0, c) for c in range(0, 11)])
    ex = PhysicsExecutor(w.scenario.executor)
    ex.bind(executor_setup(w))
    t = drive_until_done(w, ex, 0)
    expected = trapezoid_time(10.0, v, a)
    assert abs(t - expected) / expected < 0.02, (t, expected)
    x, y = ex.fleet.bodies[0].position
    assert abs(x - 10.5) < 0.02 and abs(y - 0.5) < 0.02
    s = ex.summary()
    assert s["agv_contacts"] == 0 and s["actions_executed"] == 10
    assert s["delay_turns_s"] == 0.0


def test_a_ninety_degree_turn_takes_angle_over_turn_rate():
    w = world(max_turn_rate_radps=1.2)
    force(w, 0, [(0, 0), (1, 0)])  # heading 0 (+x) -> moving down (+y): a 90 degree turn
    ex = PhysicsExecutor(w.scenario.executor)
    ex.bind(executor_setup(w))
    drive_until_done(w, ex, 0)
    expected = (math.pi / 2) / 1.2
    turn = ex.summary()["delay_turns_s"]
    assert abs(turn - expected) / expected < 0.02, (turn, expected)
    assert abs(_wrap(ex.fleet.bodies[0].angle - math.pi / 2)) < 0.02


def test_omnidirectional_agvs_do_not_turn():
    w = world(drive="omni")
    force(w, 0, [(0, 0), (1, 0), (1, 1)])
    ex = PhysicsExecutor(w.scenario.executor)
    ex.bind(executor_setup(w))
    drive_until_done(w, ex, 0)
    assert ex.summary()["delay_turns_s"] == 0.0
    assert abs(ex.fleet.bodies[0].angle) < 0.02


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def test_speed_and_acceleration_limits_hold():
    w = world(max_speed_mps=1.0, max_accel_mps2=0.5)
    force(w, 0, [(0, c) for c in range(0, 9)])
    ex = PhysicsExecutor(w.scenario.executor)
    ex.bind(executor_setup(w))
    speeds = []
    for _ in range(30):
        step_executor(w, ex)
        w.tick += 1
        speeds.append(ex.fleet.bodies[0].velocity.length)
    assert max(speeds) <= 1.0 * 1.02
    traj = ex.trajectory()
    x = traj["x"][:, 0]
    v = np.diff(x) / np.diff(traj["t"])
    acc = np.diff(v) / np.diff(traj["t"])[1:]
    assert np.abs(acc).max() <= 0.5 * 1.15


def test_follower_waits_for_the_leader_through_the_adg():
    """AGV 1 follows AGV 0 one cell behind; AGV 0 is held by an injected stop: the follower
    must wait (dependency wait), never touch it."""
    w = world(n=2, drive="omni")
    a0, a1 = w.cell(w.agvs[0].node), w.cell(w.agvs[1].node)
    assert (a0, a1) == ((0, 0), (1, 0))
    force(w, 0, [(0, c) for c in range(0, 8)])
    force(w, 1, [(1, 0), (0, 0)] + [(0, c) for c in range(1, 7)], tick=0)
    ex = PhysicsExecutor(w.scenario.executor)
    ex.bind(executor_setup(w))
    step_executor(w, ex)
    w.tick += 1
    ex.delayed_until[0] = ex.sim_s + 5.0  # AGV 0 stops for 5 s
    for _ in range(30):
        step_executor(w, ex)
        w.tick += 1
    s = ex.summary()
    assert s["agv_contacts"] == 0
    assert s["delay_dependency_wait_s"] > 1.0
    assert ex.adg.done(0) and ex.adg.done(1)
    assert w.cell(w.agvs[1].node) == (0, 6)


def delayed(path: str, adg: bool = True, seed: int = 0, **extra):
    sc = load_scenario(path, [("executor.name", "physics"), ("executor.adg", adg),
                              ("executor.delays.model", "bernoulli"),
                              ("executor.delays.prob", 0.02),
                              ("executor.delays.max_ticks", 10),
                              *extra.items()])
    return run_episode(sc, seed=seed).metrics


@pytest.mark.parametrize("scenario", [
    "layouts/paper_homogeneous.yaml",
    # ~24 s: the mixed fleet under delays is also in the physics fuzz and test_dwells
    pytest.param("layouts/paper_heterogeneous.yaml", marks=pytest.mark.slow)])
def test_adg_execution_with_delays_finishes_without_contacts(scenario):
    for seed in range(3):
        m = delayed(scenario, seed=seed)
        assert m["success_rate"] == 1.0, (seed, m)
        assert m["agv_contacts"] == 0, (seed, m)
        assert m["delay_injected_s"] > 0


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["layouts/paper_homogeneous.yaml",
                                      "layouts/paper_heterogeneous.yaml"])
def test_adg_execution_with_delays_fifty_seeds(scenario):
    bad = []
    for seed in range(50):
        m = delayed(scenario, seed=seed)
        if m["success_rate"] != 1.0 or m["agv_contacts"] != 0:
            bad.append((seed, m["success_rate"], m["agv_contacts"]))
    assert bad == []


@pytest.mark.slow  # 34 s; the ADG runs with delays stay in the default set
def test_without_the_adg_delays_cause_contacts_or_blocking():
    """The same delayed episodes, followed naively by the clock: the report counts what
    the ADG prevents."""
    with_adg = naive = 0
    for seed in range(3):
        m = delayed("layouts/paper_homogeneous.yaml", seed=seed)
        with_adg += m["agv_contacts"]
        n = delayed("layouts/paper_homogeneous.yaml", adg=False, seed=seed)
        naive += n["agv_contacts"] + n["static_contacts"] + n["deadlocks"]
    assert with_adg == 0
    assert naive > 0


def test_same_seed_same_physics():
    a = delayed("layouts/paper_homogeneous.yaml", seed=4)
    b = delayed("layouts/paper_homogeneous.yaml", seed=4)
    from warerover_phys.metrics import TIMING_KEYS

    skip = set(TIMING_KEYS)
    assert {k: v for k, v in a.items() if k not in skip} == \
        {k: v for k, v in b.items() if k not in skip}


# ----------------------------------------------------------------------------- random instances


@st.composite
def small_scenarios(draw):
    """A small floor with a shelf row, a station column and parking, 2-5 AGVs (some
    omnidirectional, some slower), a few one-shot orders and random delays."""
    rows = draw(st.integers(5, 7))
    cols = draw(st.integers(7, 10))
    grid = [["." for _ in range(cols)] for _ in range(rows)]
    for c in range(2, cols - 2):
        if draw(st.booleans()):
            grid[2][c] = "S"
    if not any(ch == "S" for ch in grid[2]):
        grid[2][3] = "S"
    grid[0][cols - 1] = "R"
    if draw(st.booleans()):
        grid[rows - 3][cols - 1] = "R"
    n = draw(st.integers(2, 5))
    for c in range(n):
        grid[rows - 1][c] = "P"
    if draw(st.booleans()):
        grid[rows - 2][cols - 2] = "#"
    fast = {"max_speed_mps": draw(st.sampled_from([1.0, 1.5, 2.0])), "drive": "diff"}
    slow = {"max_speed_mps": 0.75, "max_accel_mps2": 0.5, "drive": "omni"}
    n_slow = draw(st.integers(0, n - 1))
    return scenario_from_dict({
        "max_ticks": 600,
        "layout": {"grid": ["".join(r) for r in grid]},
        "fleet": {"types": {"fast": fast, "slow": slow},
                  "agvs": [{"type": "fast", "count": n - n_slow}]
                  + ([{"type": "slow", "count": n_slow}] if n_slow else [])},
        "orders": {"pattern": "oneshot", "oneshot": {"count": draw(st.integers(2, 6))}},
        "scheduler": draw(st.sampled_from(["ta", "rd"])),
        "planner": draw(st.sampled_from(["astar", "cbs"])),
        "executor": {"name": "physics", "delays": {
            "model": draw(st.sampled_from(["bernoulli", "poisson"])),
            "prob": draw(st.sampled_from([0.02, 0.05])),
            "duration": draw(st.sampled_from(["uniform", "gaussian"])), "max_ticks": 10},
            "speed_scale": [0.8, 1.0]},
        "seed": draw(st.integers(0, 1000)),
    })


@pytest.mark.slow  # 29 s (15 physics episodes)
# 15 examples: each example is a whole physics episode
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(small_scenarios())
def test_random_small_instances_finish_without_contacts(scenario):
    m = run_episode(scenario).metrics
    assert m["success_rate"] == 1.0, m
    assert m["agv_contacts"] == 0, m


@pytest.mark.slow  # a physics episode through the CLI as a subprocess: make test-all
def test_run_on_physics_writes_trajectories_and_gap_report(tmp_path):
    import json
    import subprocess
    import sys
    from pathlib import Path

    exe = Path(sys.executable).parent / "warerover"
    out = tmp_path / "run"
    r = subprocess.run([str(exe), "run", "layouts/paper_heterogeneous.yaml", "--executor",
                        "physics", "--seed", "2", "--out", str(out), "--quiet"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    traj = np.load(out / "trajectories.npz")
    m = json.loads((out / "metrics.json").read_text())
    n = m["agvs"]
    assert traj["x"].shape == (len(traj["t"]), n) and traj["heading"].shape == traj["x"].shape
    assert abs(traj["t"][-1] - m["ticks"] * 1.0) < 0.2  # recorded to the end at 10 Hz
    assert np.all(np.diff(traj["t"]) > 0)
    # AGVs stay on the floor (x, y in metres inside the 20 x 15 map).
    assert traj["x"].min() > 0 and traj["x"].max() < 20 and traj["y"].max() < 15
    g = subprocess.run([str(exe), "gap", "layouts/paper_homogeneous.yaml", "--seed", "1",
                        "--json", "--out", str(tmp_path / "gap.json")],
                       capture_output=True, text=True)
    assert g.returncode == 0, g.stderr
    report = json.loads(g.stdout)
    for key in ("makespan_ratio", "tp_ratio", "latency_ratio", "agv_contacts",
                "static_contacts", "min_separation_m", "deadlocks", "replans",
                "real_time_factor", "delay_dependency_wait_s", "delay_kinematic_s",
                "delay_injected_s"):
        assert key in report
    assert report["makespan_ratio"] > 1.0  # physics is slower than the ideal grid
    saved = json.loads((tmp_path / "gap.json").read_text())
    assert saved["physics"]["ticks"] == report["makespan_physics_ticks"]


@pytest.mark.parametrize("path", sorted(str(p) for p in __import__("pathlib").Path(
    "layouts").glob("*.yaml")))
def test_every_shipped_scenario_runs_on_physics(path):
    sc = load_scenario(path, [("executor.name", "physics"), ("max_ticks", 15)])
    m = run_episode(sc, seed=0).metrics
    assert m["ticks"] == 15 and m["agv_contacts"] == 0 and m["static_contacts"] == 0
    assert m["actions_executed"] > 0
