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

If LaCAM does not finish within ``time_budget_s``, the fleet takes one PIBT step instead and
the budget hit is counted (``PlanResult.budget_hits``), never silently.
"""

from __future__ import annotations

import time
from collections import deque

import numpy as np

from ..layout import CellType
from .base import AgentRequest, PlanRequest, PlanResult, TimedPath
from .graph import UNREACHABLE, MotionGraph
from .lacam import lacam_nodes
from .pibt import pibt_step

__all__ = ["LaCAMPlanner"]


class LaCAMPlanner:
    name = "lacam"
    replans_all = True

    def __init__(self, time_budget_s: float = 2.0, **_: object) -> None:
        self.time_budget_s = time_budget_s

    def plan(self, request: PlanRequest) -> PlanResult:
        agents: list[AgentRequest] = sorted(request.agents, key=lambda a: a.agv)
        result = PlanResult()
        if not agents:
            return result
        res = request.reservations
        unloaded, loaded = request.graphs.get(1, False), request.graphs.get(1, True)
        graphs = [loaded if a.loaded else unloaded for a in agents]
        goals = _effective_goals(agents, graphs, request.keep_clear)
        starts = [a.start for a in agents]
        on_plan = all(
            (p := res.paths.get(a.agv)) is not None and p.goal == g
            and p.state_at(request.tick)[1] == a.start
            for a, g in zip(agents, goals, strict=True))
        if on_plan:
            return result
        dists = [gr.dist_to(gr.cell(g)) for gr, g in zip(graphs, goals, strict=True)]
        tables = [gr.neighbors for gr in graphs]
        held = [i for i, a in enumerate(agents) if a.hold]
        prio = [float(a.priority[0]) if a.priority else 0.0 for a in agents]
        rng = request.rng if request.rng is not None else np.random.default_rng(0)
        deadline = time.monotonic() + self.time_budget_s
        if request.deadline is not None:
            deadline = min(deadline, request.deadline)
        configs, _ = lacam_nodes(unloaded, starts, goals, dists, deadline, rng, tables=tables,
                                 held=held, prio=prio)
        if configs is None:
            result.budget_hits += 1
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


def _compress(states: list[tuple[int, int]]) -> tuple[tuple[int, int], ...]:
    """Drop the trailing repeats of the final state (the AGV stays there anyway)."""
    end = len(states)
    while end > 1 and states[end - 1] == states[end - 2]:
        end -= 1
    return tuple(states[:end])


def _effective_goals(agents: list[AgentRequest], graphs: list[MotionGraph],
                     keep_clear: np.ndarray | None) -> list[int]:
    goals = [-1] * len(agents)
    taken: set[int] = set()
    for i, a in enumerate(agents):
        if a.hold:
            goals[i] = a.start
            taken.add(a.start)
    order = sorted((i for i, a in enumerate(agents) if not a.hold),
                   key=lambda i: (-(agents[i].priority[0] if agents[i].priority else 0.0), i))
    for i in order:
        a, graph = agents[i], graphs[i]
        goal = a.goal
        if goal in taken:
            goal = _queue_spot(graph, goal, a.start, taken, keep_clear)
        goals[i] = goal
        taken.add(goal)
    return goals


def _queue_spot(graph: MotionGraph, goal: int, start: int, taken: set[int],
                keep_clear: np.ndarray | None) -> int:
    """Nearest free floor cell to ``goal`` that nobody else aims for (else stay put)."""
    floor = graph.layout.grid.ravel() == CellType.FLOOR
    if keep_clear is not None:
        floor = floor & ~keep_clear
    dist_here = graph.dist_to(graph.cell(start))
    seen = {goal}
    frontier = deque([goal])
    while frontier:
        node = frontier.popleft()
        if node != goal and floor[node] and node not in taken \
                and graph.expandable(node) and dist_here[node] < UNREACHABLE:
            return node
        for nxt in graph.neighbors[node]:
            if nxt not in seen and graph.expandable(nxt):
                seen.add(nxt)
                frontier.append(nxt)
    return start if start not in taken else goal
