"""The open-loop gap: the ideal run's plan executed unchanged on physics, dwells held,
lost time split into causes whose parts add up to the total for every AGV."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys import load_scenario
from warerover_phys.config import AgvTypeSpec, DelaySpec, ExecutorSpec
from warerover_phys.execute import load_floor
from warerover_phys.gap.core import gap_report, open_loop_gap
from warerover_phys.gap.ideal_plan import Dwell, TimedPlan, record_grid_run
from warerover_phys.gap.open_loop import PARTS, compare, execute_timed, open_loop_report
from warerover_phys.planning.paths import TimedPath

HOMO = "layouts/paper_homogeneous.yaml"
HETERO = "layouts/paper_heterogeneous.yaml"


def _assert_parts_add_up(g) -> None:
    """Every AGV's parts sum to its lost time, every action's parts to its interval's."""
    assert g.report["completed"]
    for a in g.agents:
        parts = sum(a[f"lost_{p}_s"] for p in PARTS)
        assert math.isclose(parts, a["lost_s"], abs_tol=1e-9), a
        assert math.isclose(a["lost_s"], a["executed_finish_s"] - a["planned_finish_s"],
                            abs_tol=1e-9)
        assert a["lost_dwell_overrun_s"] == 0.0  # a dwell lasts exactly its planned time
        assert a["lost_faster_than_plan_s"] <= 0 and a["lost_plan_waits_skipped_s"] <= 0
        assert a["lost_reorder_gain_s"] <= 0
        for p in PARTS[:-3]:
            assert a[f"lost_{p}_s"] >= 0, (p, a)
    for act in g.actions:
        parts = sum(act[f"lost_{p}_s"] for p in PARTS)
        assert math.isclose(parts, act["interval_lost_s"], abs_tol=1e-9), act
    # fleet total and per-AGV mean are labelled and consistent
    n = len(g.agents)
    for p in PARTS:
        tot = g.report[f"lost_{p}_s_fleet_total"]
        assert math.isclose(tot, sum(a[f"lost_{p}_s"] for a in g.agents), abs_tol=1e-9)
        assert math.isclose(g.report[f"lost_{p}_s_per_agv_mean"], tot / n, abs_tol=1e-9)


@pytest.mark.parametrize("path,seed", [(HOMO, 0), (HOMO, 3), (HETERO, 2), (HETERO, 7)])
def test_lost_time_parts_add_up_for_every_agv(path, seed):
    g = open_loop_gap(load_scenario(path), seed)
    _assert_parts_add_up(g)
    r = g.report
    assert r["mode"] == "open-loop"
    assert r["deadlocks"] == 0 and r["agv_contacts"] == 0
    assert r["makespan_ratio"] > 1.0  # acceleration and turns cost more than 1.5 m/s gains
    # at 1.5 m/s the body beats the plan's one cell per tick on straight runs
    assert r["lost_faster_than_plan_s_fleet_total"] < 0


@pytest.mark.slow
@pytest.mark.parametrize("path", [HOMO, HETERO])
def test_lost_time_parts_add_up_over_ten_seeds(path):
    sc = load_scenario(path)
    for seed in range(10):
        _assert_parts_add_up(open_loop_gap(sc, seed))


def test_dwells_are_held_on_physics():
    """Every pick, hand-over, place and parking lasts at least its planned ticks from the
    AGV's arrival: the dependency graph skips plain waits, not dwells."""
    g = open_loop_gap(load_scenario(HETERO), 2)
    plan = g.run.plan
    kinds = {d.kind for ds in plan.dwells.values() for d in ds}
    assert {"pick", "handover", "place"} <= kinds
    by = {(a["agv"], a["seq"]): a for a in g.actions}
    checked = 0
    for i in range(plan.num_agents):
        for pa in plan.actions(i):
            if not pa.dwell:
                continue
            arrive = by[(i, pa.seq - 1)]["executed_finish_s"] if pa.seq else 0.0
            start = by[(i, pa.seq)]["executed_start_s"]
            assert start - arrive >= pa.dwell * plan.tick_s - 1e-9, (i, pa)
            checked += 1
    assert checked > 20


def _corridor_plan(dwell_ticks: int) -> TimedPlan:
    """One AGV on a 1 x 6 corridor: two cells east, a dwell, three more cells east."""
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "c.map"
        p.write_text("type octile\nheight 1\nwidth 6\nmap\n......\n")
        layout, _, _ = load_floor(p)
    cells = [0, 1, 2] + [2] * dwell_ticks + [3, 4, 5]
    path = TimedPath(0, 0, tuple((c, c) for c in cells))
    dwells = {0: (Dwell(0, 2, dwell_ticks, "pick", 2),)} if dwell_ticks else {}
    spec = AgvTypeSpec(body_m=(0.7, 0.7), max_speed_mps=1.5, max_accel_mps2=1.0)
    return TimedPlan(layout=layout, types=[spec], tick_s=1.0, paths={0: path},
                     dwells=dwells, source="test")


def test_a_dwell_stops_a_straight_run_and_holds_its_ticks():
    """Regression: without dwells in the view the physics AGV drives through the pick cell
    (the three waiting ticks are skipped) and finishes ~3 s early."""
    spec = ExecutorSpec(name="physics")
    held = execute_timed(_corridor_plan(3), spec)
    agents, actions, _ = compare(held)
    a2, a3 = actions[1], actions[2]
    assert a3["executed_start_s"] - a2["executed_finish_s"] >= 3.0 - 1e-9
    assert actions[2]["planned_dwell_ticks"] == 3
    assert agents[0]["lost_dwell_overrun_s"] == 0
    assert math.isclose(sum(agents[0][f"lost_{p}_s"] for p in PARTS), agents[0]["lost_s"],
                        abs_tol=1e-9)
    plain = execute_timed(_corridor_plan(0), spec)
    _, plain_actions, _ = compare(plain)
    # the same moves with no dwell: one straight run, no stop at cell 2
    assert plain_actions[-1]["executed_finish_s"] + 3.0 < actions[-1]["executed_finish_s"]


def test_recorded_plan_replays_exactly_on_the_grid():
    """The recorded plan of a grid run, executed open loop on the grid executor, visits the
    same states at the same ticks (the grid needs no holds: it follows the ticks)."""
    plan = record_grid_run(load_scenario(HETERO).with_seed(2))
    run = execute_timed(plan, ExecutorSpec(name="grid"), seed=2)
    assert run.completed
    for i, path in plan.paths.items():
        got = run.executed[i][:len(path.states)]
        assert got == list(path.states), i
    assert run.log is None
    with pytest.raises(ValueError, match="physics"):
        compare(run)


def test_recorded_dwells_match_the_scenario_task_times():
    sc = load_scenario(HOMO).with_seed(1)
    plan = record_grid_run(sc)
    work = [d for ds in plan.dwells.values() for d in ds if d.kind != "park"]
    assert work and all(d.ticks <= 2 for d in work)  # pick / hand-over / place: 2 ticks
    assert sum(d.ticks == 2 for d in work) >= 0.9 * len(work)
    assert plan.grid_metrics["success_rate"] == 1.0
    for p in plan.paths.values():
        assert p.states[-1][0] == p.states[-1][1]  # every path ends standing


def test_modes_are_labelled():
    sc = load_scenario(HOMO, [("max_ticks", 40)])
    closed = gap_report(sc, 1, mode="closed")
    assert closed["mode"] == "closed-loop"
    assert "delay_dependency_wait_s_fleet_total" in closed
    assert "delay_dependency_wait_s_per_agv_mean" in closed
    with pytest.raises(ValueError, match="mode"):
        gap_report(sc, 1, mode="sideways")


# 6 examples: each example executes a plan on the physics executor
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(prob=st.floats(0.0, 0.3), seed=st.integers(0, 10_000), dwell=st.integers(0, 4))
def test_parts_add_up_under_injected_delays(prob, seed, dwell):
    """Property: with random injected delays the parts still add up exactly, injected
    delays show up only as ``injected`` (or are absorbed by dwells and planned waits)."""
    spec = ExecutorSpec(name="physics", delays=DelaySpec(model="bernoulli", prob=prob,
                                                         min_ticks=1, max_ticks=3))
    run = execute_timed(_corridor_plan(dwell), spec, seed=seed)
    agents, actions, _ = compare(run)
    a = agents[0]
    assert a["completed"]
    assert math.isclose(sum(a[f"lost_{p}_s"] for p in PARTS), a["lost_s"], abs_tol=1e-9)
    for act in actions:
        assert math.isclose(sum(act[f"lost_{p}_s"] for p in PARTS), act["interval_lost_s"],
                            abs_tol=1e-9)
    if prob == 0.0:
        assert a["lost_injected_s"] == 0.0


def test_report_figures_are_consistent():
    g = open_loop_gap(load_scenario(HOMO), 1)
    r, _, _ = open_loop_report(g.run)
    pf = [a["planned_finish_s"] for a in g.agents]
    ef = [a["executed_finish_s"] for a in g.agents]
    assert r["planned_makespan_s"] == max(pf) and r["executed_makespan_s"] == max(ef)
    assert math.isclose(r["makespan_ratio"], max(ef) / max(pf))
    assert math.isclose(r["sum_of_costs_ratio"], sum(ef) / sum(pf))
    assert r["orders"] == 20 and 0 < r["tp_ratio"] < 1
    assert np.isclose(r["lost_s_fleet_total"], sum(ef) - sum(pf))
    for a in g.agents:
        assert sum(s for _, s in a["top_blockers"]) <= a["dependency_wait_s"] + 1e-9


def test_a_move_starts_with_the_plans_cargo():
    """The cargo an AGV has when a move starts is the plan's at that move's tick: a shelf
    put down stays behind (no loaded AGV drives into the next shelf's cell: seed 1 counted
    2 such contacts when the cargo lagged a tick behind a dwell ending mid-tick), a shelf
    picked up comes along."""
    from warerover_phys.gap.ideal_plan import repair_rotations

    sc = load_scenario(HOMO).with_seed(1)
    plan = repair_rotations(record_grid_run(sc, None))
    log: list = []

    def hook(tick, ex):
        if not log:
            step = ex.step

            def logged(view):
                report = step(view)
                log.append((view.carried, dict(report.states)))
                return report
            ex.step = logged
            log.append(None)

    run = execute_timed(plan, sc.with_executor("physics").executor, seed=1, before_tick=hook)
    assert run.summary["static_contacts"] == 0
    n = plan.num_agents
    acts = {i: plan.actions(i) for i in range(n)}
    done = [0] * n
    before: dict = {}
    starts = 0
    for carried, states in log[1:]:
        for i, (a, b) in states.items():
            if a != b and before.get(i) != (a, b):  # a move began during this tick
                j = next(j for j in range(done[i], len(acts[i]))
                         if (acts[i][j].src, acts[i][j].dst) == (a, b))
                done[i] = j
                want = int(plan.carried[acts[i][j].tick, i])
                assert carried[i] == (None if want < 0 else want), (i, acts[i][j])
                starts += 1
        before = states
    assert starts >= sum(len(a) for a in acts.values()) // 2
