"""Prioritized space-time A*: each AGV in turn finds the fastest path that avoids every
path already committed in the reservation table.

Footprint-aware: a ``k x k`` AGV checks all its cells; a move of a slow AGV (``m`` ticks
per cell) holds both footprints for the ``m - 1`` ticks in between. The heuristic is the
exact static distance on the AGV's motion graph times ``m``.
"""

from __future__ import annotations

import heapq
import time
from collections import deque
from dataclasses import replace

import numpy as np

from ...layout import CellType
from ..base import AgentRequest, PlanRequest, PlanResult, State, TimedPath, footprint_nodes
from ..graph import UNREACHABLE, MotionGraph
from ..reservation import FOREVER, ReservationTable
from ..sweep import turn_aware
from .frontier import swaps
from .turning_astar import turning_astar

__all__ = ["AStarPlanner", "space_time_astar", "goal_held", "nearest_free_anchor"]


def _cell_tests(res: ReservationTable, k: int, cols: int):
    """``free(cell, t, me)`` (may AGV ``me`` hold ``cell`` at tick ``t``?) over the table's
    raw dicts, and ``fp(node)`` (the cells of a ``k x k`` AGV anchored at ``node``): closures,
    as the search calls them for every expansion."""
    occ, rest = res._occ, res._rest

    def free(cell: int, t: int, me: int) -> bool:
        slot = occ.get(cell)
        if slot is not None:
            a = slot.get(t)
            if a is not None:
                return a == me
        r = rest.get(cell)
        return r is None or t < r[0] or r[1] == me

    if k == 1:
        def fp(node: int) -> tuple[int, ...]:
            return (node,)
    else:
        def fp(node: int) -> tuple[int, ...]:
            return footprint_nodes(node, k, cols)
    return free, fp


def space_time_astar(graph: MotionGraph, res: ReservationTable, agent: AgentRequest,
                     t0: int, max_expansions: int = 50_000,
                     budget_per_move: int | None = 40) -> tuple[TimedPath | None, int]:
    """Search one AGV's path from tick ``t0``. Returns (path or None, expansions).

    A turn-aware AGV (:func:`~warerover_phys.planning.sweep.turn_aware`) is searched with
    headings by :func:`~warerover_phys.planning.search.turning_astar.turning_astar`.

    With ``budget_per_move`` the search also gives up after that many expansions per move
    of the static shortest path (plus a margin): in the closed loop a search that needs far
    more is usually blocked by AGVs that will move later, and retrying is cheaper.
    """
    if turn_aware(agent) or agent.turn_ticks is not None:
        return turning_astar(graph, res, agent, t0, max_expansions=max_expansions,
                             budget_per_move=budget_per_move)
    cols, k, m, me = graph.cols, agent.k, agent.ticks_per_move, agent.agv
    start, goal = agent.start, agent.goal
    free, fp = _cell_tests(res, k, cols)

    # Earliest tick from which the AGV may stay at the goal for good.
    t_free = max((res.last_use(c, me) for c in fp(goal)), default=-1) + 1
    if t_free >= FOREVER:
        return None, 0
    h_table = graph.dist_to(graph.cell(goal))
    h0 = graph.distance(graph.cell(start), graph.cell(goal))
    if h0 >= UNREACHABLE:
        return None, 0
    t_limit = max(t_free, t0 + h0 * m) + h0 * m + 64
    if budget_per_move is not None:
        max_expansions = min(max_expansions, budget_per_move * (h0 * m + 25))

    def h(node: int) -> int:
        v = int(h_table[node])
        return v * m if v < UNREACHABLE else (h0 * m if node == start else UNREACHABLE)

    loaded_sinks = graph.has_sinks
    expandable = graph.expandable_flat
    neighbors = graph.neighbors
    open_heap: list[tuple[int, int, int, int]] = [(t0 + h(start), -t0, start, t0)]
    parent: dict[tuple[int, int], tuple[int, int] | None] = {(start, t0): None}
    closed: set[tuple[int, int]] = set()
    expansions = 0
    while open_heap:
        _, _, node, t = heapq.heappop(open_heap)
        if (node, t) in closed:
            continue
        closed.add((node, t))
        if node == goal and t >= t_free:
            return _reconstruct(parent, node, t, me), expansions
        expansions += 1
        if expansions > max_expansions or t >= t_limit:
            if expansions > max_expansions:
                break
            continue
        here = fp(node)
        # Wait one tick.
        if (node, t + 1) not in parent and all(free(c, t + 1, me) for c in here):
            parent[(node, t + 1)] = (node, t)
            heapq.heappush(open_heap, (t + 1 + h(node), -(t + 1), node, t + 1))
        for nxt in (neighbors[node] if node == start or expandable[node] else ()):
            if loaded_sinks and nxt != goal and not expandable[nxt]:
                continue  # never drive into another shelf's home
            t_arr = t + m
            if (nxt, t_arr) in parent:
                continue
            hn = h(nxt)
            if hn >= UNREACHABLE:
                continue
            there = fp(nxt)
            if not all(free(c, t_arr, me) for c in there):
                continue
            if m > 1:
                both = set(here) | set(there)
                if not all(free(c, t + i, me) for i in range(1, m) for c in both):
                    continue
            elif swaps(res, here, there, t, me):
                continue
            parent[(nxt, t_arr)] = (node, t)
            heapq.heappush(open_heap, (t_arr + hn, -t_arr, nxt, t_arr))
    return None, expansions


def goal_held(graph: MotionGraph, res: ReservationTable, agent: AgentRequest) -> bool:
    """Is some other AGV parked for good on the goal's footprint?"""
    return any(res.last_use(c, agent.agv) >= FOREVER
               for c in footprint_nodes(agent.goal, agent.k, graph.cols))


def nearest_free_anchor(graph: MotionGraph, res: ReservationTable, agent: AgentRequest,
                        radius: int = 12, keep_clear: np.ndarray | None = None,
                        avoid: frozenset[int] = frozenset()) -> int | None:
    """The anchor nearest to the goal (breadth-first, up to ``radius`` moves) where the AGV
    could wait for good: a place to queue while the goal is taken.

    Only plain floor qualifies: an AGV queuing on a station, shelf or parking spot could hold
    another AGV's goal, and two AGVs holding each other's goals never move again.
    """
    goal, me, k, cols = agent.goal, agent.agv, agent.k, graph.cols
    floor = graph.layout.grid.ravel() == CellType.FLOOR
    if keep_clear is not None:
        floor = floor & ~keep_clear
    seen = {goal}
    frontier = deque([(goal, 0)])
    while frontier:
        node, d = frontier.popleft()
        cells = footprint_nodes(node, k, cols)
        if d > 0 and graph.expandable(node) and all(floor[c] and c not in avoid
                                                     for c in cells) and all(
                res.last_use(c, me) < FOREVER for c in cells):
            return node
        if d == radius:
            continue
        for nxt in graph.succ(node, is_start=True):
            if nxt not in seen and graph.expandable(nxt):
                seen.add(nxt)
                frontier.append((nxt, d + 1))
    return None


def _reconstruct(parent: dict, node: int, t: int, agv: int) -> TimedPath:
    """The timed path ending at ``(node, t)`` from a search's parent links (shared by the
    A* of :mod:`cbs`); a move that took several ticks fills them with ``(a, b)`` states."""
    chain: list[tuple[int, int]] = []
    key: tuple[int, int] | None = (node, t)
    while key is not None:
        chain.append(key)
        key = parent[key]
    chain.reverse()
    states: list[State] = [(chain[0][0], chain[0][0])]
    for (a, ta), (b, tb) in zip(chain, chain[1:], strict=False):
        for _ in range(tb - ta - 1):
            states.append((a, b))
        states.append((b, b))
    return TimedPath(agv=agv, start_tick=chain[0][1], states=tuple(states))


class AStarPlanner:
    """Prioritized planning with space-time A* (WareRover's ``A*``)."""

    name = "astar"
    replans_all = False

    def __init__(self, max_expansions: int = 50_000, budget_per_move: int | None = 40) -> None:
        self.max_expansions = max_expansions
        self.budget_per_move = budget_per_move

    def plan(self, request: PlanRequest) -> PlanResult:
        result = PlanResult()
        res = request.reservations
        for agent in sorted(request.agents, key=lambda a: (a.priority, a.agv)):
            if request.deadline is not None and time.monotonic() > request.deadline:
                result.failed.append(agent.agv)
                continue
            graph = request.graphs.get(agent.k, agent.loaded, agent.shelf)
            old = res.paths.get(agent.agv)
            res.release(agent.agv)
            path, n = space_time_astar(graph, res, agent, request.tick, self.max_expansions,
                                       self.budget_per_move)
            if path is None and goal_held(graph, res, agent):
                # Queue near the goal; the loop replans once the goal is free.
                alt = nearest_free_anchor(graph, res, agent, keep_clear=request.keep_clear)
                if alt is not None:
                    path, n2 = space_time_astar(graph, res, replace(agent, goal=alt),
                                                request.tick, self.max_expansions,
                                                self.budget_per_move)
                    n += n2
                    if path is not None:
                        result.detours.append(agent.agv)
            result.expansions += n
            if path is None:
                if old is not None:
                    res.commit(old, agent.k)
                result.failed.append(agent.agv)
                continue
            res.commit(path, agent.k, agent.heading)
            result.paths[agent.agv] = path
        return result
