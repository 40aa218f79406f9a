"""Failures in the open loop: the grid run's failures (same AGV, same tick, same repair
time) are replayed on physics; the time an AGV is down is the lost-time cause
``failures``, and the parts still add up exactly for every AGV."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import pytest

from warerover_phys import load_scenario
from warerover_phys.config import AgvTypeSpec, ExecutorSpec
from warerover_phys.execute import load_floor
from warerover_phys.gap.core import open_loop_gap
from warerover_phys.gap.ideal_plan import Failure, TimedPlan, record_grid_run
from warerover_phys.gap.open_loop import PARTS, execute_timed, open_loop_report
from warerover_phys.planning.paths import TimedPath

FAULT = "layouts/paper_fault.yaml"


def _corridor(failures: tuple[Failure, ...]) -> TimedPlan:
    """One AGV driving five cells east on a 1 x 6 corridor."""
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "c.map"
        p.write_text("type octile\nheight 1\nwidth 6\nmap\n......\n")
        layout, _, _ = load_floor(p)
    path = TimedPath(0, 0, tuple((c, c) for c in range(6)))
    spec = AgvTypeSpec(body_m=(0.7, 0.7), max_speed_mps=1.0, max_accel_mps2=1.0)
    return TimedPlan(layout=layout, types=[spec], tick_s=1.0, paths={0: path}, dwells={},
                     source="test", failures=failures)


def _add_up(agents: list[dict]) -> None:
    for a in agents:
        assert math.isclose(sum(a[f"lost_{p}_s"] for p in PARTS), a["lost_s"], abs_tol=1e-9)
        assert a["lost_failures_s"] >= 0


def test_a_failure_stops_the_agv_for_its_ticks():
    spec = ExecutorSpec(name="physics")
    _, plain, _ = open_loop_report(execute_timed(_corridor(()), spec))
    rep, down, _ = open_loop_report(execute_timed(_corridor((Failure(0, 2, 6),)), spec))
    assert rep["failures"] == 1 and rep["failure_down_ticks"] == 6
    a, b = plain[0], down[0]
    assert a["lost_failures_s"] == 0
    # down 6 s mid-run (braking and starting again are acceleration, not failure time)
    assert 6.0 <= b["lost_failures_s"] <= 6.0 + 1e-9
    assert b["executed_finish_s"] - a["executed_finish_s"] >= 6.0
    _add_up(plain + down)


def test_grid_run_failures_are_recorded():
    sc = load_scenario(FAULT).with_seed(0)
    plan = record_grid_run(sc)
    g = plan.grid_metrics
    assert len(plan.failures) >= 1
    assert all(f.ticks == 40 for f in plan.failures)  # faults.random.repair_ticks
    for f in plan.failures:  # it stands still (state FAILED = 7) while down on the grid
        assert all(int(plan.task_state[t, f.agv]) == 7
                   for t in range(f.tick + 1, min(f.tick + f.ticks, len(plan.task_state))))
    assert g.get("failures", len(plan.failures)) == len(plan.failures)


@pytest.mark.slow
def test_paper_fault_open_loop_replays_the_failures():
    g = open_loop_gap(load_scenario(FAULT), 0)
    rep = g.report
    assert rep["completed"] and rep["failures"] >= 1 and rep["deadlocks"] == 0
    assert rep["lost_failures_s_fleet_total"] > 0
    _add_up(g.agents)
