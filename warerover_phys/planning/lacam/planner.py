"""LaCAM in the warehouse loop: one joint plan for every AGV, re-solved when goals change.

Every tick the loop hands over all AGVs (``replans_all``). If each AGV's committed path still
ends at its *effective goal*, nothing is planned. Otherwise LaCAM solves the whole fleet
from where it stands, and every AGV gets its full path. Effective goals make the one-shot
problem solvable:

- AGVs working in place (picking, handing over, placing) are held: goal = where they are,
  and LaCAM never moves them;
- in priority order (ticks since the goal was set), an AGV whose goal another AGV already
  claimed (or stands on, held) queues at the nearest free floor cell instead, away from
  the cells in front of stations; it is replanned when its goal frees up.

If LaCAM does not finish within ``max_iterations`` high-level iterations (a work budget: the
same result on any machine), the fleet takes one PIBT step instead and the budget hit is
counted (``PlanResult.budget_hits``), never silently. ``time_budget_s`` is a wall-clock
safety stop only: when it ends a search first (so the result depends on the machine), the
hit is counted too and a warning is logged. When no solution exists (an AGV cannot reach its
goal, e.g. behind a closed safety corridor, or the search space is exhausted) the same PIBT
step is taken without a search and without a budget hit.

A fleet of 1x1 AGVs that move one cell per tick takes the fast path (:func:`lacam_nodes`).
Any other fleet is solved by :func:`footprint_lacam` over poses (an AGV in the middle of a
multi-tick move has one successor; its progress is read back from its committed path), with
footprint-aware effective goals: goal footprints of different AGVs never overlap. A fleet
with turn-aware AGVs takes that path too (headings kept per search node; see
:mod:`footprint_lacam`).
"""

from __future__ import annotations

import logging
import time
from collections import deque

import numpy as np

from ...layout import CellType
from ..base import AgentRequest, PlanRequest, PlanResult, TimedPath, footprint_nodes
from ..graph import UNREACHABLE, MotionGraph
from ..pibt.footprint import footprint_step
from ..pibt.planner import commit_poses, current_pose, headings_for, movers_for, uniform_fleet
from ..pibt.reference import pibt_step
from ..reservation import ReservationTable
from .footprint import footprint_lacam
from .reference import lacam_nodes

__all__ = ["LaCAMPlanner", "effective_goals", "on_plan", "solve_footprints"]

log = logging.getLogger(__name__)


def _report_stop(stats: dict, budget_s: float) -> None:
    """Log a search that the wall-clock safety stop ended (results then depend on timing)."""
    if stats.get("stopped") == "time":
        log.warning("lacam: wall-clock safety stop (%g s) hit after %d iterations; this "
                    "result depends on machine speed (raise planner.time_budget_s or lower "
                    "planner.max_iterations)", budget_s, stats.get("iterations", 0))


class LaCAMPlanner:
    name = "lacam"
    replans_all = True

    def __init__(self, time_budget_s: float = 10.0, max_iterations: int | None = 2_000,
                 **_: object) -> None:
        self.time_budget_s = time_budget_s
        self.max_iterations = max_iterations

    def plan(self, request: PlanRequest) -> PlanResult:
        agents: list[AgentRequest] = sorted(request.agents, key=lambda a: a.agv)
        result = PlanResult()
        if not agents:
            return result
        if not uniform_fleet(agents):
            return self._plan_footprints(request, agents)
        res = request.reservations
        unloaded, loaded = request.graphs.get(1, False), request.graphs.get(1, True)
        graphs = [loaded if a.loaded else unloaded for a in agents]
        goals = effective_goals(agents, graphs, request.keep_clear)
        starts = [a.start for a in agents]
        if on_plan(res, agents, goals, request.tick):
            return result
        dists = [gr.dist_to(gr.cell(g)) for gr, g in zip(graphs, goals, strict=True)]
        tables = [gr.neighbors for gr in graphs]
        held = [i for i, a in enumerate(agents) if a.hold]
        prio = [float(a.priority[0]) if a.priority else 0.0 for a in agents]
        rng = request.rng if request.rng is not None else np.random.default_rng(0)
        deadline = time.monotonic() + self.time_budget_s
        if request.deadline is not None:
            deadline = min(deadline, request.deadline)
        configs, stats = lacam_nodes(unloaded, starts, goals, dists, deadline, rng,
                                     tables=tables, held=held, prio=prio,
                                     max_iterations=self.max_iterations)
        _report_stop(stats, self.time_budget_s)
        if configs is None:
            result.budget_hits += not stats.get("exhausted", False)
            nxt = pibt_step(unloaded, starts, dists, prio, rng.random(unloaded.num_nodes) * 0.5,
                            forced=[(i, starts[i]) for i in held], goals=goals, tables=tables)
            configs = [starts, nxt if nxt is not None else starts]
        for i, a in enumerate(agents):
            states = _compress([(c[i], c[i]) for c in configs])
            path = TimedPath(a.agv, request.tick, states)
            res.commit(path, 1)
            result.paths[a.agv] = path
            if goals[i] != a.goal:
                result.detours.append(a.agv)
        return result

    def _plan_footprints(self, request: PlanRequest, agents: list[AgentRequest]) -> PlanResult:
        """The same for a fleet of mixed sizes and speeds (poses, footprint-aware LaCAM)."""
        deadline = time.monotonic() + self.time_budget_s
        if request.deadline is not None:
            deadline = min(deadline, request.deadline)
        return solve_footprints(request, agents, deadline, keep=True,
                                max_iterations=self.max_iterations)


def solve_footprints(request: PlanRequest, agents: list[AgentRequest], deadline: float,
                     keep: bool, max_iterations: int | None = None) -> PlanResult:
    """Footprint-aware LaCAM for the whole fleet towards its effective goals; commit every
    AGV's full path. With ``keep``, nothing is planned while every committed path still
    leads to its effective goal. Past ``max_iterations`` or ``deadline``, one footprint-aware
    PIBT step (counted as a budget hit); the same step, uncounted, when no solution exists."""
    res, tick = request.reservations, request.tick
    graphs = [request.graphs.get(a.k, a.loaded, a.shelf) for a in agents]
    goals = effective_goals(agents, graphs, request.keep_clear)
    result = PlanResult()
    if keep and on_plan(res, agents, goals, tick):
        return result
    movers = movers_for(request, agents, goals)
    poses = [current_pose(res, a, tick) for a in agents]
    held = [i for i, a in enumerate(agents) if a.hold and poses[i][2] == 0]
    prio = [float(a.priority[0]) if a.priority else 0.0 for a in agents]
    rng = request.rng if request.rng is not None else np.random.default_rng(0)
    headings = headings_for(agents, res, tick)
    configs, stats = footprint_lacam(movers, poses, res.cols, deadline, rng, held=held,
                                     prio=prio, max_iterations=max_iterations,
                                     headings=headings)
    _report_stop(stats, deadline - time.monotonic())
    heads = stats.get("headings")
    if configs is None:
        result.budget_hits += not stats.get("exhausted", False)
        out_heads: list[int] = []
        nxt = footprint_step(movers, poses, prio, rng.random(len(movers[0].dist)) * 0.5,
                             res.cols, forced={i: poses[i][1] for i in held},
                             headings=headings, out_headings=out_heads)
        configs = [tuple(poses), tuple(nxt if nxt is not None else poses)]
        if headings is not None:
            heads = [headings, tuple(out_heads) if nxt is not None else headings]
    if heads is None and headings is not None:
        heads = [headings] * len(configs)  # no rotation-aware AGV: headings unused
    commit_poses(result, res, agents, configs, heads, tick)
    for i, a in enumerate(agents):
        if goals[i] != a.goal:
            result.detours.append(a.agv)
    return result


def on_plan(res: ReservationTable, agents: list[AgentRequest], goals: list[int],
            tick: int) -> bool:
    """Does every AGV's committed path go on from where it is to its effective goal, and
    keep every held AGV where it is? (A joint plan may pass through an AGV's goal early:
    once there the AGV starts working and is held, and the plan is made again.)"""
    for a, g in zip(agents, goals, strict=True):
        p = res.paths.get(a.agv)
        if p is None or p.goal != g or p.state_at(tick)[1] != a.start:
            return False
        if a.hold and p.end_tick > tick:
            return False
    return True


def _compress(states: list[tuple[int, int]]) -> tuple[tuple[int, int], ...]:
    """Drop the trailing repeats of the final state (the AGV stays there anyway)."""
    end = len(states)
    while end > 1 and states[end - 1] == states[end - 2]:
        end -= 1
    return tuple(states[:end])


def effective_goals(agents: list[AgentRequest], graphs: list[MotionGraph],
                    keep_clear: np.ndarray | None) -> list[int]:
    """Goals whose footprints never overlap: held AGVs keep where they stand; in priority
    order, an AGV whose goal footprint overlaps one already claimed queues nearby."""
    goals = [-1] * len(agents)
    taken: set[int] = set()
    for i, a in enumerate(agents):
        if a.hold:
            goals[i] = a.start
            taken.update(_cells(graphs[i], a.start))
    order = sorted((i for i, a in enumerate(agents) if not a.hold),
                   key=lambda i: (-(agents[i].priority[0] if agents[i].priority else 0.0), i))
    for i in order:
        a, graph = agents[i], graphs[i]
        goal = a.goal
        if not taken.isdisjoint(_cells(graph, goal)):
            goal = _queue_spot(graph, goal, a.start, taken, keep_clear)
        goals[i] = goal
        taken.update(_cells(graph, goal))
    return goals


def _cells(graph: MotionGraph, anchor: int) -> tuple[int, ...]:
    return footprint_nodes(anchor, graph.k, graph.cols)


def _queue_spot(graph: MotionGraph, goal: int, start: int, taken: set[int],
                keep_clear: np.ndarray | None) -> int:
    """Nearest anchor to ``goal`` whose footprint is free floor that nobody else aims for
    (else stay put)."""
    floor = graph.layout.grid.ravel() == CellType.FLOOR
    if keep_clear is not None:
        floor = floor & ~keep_clear
    dist_here = graph.dist_to(graph.cell(start))
    seen = {goal}
    frontier = deque([goal])
    while frontier:
        node = frontier.popleft()
        if node != goal and graph.expandable(node) and dist_here[node] < UNREACHABLE \
                and all(floor[c] and c not in taken for c in _cells(graph, node)):
            return node
        for nxt in graph.neighbors[node]:
            if nxt not in seen and graph.expandable(nxt):
                seen.add(nxt)
                frontier.append(nxt)
    return start if taken.isdisjoint(_cells(graph, start)) else goal
