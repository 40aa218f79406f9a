"""Freeze detector and recovery (issue 13, fault 3): freezes are found, counted as deadlocks
with their tick and AGVs, broken by replanning from the actual poses, and every failed
episode names its cause."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as hst

from warerover_phys import load_scenario, run_episode
from warerover_phys.errors import ScenarioError
from warerover_phys.freeze import FreezeDetector

ROOT = Path(__file__).resolve().parents[1]
LAYOUTS = ROOT / "layouts"

SLOW_TURN_CBS = [("executor.name", "physics"), ("planner.name", "cbs"),
                 ("fleet.types.agv.max_turn_rate_radps", 0.3),
                 ("fleet.types.agv.max_accel_mps2", 0.2)]


def test_slow_turning_cbs_freeze_is_found_and_broken():
    """Seed 0 of the slow-turn CBS case stood still for good on main (SR 0.80 after 1,000
    ticks, AGVs 2 and 4 facing each other at station (9, 0), no cause reported)."""
    result = run_episode(load_scenario(LAYOUTS / "paper_homogeneous.yaml", SLOW_TURN_CBS),
                         seed=0)
    m = result.metrics
    assert m["success_rate"] == 1.0
    freezes = [e for e in result.events if e["event"] == "freeze"]
    assert freezes and m["freezes"] == len(freezes)
    assert m["deadlocks"] >= m["freezes"]
    for e in freezes:
        assert e["agvs"] and e["since"] <= e["tick"] - 30  # freeze_s = 30 s, tick_s = 1 s
    assert m["failure_cause"] is None


def test_failed_episode_names_its_cause():
    result = run_episode(load_scenario(LAYOUTS / "paper_homogeneous.yaml",
                                       [("max_ticks", 20)]), seed=1)
    m = result.metrics
    assert m["success_rate"] < 1.0
    assert m["failure_cause"] == "timeout" and "max_ticks 20" in m["failure_detail"]


FAULT_60 = [("max_ticks", 60), ("faults.random.prob_per_tick", 0.0),
            ("faults.orders_of_failed", "wait")]


def _fail_agv0_at(tick: int | None):
    extra = [] if tick is None else [("faults.scheduled",
                                      [{"agv": 0, "tick": tick, "repair_ticks": 500}])]
    return run_episode(load_scenario(LAYOUTS / "paper_fault.yaml", FAULT_60 + extra), seed=1)


def test_fault_at_the_end_is_the_cause():
    """AGV 0 fails for good one tick after its first trip starts (found by a run without
    the failure, so the case holds whatever the scheduler picks): it holds orders at the
    end, and the fault is the cause, naming AGV 0."""
    first = min(e["tick"] for e in _fail_agv0_at(None).events
                if e["event"] == "trip_started" and e["agv"] == 0)
    result = _fail_agv0_at(first + 1)
    assert any(e["event"] == "agv_failed" and e["agv"] == 0 and e["tick"] == first + 1
               for e in result.events)
    m = result.metrics
    assert m["success_rate"] < 1.0
    assert m["failure_cause"] == "fault"
    assert m["failure_detail"].startswith("AGVs [0] down at the end; ")


def test_a_fault_holding_no_orders_is_not_the_cause():
    """AGV 0 fails at tick 0, before any order is assigned: it holds none at the end, so
    the episode that runs out of ticks is a timeout, not a fault."""
    result = _fail_agv0_at(0)
    assert not any(e["event"] == "trip_started" and e["agv"] == 0 for e in result.events)
    m = result.metrics
    assert m["success_rate"] < 1.0
    assert m["failure_cause"] == "timeout"
    assert m["failure_detail"].startswith("max_ticks 60 reached; ")


def test_freeze_s_is_validated():
    with pytest.raises(ScenarioError) as err:
        load_scenario(LAYOUTS / "paper_homogeneous.yaml", [("executor.freeze_s", -1)])
    assert "executor.freeze_s" in str(err.value)
    with pytest.raises(ScenarioError):
        load_scenario(LAYOUTS / "paper_homogeneous.yaml", [("executor.freeze_sec", 5)])


def test_detector_off():
    result = run_episode(load_scenario(LAYOUTS / "paper_homogeneous.yaml",
                                       [*SLOW_TURN_CBS, ("executor.freeze_s", 0),
                                        ("max_ticks", 200)]), seed=0)
    assert result.metrics["freezes"] == 0


# ----------------------------------------------------------------------------- the detector


def _run(det, ticks, nodes, goals, waits, busy=None, failed=None, start=1):
    n = len(nodes)
    found = []
    for t in range(start, start + ticks):
        found += det.update(t, nodes, goals, busy or [False] * n, failed or [False] * n,
                            waits)
    return found


def test_detector_cycle_and_queue():
    det = FreezeDetector(3, 10, 5)
    # 0 and 1 wait on each other; 2 waits on 0: one group, found once per 5 ticks.
    found = _run(det, 6, [0, 1, 2], [9, 8, 7], {0: {1}, 1: {0}, 2: {0}})
    assert [f.agvs for f in found] == [(0, 1, 2)]
    assert found[0].since_tick == 1  # goals set (last progress) at tick 1, found at 6
    assert _run(det, 4, [0, 1, 2], [9, 8, 7], {0: {1}, 1: {0}, 2: {0}}, start=7) == []


def test_detector_waiting_on_a_mover_or_a_fault_is_no_freeze():
    det = FreezeDetector(2, 10, 3)
    nodes, goals = [0, 50], [9, 99]
    found = []
    for t in range(1, 10):
        nodes[1] = 50 + t  # AGV 1 progresses towards 59
        found += det.update(t, nodes, goals, [False, False], [False, False], {0: {1}})
    assert found == []
    det = FreezeDetector(2, 10, 3)
    assert _run(det, 8, [0, 50], [9, None], {0: {1}}, failed=[False, True]) == []
    # working in place: it will move again
    det = FreezeDetector(2, 10, 3)
    assert _run(det, 8, [0, 50], [9, None], {0: {1}}, busy=[False, True]) == []


@settings(max_examples=50, deadline=None)
@given(freeze=hst.integers(1, 8), ticks=hst.integers(1, 30), d0=hst.integers(1, 9))
def test_detector_never_fires_while_an_agv_gets_nearer(freeze, ticks, d0):
    """An AGV that comes one cell nearer at least every ``freeze`` ticks is never frozen;
    one that stands still is found exactly after ``freeze`` ticks."""
    det = FreezeDetector(1, 100, freeze)
    goal = 99
    node = goal - d0 - ticks
    found = []
    for t in range(1, ticks + 1):
        if t % freeze == 0:
            node += 1
        found += det.update(t, [node], [goal], [False], [False], {})
    assert found == []
    det = FreezeDetector(1, 100, freeze)
    found = _run(det, freeze + 1, [goal - d0], [goal], {})
    assert len(found) == 1 and found[0].agvs == (0,)
