"""Planning that takes time (``planner.invoke``, ``planner.latency``; :mod:`warerover_phys.invoke`).

- A planner that sleeps costs throughput only with a latency on: without one the world
  waits for it (the same episode as a planner that does not sleep), with ``measured`` the
  robots stand while it thinks.
- Periodic and event-triggered calls, windowed PIBT, fixed latencies: every executed state
  checked by the independent validator; the same seed gives the same episode.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from warerover_phys import load_scenario
from warerover_phys.config import parse_override
from warerover_phys.errors import ScenarioError
from warerover_phys.invoke import cut, hold_back, splice
from warerover_phys.planning.paths import TimedPath
from warerover_phys.planning.search.astar import AStarPlanner
from warerover_phys.sim import Simulation
from warerover_phys.validate import validate_states

SCENARIO = "layouts/paper_homogeneous.yaml"


def _sim(name: str, *sets: str, seed: int = 1, planner=None) -> Simulation:
    ov = [parse_override(s) for s in (f"planner={name}", *sets)]
    return Simulation(load_scenario(SCENARIO, ov), seed, planner=planner)


def _checked(result) -> dict:
    w = result.world
    conflicts = validate_states(result.actual, w.layout.grid == 1,
                                sizes={a.id: a.k for a in w.agvs},
                                ticks_per_move={a.id: a.ticks_per_move for a in w.agvs})
    assert conflicts == []
    assert result.metrics["collisions"] == 0
    return result.metrics


class SleepyAStar(AStarPlanner):
    """A* that takes ``nap`` seconds of wall time per call."""

    nap = 0.12

    def plan(self, request):
        time.sleep(self.nap)
        return super().plan(request)


def test_a_sleeping_planner_costs_throughput_only_with_a_latency():
    awake = _checked(_sim("astar", "tick_s=0.1", "fleet.types.agv.max_speed_mps=12",
                          "orders.oneshot.count=8").run())
    asleep = _checked(_sim("astar", "tick_s=0.1", "fleet.types.agv.max_speed_mps=12",
                           "orders.oneshot.count=8", planner=SleepyAStar()).run())
    slow = _sim("astar", "tick_s=0.1", "fleet.types.agv.max_speed_mps=12",
                "orders.oneshot.count=8", "planner.latency=measured", planner=SleepyAStar())
    late = _checked(slow.run())
    # without a latency the world waits: the same episode, tick for tick
    for key in ("ticks", "orders_completed", "throughput", "replans", "blocked_moves"):
        assert asleep[key] == awake[key]
    assert awake["plan_wait_agv_s"] == 0 and awake["plan_effect_ticks_mean"] == 0
    # with its time simulated, each answer comes >= 2 ticks (0.12 s / 0.1 s) after the call
    assert late["plan_effect_ticks_mean"] >= 2
    assert late["ct_plan_call_mean_ms"] >= 120
    assert late["plan_wait_agv_s"] > 0
    assert late["success_rate"] == awake["success_rate"] == 1.0
    assert late["throughput"] < awake["throughput"]


@pytest.mark.parametrize("planner,sets", [
    ("pibt", ("planner.invoke=periodic:4",)),
    ("pibt", ("planner.invoke=event:3", "planner.latency=fixed:2")),
    ("pibt", ("planner.latency=fixed:1",)),
    ("astar", ("planner.invoke=periodic:3", "planner.latency=fixed:2")),
    ("lacam", ("planner.invoke=event:2",)),
])
def test_invoke_and_latency_keep_plans_valid_and_deterministic(planner, sets):
    a = _checked(_sim(planner, *sets).run())
    b = _sim(planner, *sets).run().metrics
    for key in ("ticks", "orders_completed", "replans", "planner_calls", "plan_wait_agv_s",
                "blocked_moves"):
        assert a[key] == b[key]
    assert a["success_rate"] == 1.0
    invoke = dict(x.split("=") for x in sets).get("planner.invoke", "every_tick")
    assert a["planner_invoke"] == invoke
    if invoke != "every_tick":  # fewer calls than ticks
        assert a["planner_calls"] < a["ticks"]


def test_fixed_latency_delays_each_plan_by_its_ticks():
    m = _checked(_sim("pibt", "planner.latency=fixed:3").run())
    assert m["plan_effect_ticks_mean"] == 3.0
    base = _checked(_sim("pibt").run())
    assert m["throughput"] < base["throughput"]


def test_windowed_pibt_plans_its_window():
    sim = _sim("pibt", "planner.invoke=periodic:5")
    assert sim.clock.window == 10 and sim.clock.period == 5
    sim.step()
    paths = sim.world.reservations.paths
    moving = [p for p in paths.values() if len(set(p.states)) > 1]
    assert moving and {len(p.states) for p in moving} == {11}
    # an AGV that stands the whole window keeps its path (nothing changes for it)
    assert all(len(set(p.states)) == 1 for p in paths.values() if len(p.states) != 11)


def test_bad_invoke_and_latency_are_named():
    for field, value in (("planner.invoke", "sometimes"), ("planner.invoke", "periodic:-1"),
                         ("planner.invoke", "event:1.5"), ("planner.latency", "slow"),
                         ("planner.latency", "fixed:nan")):
        with pytest.raises(ScenarioError, match=field.replace(".", r"\.")):
            load_scenario(SCENARIO, [(field, value)])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, 3), min_size=1, max_size=8), st.integers(0, 8),
       st.integers(0, 4), st.lists(st.integers(0, 3), min_size=1, max_size=6))
def test_splice_keeps_the_prefix_then_waits_then_follows(old_cells, t_eff, late, new_cells):
    """The spliced path is the old one up to t_eff, the new plan's first state until t_r,
    then the new plan; it refuses a new plan that starts elsewhere."""
    old = TimedPath(0, 0, tuple((c, c) for c in old_cells))
    old = cut(old, t_eff)
    first = old.state_at(t_eff)
    new = TimedPath(0, t_eff, (first,) + tuple((c, c) for c in new_cells))
    t_r = t_eff + late
    now = old.states[0]
    got = splice(old, new, t_r, now)
    # kept from the AGV's state now (its last visit of it up to t_eff) on
    assert got is not None and got.states[0] == now and got.start_tick <= t_eff
    for t in range(got.start_tick, t_eff):
        assert got.state_at(t) == old.state_at(t)
    for t in range(t_eff, t_r + 1):
        assert got.state_at(t) == first
    for k, s in enumerate(new.states):
        assert got.state_at(t_r + k) == s
    other = (first[0] + 1, first[0] + 1)
    if old.state_at(t_eff) != other and old.states[-1] != other:
        assert splice(old, TimedPath(0, t_eff, (other,)), t_r, old.states[0]) is None


def test_splice_keeps_a_side_step_the_agv_has_not_made_yet():
    """A path that steps aside and comes back (A, B, A): an AGV behind its plan, still at
    the first A, keeps the side step (dropping it would leave the AGV on A while another
    AGV's plan passes A in the meantime: a dependency cycle)."""
    a, b, c = (1, 1), (2, 2), (3, 3)
    old = TimedPath(0, 10, (a, a, b, a, a))  # ticks 10..14
    new = TimedPath(0, 14, (a, c))
    got = splice(old, new, 14, a)
    assert got.start_tick == 11 and got.states == (a, b, a, a, c)
    # an AGV that stands on A from the start keeps no more of its stand than it must
    assert splice(TimedPath(0, 10, (a,) * 5), new, 14, a).start_tick == 14


def test_hold_back_stops_whom_a_kept_path_stands_in_the_way_of():
    """AGV 0's late plan was dropped (it keeps standing on cell 5); AGV 1's new path moves
    into cell 5 and must keep its old path too, and then AGV 2, which planned to follow
    AGV 1 into cell 6; AGV 3, elsewhere, keeps its new plan."""
    old = {0: TimedPath(0, 0, ((5, 5),) * 3), 1: TimedPath(1, 0, ((6, 6),) * 3),
           2: TimedPath(2, 0, ((7, 7),) * 3), 3: TimedPath(3, 0, ((20, 20),) * 3)}
    spliced = {1: TimedPath(1, 0, ((6, 6), (6, 6), (5, 5))),
               2: TimedPath(2, 0, ((7, 7), (7, 7), (7, 7), (6, 6))),
               3: TimedPath(3, 0, ((20, 20), (21, 21)))}
    sizes = {i: 1 for i in range(4)}
    assert hold_back(spliced, old, [0], sizes, cols=100, tick=0) == [1, 2]
    assert hold_back(spliced, old, [], sizes, cols=100, tick=0) == []


@pytest.mark.slow  # 300 busy AGVs on physics, 2 x 60 ticks with a graph check each tick
@pytest.mark.parametrize("invoke", ["every_tick", "periodic:5"])
def test_late_plans_keep_the_dependency_graph_acyclic_at_scale(invoke):
    """With a planning latency on the busy industrial floor, the plans spliced in late
    never make the physics executor's dependency graph cyclic (before the fix: a cycle
    by tick 25 and 113-162 dependency deadlocks per 1,000 AGV-minutes at 1,000 AGVs)."""
    ov = [parse_override(x) for x in (
        "fleet.agvs.0.count=300", "orders.constant.batch=60", "scheduler=ta", "planner=pibt",
        "executor=physics", "executor.dt_s=0.05", "planner.latency=fixed:1",
        f"planner.invoke={invoke}", "max_ticks=60")]
    sim = Simulation(load_scenario("layouts/industrial.yaml", ov), 0)
    for _ in range(60):
        sim.step()
        sim.executor.adg.check_acyclic()
    assert sim.executor.adg.deadlock_cycles() == []


def test_latency_on_physics_keeps_bodies_apart():
    sim = _sim("pibt", "executor=physics", "planner.invoke=periodic:4",
               "planner.latency=fixed:1.5")
    m = sim.run().metrics
    assert m["agv_contacts"] == 0 and m["success_rate"] == 1.0
    assert m["plan_effect_ticks_mean"] == 2.0
    assert np.isfinite(m["ct_plan_call_p99_ms"])
