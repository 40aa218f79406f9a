"""Anchored dwells: a stage's work starts only at rest on the stage's goal, the AGV holds the
goal during the dwell, and the events agree with the motion (issue 13, fault 4)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hst

from warerover_phys import load_scenario, run_episode
from warerover_phys.validate import (
    DWELL_HEADING_TOL_RAD,
    DWELL_POS_TOL_M,
    dwell_intervals,
    validate_dwells,
)

ROOT = Path(__file__).resolve().parents[1]
LAYOUTS = ROOT / "layouts"
SHIPPED = sorted(p.name for p in LAYOUTS.glob("*.yaml"))


def load(name: str, *overrides):
    return load_scenario(LAYOUTS / name, list(overrides))


def dwell_violations(result):
    return validate_dwells(result.events, result.world.layout.cols, actual=result.actual,
                           trajectory=result.trajectory)


# ----------------------------------------------------------------------------- the reported case


def test_shelf_picked_where_the_agv_stands_on_the_shelf():
    """paper_heterogeneous, seed 2, astar, grid: AGV 8 (2x2) passed shelf 16's anchor (9, 6)
    at ticks 8-9 on a path that went on, and ``shelf_picked`` came at tick 11 at (8, 6).
    Now the pick starts only once its path has ended on the anchor, and every tick of the
    pick is spent there."""
    result = run_episode(load("paper_heterogeneous.yaml", ("planner.name", "astar"),
                              ("executor.name", "grid")), seed=2)
    w = result.world
    cols = w.layout.cols
    anchor = w.layout.shelves[16].anchor
    node = anchor[0] * cols + anchor[1]
    picked = [e for e in result.events if e["event"] == "shelf_picked" and e["agv"] == 8]
    assert picked and picked[0]["shelf"] == 16
    t = picked[0]["tick"]
    pick_ticks = w.scenario.tasks.pick_ticks
    # On the anchor for the whole pick: the tick it began and every tick up to the event.
    for tick in range(t - pick_ticks, t + 1):
        assert result.actual[8][tick] == (node, node), (tick, result.actual[8][tick])
    # The path it had when the pick began ends there (no move planned after it).
    started = [e for e in result.events if e["event"] == "work_started" and e["agv"] == 8]
    assert started[0]["tick"] == t - pick_ticks and started[0]["cell"] == list(anchor)
    assert dwell_violations(result) == []


def test_work_waits_for_a_path_that_passes_the_goal():
    """The committed path of the reported case passes the goal before it ends there: no
    work may start while later moves remain."""
    from warerover_phys.sim import Simulation

    sim = Simulation(load("paper_heterogeneous.yaml", ("planner.name", "astar")), seed=2)
    w = sim.world
    seen_pass = False
    while not sim.done and w.tick < 40:
        sim.step()
        agv = w.agvs[8]
        path = w.reservations.paths[8]
        ahead = path.states[max(0, w.tick - agv.delay - path.start_tick):]
        moves_left = any(a != b or a != agv.node for a, b in ahead)
        if agv.standing and agv.node == w.goal_of(agv) and moves_left:
            seen_pass = True
        if agv.state.name == "PICKING":
            assert not moves_left
    assert seen_pass, "the case no longer passes the goal: the test shows nothing"


@pytest.mark.parametrize("planner", ["astar", "pibt"])
def test_physics_holds_the_goal_pose_during_dwells(planner):
    result = run_episode(load("paper_heterogeneous.yaml", ("planner.name", planner),
                              ("executor.name", "physics")), seed=2)
    assert result.metrics["success_rate"] == 1.0
    assert len(dwell_intervals(result.events)) > 20
    assert dwell_violations(result) == []


# ----------------------------------------------------------------------------- every scenario


def _brief(name: str, executor: str, planner: str):
    ticks = 40 if name == "industrial.yaml" else 120
    return load(name, ("executor.name", executor), ("planner.name", planner),
                ("max_ticks", ticks))


# On physics each episode takes ~5 s: astar runs in the default set for every scenario,
# pibt and cbs in the slow set.
@pytest.mark.parametrize("planner,executor", [
    ("astar", "grid"), ("pibt", "grid"), ("cbs", "grid"), ("astar", "physics"),
    pytest.param("pibt", "physics", marks=pytest.mark.slow),
    pytest.param("cbs", "physics", marks=pytest.mark.slow)])
@pytest.mark.parametrize("name", [n for n in SHIPPED if n != "industrial.yaml"])
def test_every_dwell_is_on_its_goal(name, executor, planner):
    result = run_episode(_brief(name, executor, planner), seed=1)
    assert dwell_intervals(result.events), "no dwell to check"
    assert dwell_violations(result) == []


@pytest.mark.slow
@pytest.mark.parametrize("executor", ["grid", "physics"])
def test_every_dwell_is_on_its_goal_industrial(executor):
    result = run_episode(_brief("industrial.yaml", executor, "pibt"), seed=1)
    assert dwell_intervals(result.events), "no dwell to check"
    assert dwell_violations(result) == []


# ----------------------------------------------------------------------------- the validator


def _events(dwells):
    out = []
    for agv, t0, t1, cell in dwells:
        out.append({"tick": t0, "event": "work_started", "agv": agv, "stage": "pick",
                    "cell": list(cell)})
        out.append({"tick": t1, "event": "work_done", "agv": agv, "stage": "pick",
                    "cell": list(cell)})
    return sorted(out, key=lambda e: e["tick"])


@settings(max_examples=60, deadline=None)
@given(t0=hst.integers(0, 20), length=hst.integers(0, 5), off=hst.integers(-3, 8))
def test_grid_validator_flags_exactly_a_move_inside_the_dwell(t0, length, off):
    cols, node = 5, 7
    t1 = t0 + length
    states = [(node, node)] * 30
    bad = t0 + off
    states[bad] = (node, node + 1)
    found = validate_dwells(_events([(0, t0, t1, divmod(node, cols))]), cols,
                            actual={0: states})
    assert bool(found) == (t0 <= bad <= t1)
    if found:
        assert found[0].tick == bad and found[0].agv == 0


def test_physics_validator_tolerance():
    tick_s, cell_m = 1.0, 1.0
    t = np.arange(0, 10.01, 0.1)
    x = np.full((len(t), 1), 2.5)
    y = np.full((len(t), 1), 1.5)
    h = np.zeros((len(t), 1))
    traj = {"t": t, "x": x, "y": y, "heading": h, "footprint": np.array([1]),
            "cell_m": np.array(cell_m), "tick_s": np.array(tick_s)}
    events = _events([(0, 3, 5, (1, 2))])
    assert validate_dwells(events, 5, trajectory=traj) == []
    x[42, 0] += DWELL_POS_TOL_M * 0.9  # inside the tolerance
    assert validate_dwells(events, 5, trajectory=traj) == []
    x[42, 0] += DWELL_POS_TOL_M * 0.2  # just outside
    found = validate_dwells(events, 5, trajectory=traj)
    assert len(found) == 1 and found[0].tick == pytest.approx(4.2)
    x[42, 0] = 2.5
    h[31:, 0] = DWELL_HEADING_TOL_RAD * 1.5  # turns during the dwell
    assert len(validate_dwells(events, 5, trajectory=traj)) == 1
    h[:, 0] = DWELL_HEADING_TOL_RAD * 1.5  # a constant heading is held: fine
    assert validate_dwells(events, 5, trajectory=traj) == []
    x[60:, 0] = 9.0  # leaves after the dwell: not checked
    assert validate_dwells(events, 5, trajectory=traj) == []


def test_dwell_intervals_pair_events_and_parking():
    events = _events([(1, 2, 4, (0, 0)), (0, 3, 3, (1, 1))])
    events.append({"tick": 9, "event": "parked", "agv": 2, "cell": [2, 2]})
    events.append({"tick": 10, "event": "work_started", "agv": 3, "stage": "place",
                   "cell": [0, 1]})
    assert dwell_intervals(events) == [(1, "pick", 2, 4, (0, 0)), (0, "pick", 3, 3, (1, 1)),
                                       (2, "park", 9, 9, (2, 2))]
    assert dwell_intervals(events, end_tick=12)[-1] == (3, "place", 10, 12, (0, 1))
