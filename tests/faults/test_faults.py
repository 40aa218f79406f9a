"""Failures and safety corridors: the paper's fault scenario, order invariants through
failures, intrusion checks that can fail, on-demand failures, bad input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys import load_scenario, scenario_from_dict
from warerover_phys.errors import ScenarioError
from warerover_phys.planning.base import TimedPath, occupancy
from warerover_phys.sim import Simulation, run_episode, step_executor
from warerover_phys.world import AgvState, OrderStatus

FAULT = "layouts/paper_fault.yaml"


def fault_run(planner: str, executor: str, seed: int) -> dict:
    sc = load_scenario(FAULT, [("planner.name", planner), ("executor.name", executor)])
    return run_episode(sc, seed=seed).metrics


def check_corridor_figures(m: dict) -> None:
    """What the corridor figures must satisfy whatever happened."""
    assert m["corridor_caught_inside"] == (m["corridor_exits_within_bound"]
                                           + m["corridor_exits_overrun"]), m
    assert 0 <= m["corridor_intrusion_agv_s"] <= m["corridor_inside_agv_s"], m


# On physics each takes 30-40 s: in the slow set (the random fuzz test of
# tests/faults/test_fuzz_physics.py draws planners on physics in the default set, and
# tests/test_dwells.py runs paper_fault with astar on physics).
@pytest.mark.parametrize("planner,executor", [
    ("astar", "grid"), ("cbs", "grid"), ("pibt", "grid"),
    pytest.param("astar", "physics", marks=pytest.mark.slow),
    pytest.param("cbs", "physics", marks=pytest.mark.slow),
    pytest.param("pibt", "physics", marks=pytest.mark.slow)])
def test_paper_fault_scenario_finishes(planner, executor):
    """Every order completes and no AGV-AGV contact. Intrusions need not be 0: AGVs caught
    inside a new corridor are sent out but may still overrun their exit bound (issue 13,
    fault 5; counted, no longer hidden by an exemption)."""
    failures = 0
    for seed in range(2):
        m = fault_run(planner, executor, seed)
        assert m["success_rate"] == 1.0, (seed, m)
        check_corridor_figures(m)
        assert m["collisions"] == 0 if executor == "grid" else m["agv_contacts"] == 0, m
        failures += m["failures"]
    assert failures > 0  # the scenario does break AGVs


@pytest.mark.slow
@pytest.mark.parametrize("executor", ["grid", "physics"])
@pytest.mark.parametrize("planner", ["astar", "cbs", "pibt"])
def test_paper_fault_scenario_twenty_seeds(planner, executor):
    bad = []
    for seed in range(20):
        m = fault_run(planner, executor, seed)
        contacts = m["collisions"] if executor == "grid" else m["agv_contacts"]
        check_corridor_figures(m)
        if m["success_rate"] != 1.0 or contacts:
            bad.append((seed, m["success_rate"], contacts))
    assert bad == []


# ----------------------------------------------------------------------------- invariants


def check_orders(sim: Simulation) -> None:
    """Every generated order is exactly one of pending, assigned, in progress, completed,
    and the trips agree with it."""
    w = sim.world
    assert set(w.status) == set(w.orders)
    on_trips: dict[int, int] = {}
    for agv in w.agvs:
        if agv.trip is not None:
            for oid in agv.trip.orders:
                assert oid not in on_trips, f"order {oid} on two AGVs"
                on_trips[oid] = agv.id
    for oid, status in w.status.items():
        assert status in (OrderStatus.PENDING, OrderStatus.ASSIGNED, OrderStatus.IN_PROGRESS,
                          OrderStatus.COMPLETED)
        if status in (OrderStatus.ASSIGNED, OrderStatus.IN_PROGRESS):
            assert oid in on_trips, f"order {oid} is {status.name} but on no trip"
        if status == OrderStatus.PENDING:
            assert oid not in on_trips, f"pending order {oid} is on AGV {on_trips[oid]}"
        assert (status == OrderStatus.COMPLETED) == (oid in w.completed_tick)


@st.composite
def fault_schedules(draw):
    n = draw(st.integers(1, 6))
    scheduled = [{"agv": draw(st.integers(0, 8)), "tick": draw(st.integers(0, 60)),
                  "repair_ticks": draw(st.integers(1, 50))} for _ in range(n)]
    return {"scheduled": scheduled,
            "random": {"prob_per_tick": draw(st.sampled_from([0.0, 0.01, 0.03])),
                       "repair_ticks": 20, "repair_ticks_max": 60,
                       "max_down": draw(st.sampled_from([None, 2]))},
            "orders_of_failed": draw(st.sampled_from(["reassign", "wait"]))}


# 20 examples: each example runs an episode of up to 1,500 ticks
@pytest.mark.slow  # episodes with failures over several seeds: make test-all
@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(fault_schedules(), st.sampled_from(["ta", "rd"]), st.integers(0, 100))
def test_orders_are_never_lost_through_failures(faults, scheduler, seed):
    sc = load_scenario("layouts/paper_homogeneous.yaml",
                       [("faults", faults), ("scheduler.name", scheduler), ("max_ticks", 1500)])
    sim = Simulation(sc, seed=seed)
    while not sim.done:
        sim.step()
        check_orders(sim)
    assert sim.world.all_done(), "every order completes once the AGVs are repaired"


# ----------------------------------------------------------------------------- corridors


def small(executor: str = "grid", **faults):
    return Simulation(scenario_from_dict({
        "layout": {"grid": ["..........",
                            "..SS.SS...",
                            ".........R",
                            "..SS.SS...",
                            "P...P...P."]},
        "fleet": {"agvs": [{"count": 3}]},
        "orders": {"pattern": "oneshot", "oneshot": {"count": 1}},
        "executor": executor, "faults": faults}), seed=0)


@pytest.mark.parametrize("executor", ["grid", "physics"])
def test_driving_into_an_open_corridor_is_reported(executor):
    """A deliberately wrong plan takes AGV 1 through AGV 0's corridor: the check sees it."""
    sim = small(executor)
    w = sim.world
    sim.fail(0)
    corridor = next(iter(w.corridors.values()))
    inside = sorted(corridor.cells - set(occupancy(w.agvs[0].pos, 1, w.layout.cols)))
    start = w.agvs[1].node
    target = inside[0]
    path = w.graphs.get(1, False)  # closed graph: no way in; write the path by hand
    assert path.distance(w.cell(start), w.cell(target)) >= 10**6
    route = _straight_route(w, start, target)
    w.reservations.commit(TimedPath(1, w.tick, tuple((n, n) for n in route)), 1)
    w.agvs[1].retry_at = 10**9  # keep the planner away from it
    for _ in range(len(route) + 3):
        step_executor(w, sim.executor)
        w.tick += 1
        if executor == "grid":  # the loop's cell check, as Simulation.step runs it
            sim._grid_intrusions()
    assert w.fault_stats["corridor_intrusions"] >= 1
    events = [e for e in w.events if e["event"] == "corridor_intrusion"]
    assert events and events[0]["agv"] == 1 and events[0]["depth"] > 0


def _straight_route(w, start: int, target: int) -> list[int]:
    """Cells from ``start`` to ``target``: along the row, then the column (open floor)."""
    (r0, c0), (r1, c1) = w.cell(start), w.cell(target)
    route = [start]
    r, c = r0, c0
    while c != c1:
        c += 1 if c1 > c else -1
        route.append(w.node((r, c)))
    while r != r1:
        r += 1 if r1 > r else -1
        route.append(w.node((r, c)))
    return route


@pytest.mark.parametrize("executor", ["grid", "physics"])
def test_on_demand_failure_opens_a_corridor_that_later_plans_avoid(executor):
    sc = load_scenario("layouts/paper_homogeneous.yaml", [("executor.name", executor)])
    sim = Simulation(sc, seed=3)
    w = sim.world
    while w.tick < 12:
        sim.step()
    victim = next(a.id for a in w.agvs if a.state != AgvState.IDLE)
    sim.fail(victim)
    assert w.agvs[victim].state == AgvState.FAILED and len(w.corridors) == 1
    corridor = next(iter(w.corridors.values()))
    exempt = {g.agv for g in w.corridor_book.grants.values() if g.corridor == corridor.id}
    before = {aid: p for aid, p in w.reservations.paths.items()}
    for _ in range(30):
        sim.step()
        for aid, path in w.reservations.paths.items():
            if aid == victim or aid in exempt or path is before.get(aid):
                continue
            for s in path.states:
                assert not corridor.cells.intersection(occupancy(s, w.agvs[aid].k,
                                                                  w.layout.cols)), aid
    # No AGV that was outside when it opened entered it.
    book = w.corridor_book
    entered = {e["agv"] for e in w.events if e["event"] == "corridor_intrusion"}
    assert entered <= exempt, (entered, exempt)
    assert book.intrusions == 0 or all(g.overran for g in book.grants.values()
                                       if g.agv in entered)
    sim.repair(victim)
    assert not w.corridors and w.agvs[victim].state != AgvState.FAILED
    result = sim.run()
    assert result.metrics["success_rate"] == 1.0
    assert result.metrics["failures"] == 1 and result.metrics["down_ticks"] >= 30


# ----------------------------------------------------------------------------- bad input


def test_bad_fault_requests_are_clear_errors():
    sim = small()
    with pytest.raises(ValueError, match="unknown AGV id 7"):
        sim.fail(7)
    with pytest.raises(ValueError, match="AGV 1 is working"):
        sim.repair(1)
    sim.fail(1)
    with pytest.raises(ValueError, match="already failed"):
        sim.fail(1)
    with pytest.raises(ValueError, match="repair_ticks"):
        sim.fail(2, repair_ticks=0)


def test_corridor_wider_than_the_map_is_rejected_at_load(tmp_path):
    with pytest.raises(ScenarioError, match="corridor_width_m"):
        small(corridor_width_m=50.0)
    bad = tmp_path / "wide.yaml"
    text = Path(FAULT).read_text().replace("corridor_width_m: 1.0", "corridor_width_m: 40.0")
    text = text.replace("layout: maps/", f"layout: {Path('layouts/maps').resolve()}/")
    bad.write_text(text)
    exe = Path(sys.executable).parent / "warerover"
    r = subprocess.run([str(exe), "run", str(bad), "--quiet"], capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert "faults.corridor_width_m" in r.stderr and "40" in r.stderr


def test_fault_metrics_are_written(tmp_path):
    exe = Path(sys.executable).parent / "warerover"
    r = subprocess.run([str(exe), "run", FAULT, "--seed", "1", "--out", str(tmp_path),
                        "--quiet"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    m = json.loads((tmp_path / "metrics.json").read_text())
    for key in ("failures", "down_ticks", "orders_delayed_by_failures", "corridor_intrusions",
                "failure_replans", "corridor_intrusion_agv_s", "corridor_inside_agv_s",
                "corridor_caught_inside", "corridor_exits_within_bound",
                "corridor_exits_overrun", "corridor_exit_max_s"):
        assert key in m
    assert m["failures"] > 0 and m["down_ticks"] > 0
    events = [json.loads(x) for x in (tmp_path / "events.jsonl").read_text().splitlines()]
    opened = [e for e in events if e["event"] == "corridor_opened"]
    closed = [e for e in events if e["event"] == "corridor_closed"]
    assert len(opened) == m["failures"] and len(closed) <= len(opened)
