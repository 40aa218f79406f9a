"""The planner checker, :func:`check_planner`: the plan cases and one planning call each."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .common import (
    STEP_TICKS,
    ConformanceReport,
    _check_members,
    _check_name,
    _Checker,
    _factory,
    _label,
    _mixed_world,
    _new,
    _short,
    _timed,
)
from .plan_checks import _check_goals, _check_paths


@dataclass(frozen=True)
class _PlanCase:
    """Agents to plan from tick 0 (``goals``); other AGVs hold ``committed`` cell paths."""

    name: str
    goals: dict[int, tuple[int, int]]
    committed: dict[int, list[tuple[int, int]]] = field(default_factory=dict)
    easy: bool = True
    """Every asked AGV can reach its goal: it must."""
    all_agents: bool = True
    """Every AGV is asked (the only kind of request a ``replans_all`` planner gets)."""


PLAN_CASES = (
    _PlanCase("crossing", {0: (3, 7), 1: (0, 7), 2: (0, 5)}),
    _PlanCase("around a committed path", {1: (0, 7)},
              committed={0: [(0, 0), (0, 1), (0, 2), (0, 3), (0, 3), (0, 3), (0, 3), (0, 3),
                             (1, 3), (2, 3)],
                         2: [(2, 1)]}, all_agents=False),
    _PlanCase("goal held for good", {0: (0, 6)},
              committed={1: [(1, 0), (1, 1), (1, 2), (1, 3), (1, 4), (1, 5), (1, 6), (0, 6)],
                         2: [(2, 1)]}, easy=False, all_agents=False),
)


def check_planner(target: Any, spec: Any = None, *, seed: int = 0,
                  rotations: bool = False) -> ConformanceReport:
    """Run a planner through fixed cases; raise :class:`ConformanceError` on the first
    problem, else return the passed checks. ``rotations``: plan the cases rotation-aware
    (see the module doc).

    >>> check_planner("pibt").passed[:3]
    ['members', 'name', 'replans_all']
    """
    ck = _Checker("planner", _label(target))
    factory = _factory("planner", target, spec, ck)
    planner = _new(factory, ck)
    _check_members("planner", planner, ck)
    _check_name(planner, ck)
    if not isinstance(getattr(planner, "replans_all", None), bool):
        ck.fail("replans_all", f"replans_all is {getattr(planner, 'replans_all', None)!r}, "
                "not a bool", "add a class attribute replans_all = False (planned only for "
                "AGVs that need a new path) or True (every AGV, every tick)")
    ck.ok("replans_all")
    for case in PLAN_CASES:
        if planner.replans_all and not case.all_agents:
            continue
        ck.case = case.name
        _run_plan_case(planner, case, seed, ck, rotations)
    ck.case = PLAN_CASES[0].name
    fresh = _new(factory, ck)
    runs = [_run_plan_case(p, PLAN_CASES[0], seed, ck, rotations)
            for p in (fresh, fresh, planner)]
    if runs.count(runs[0]) != len(runs):
        first, again = runs[0], next(r for r in runs if r != runs[0])
        ck.fail("determinism", f"the same requests (seed {seed}) got different answers from "
                "a fresh planner, called twice, and the one that ran the other cases: "
                f"{_plan_difference(first, again)}",
                "draw randomness only from request.rng, keep no state between calls on self, "
                "and break ties by AGV id, not by set or dict order of unsorted keys")
    ck.ok("determinism")
    return ck.report


def _plan_difference(first: list, again: list) -> str:
    """Where two planner traces (tick, {agv: (start tick, states)}, failed) first differ."""
    for (t, paths_a, failed_a), (_, paths_b, failed_b) in zip(first, again, strict=False):
        for agv in sorted(paths_a.keys() | paths_b.keys()):
            a, b = paths_a.get(agv), paths_b.get(agv)
            if a != b:
                return (f"at tick {t}, AGV {agv}'s path is {_short(a and a[1], 120)} in one "
                        f"run and {_short(b and b[1], 120)} in the other")
        if failed_a != failed_b:
            return f"at tick {t}, failed is {failed_a} in one run and {failed_b} in the other"
    return f"one run made {len(first)} planning calls, the other {len(again)}"


def _run_plan_case(planner, case: _PlanCase, seed: int, ck: _Checker,
                   rotations: bool = False) -> list:
    """Plan ``case`` (tick by tick for ``replans_all`` planners, committing the returned
    paths as the loop does) and check every call; return a trace of the results."""
    from ..planning.base import AgentRequest
    from ..planning.rotation import agent_turn_ticks
    from ..planning.sweep import EAST, turn_fields
    from ..planning.sweep_checks import heading_after

    world = _mixed_world(seed)
    res = world.reservations
    fields = turn_fields(world.layout, [a.spec for a in world.agvs])
    if fields:
        res.configure_turns({a: sw for a, (sw, _) in fields.items() if sw is not None},
                            world.layout.rows)
    for agv, cells in case.committed.items():
        res.commit(_timed(world, agv, cells), world.agvs[agv].k)
    goals = {agv: world.node(cell) for agv, cell in case.goals.items()}
    rng = np.random.default_rng(seed)
    n = len(world.agvs)
    trace = []
    for t in range(STEP_TICKS if planner.replans_all else 1):
        agents = []
        for agv in world.agvs:
            if agv.id not in goals:
                continue
            pos = res.paths[agv.id].state_at(t)
            turn = fields.get(agv.id)
            extra = {} if turn is None else {
                "heading": heading_after(res.paths[agv.id].states[:t - res.paths[agv.id]
                                                                   .start_tick + 1],
                                         world.layout.cols,
                                         res.heading_at_start(agv.id)),
                "sweep": turn[0], "no_turn": turn[1]}
            if rotations and turn is None:
                tt = agent_turn_ticks(agv.spec, world.scenario.tick_s)
                if tt is not None:
                    h = res.paths[agv.id].heading_at(t)
                    extra = {"heading": _DIRS[h] if h is not None else EAST, "turn_ticks": tt}
            agents.append(AgentRequest(agv=agv.id, start=pos[1], goal=goals[agv.id], k=agv.k,
                                       ticks_per_move=agv.ticks_per_move,
                                       priority=(t + (n - agv.id) / (n + 1),), **extra))
        if planner.replans_all and all(res.paths[a.agv].state_at(t) == (a.goal, a.goal)
                                       and res.paths[a.agv].end_tick <= t for a in agents):
            break
        result = _plan_once(planner, world, agents, t, rng, ck)
        trace.append((t, {a: (p.start_tick, p.states) for a, p in sorted(result.paths.items())},
                      sorted(result.failed)))
        for a in agents:  # commit as the loop does: returned paths, in request order
            if a.agv in result.paths:
                res.commit(result.paths[a.agv], a.k, a.heading)
    if case.easy:
        _check_goals(world, goals, planner.replans_all, ck)
    return trace


_DIRS = ((0, 1), (1, 0), (0, -1), (-1, 0))


def _plan_once(planner, world, agents: list, tick: int, rng, ck: _Checker):
    from ..planning.base import PlanRequest, PlanResult

    graphs = world.graphs
    committed = world.reservations
    asked = list(agents)
    request = PlanRequest(tick=tick, agents=agents, graphs=graphs,
                          reservations=committed.copy(), rng=rng,
                          keep_clear=world.keep_clear())
    try:
        result = planner.plan(request)
    except Exception as err:  # noqa: BLE001 - a plug-in's plan is user code
        ck.fail("plan runs", f"plan() raised {type(err).__name__}: {err} at tick {tick}",
                "return PlanResult(failed=[agv, ...]) for AGVs you cannot plan instead of "
                "raising")
    ck.ok("plan runs")
    if not isinstance(result, PlanResult):
        ck.fail("return type", f"plan() returned {type(result).__name__} {_short(result)}",
                "return warerover_phys.planning.PlanResult(paths={agv: TimedPath(agv, "
                "request.tick, states)}, failed=[...])")
    if not isinstance(result.paths, dict) or not isinstance(result.failed, list):
        ck.fail("return type", f"PlanResult.paths is {type(result.paths).__name__} and .failed "
                f"is {type(result.failed).__name__}", "use a dict {agv id: TimedPath} and a "
                "list of AGV ids")
    ck.ok("return type")
    if agents != asked:
        ck.fail("request untouched", "plan() reordered or changed request.agents (the loop "
                "commits the returned paths in the request's order)",
                "sort a copy: for agent in sorted(request.agents, key=...)")
    _check_graphs(world, ck)
    ck.ok("request untouched")
    _check_paths(world, agents, result, tick, ck)
    return result


def _check_graphs(world, ck: _Checker) -> None:
    """The motion graphs match fresh ones built from the same layout."""
    from ..planning.graph import MotionGraph

    graphs = world.graphs
    built = [((k, loaded, None), g) for (k, loaded), g in graphs._graphs.items()] + \
        [((k, True, shelf), g) for (k, shelf), g in graphs._per_shelf.items()]
    for (k, loaded, shelf), g in built:
        fresh = MotionGraph(world.layout, k, loaded, shelf, closed=graphs.closed)
        same = (np.array_equal(g.valid, fresh.valid) and np.array_equal(g.enterable,
                                                                        fresh.enterable)
                and g.neighbors == fresh.neighbors and g.expandable_flat == fresh.expandable_flat)
        if not same:
            ck.fail("request untouched", f"plan() changed the motion graph of {k}x{k} "
                    f"{'loaded' if loaded else 'unloaded'} AGVs (valid anchors or neighbours)",
                    "treat request.graphs as read-only (it is the world's own); copy what you "
                    "need to change")
