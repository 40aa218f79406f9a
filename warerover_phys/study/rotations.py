"""One-shot MAPF with rotations (``rotations: true`` in a study's planner): every agent
from its start to its goal, differential-drive robots moving only along their heading and
turning in place for the ticks the planner's robot model needs
(:func:`~warerover_phys.planning.rotation.agent_turn_ticks`).

The loop's own rotation-aware planners do the work, driven as the closed loop drives them
but with fixed goals: ``astar`` is called once (prioritized turning A*, every agent's whole
path); ``pibt`` and ``lacam`` are called every tick with every agent (LaCAM solves the whole
fleet when it can and keeps that plan; when its search ends without a solution it takes one
PIBT step), and the states each tick begins with are the plan. Agents start facing east, as
the physics executor places them. An omnidirectional model never turns: the plan is then
the same problem without headings.
"""

from __future__ import annotations

import time

import numpy as np

from ..config import AgvTypeSpec
from ..plans import Plan

__all__ = ["solve_rotations", "DIRS"]

DIRS = ((0, 1), (1, 0), (0, -1), (-1, 0))
"""``(drow, dcol)`` by direction index (0 east, 1 south, 2 west, 3 north)."""
MAX_TICKS = 100_000


def _setup(obstacles: np.ndarray):
    from ..planning.graph import GraphSet
    from ..planning.oneshot.core import grid_graph

    graph = grid_graph(obstacles)
    graphs = GraphSet(graph.layout)
    graphs._graphs[(1, False)] = graph  # the bare grid's graph, as oneshot's A* does
    return graph, graphs


def _planner(name: str, budget_s: float):
    from ..planning.lacam.planner import LaCAMPlanner
    from ..planning.pibt.planner import PIBTPlanner
    from ..planning.search.astar import AStarPlanner

    if name == "astar":
        return AStarPlanner(max_expansions=200_000, budget_per_move=None)
    if name == "lacam":
        return LaCAMPlanner(time_budget_s=budget_s, max_iterations=None)
    return PIBTPlanner()


def solve_rotations(obstacles: np.ndarray, starts: list[tuple[int, int]],
                    goals: list[tuple[int, int]], agv_type: AgvTypeSpec, *, planner: str,
                    time_limit_s: float, tick_s: float = 1.0, seed: int = 0,
                    ) -> tuple[Plan | None, dict]:
    """A rotation-aware plan (cells and headings per tick) or None, and the planner's
    figures (``turn_ticks``, ``ticks``, ``calls``, ``reason`` when it failed). LaCAM's
    warning when its wall-clock stop ends a search is silenced here: the time limit is the
    study's, and a plan not found within it is the reported result."""
    import logging

    quiet = logging.getLogger("warerover_phys.planning.lacam.planner")
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        return _solve(obstacles, starts, goals, agv_type, planner, time_limit_s, tick_s, seed)
    finally:
        quiet.setLevel(level)


def _solve(obstacles: np.ndarray, starts: list[tuple[int, int]], goals: list[tuple[int, int]],
           agv_type: AgvTypeSpec, planner: str, time_limit_s: float, tick_s: float,
           seed: int) -> tuple[Plan | None, dict]:
    from ..planning.base import AgentRequest, PlanRequest, TimedPath
    from ..planning.reservation import ReservationTable
    from ..planning.rotation import agent_turn_ticks

    deadline = time.monotonic() + time_limit_s
    graph, graphs = _setup(obstacles)
    tt = agent_turn_ticks(agv_type, tick_s)
    n = len(starts)
    res = ReservationTable(graph.cols)
    for i, s in enumerate(starts):
        node = graph.node(s)
        res.commit(TimedPath(i, 0, ((node, node),), (0,) if tt else None), 1, DIRS[0])
    goal_nodes = [graph.node(g) for g in goals]
    rng = np.random.default_rng(seed)
    algo = _planner(planner, time_limit_s)
    stats: dict = {"turn_ticks": list(tt) if tt else None, "calls": 0}
    cells: list[list[int]] = [[] for _ in range(n)]
    heads: list[list[int]] = [[] for _ in range(n)]
    since = [0] * n
    for t in range(MAX_TICKS):
        agents, done = [], True
        for i in range(n):
            path = res.paths[i]
            node = path.state_at(t)[0]
            h = path.heading_at(t)
            cells[i].append(node)
            heads[i].append(h if h is not None else 0)
            at_goal = node == goal_nodes[i] and path.end_tick <= t
            done &= at_goal
            since[i] = 0 if at_goal else since[i] + 1
            extra = {"heading": DIRS[h if h is not None else 0], "turn_ticks": tt} if tt else {}
            agents.append(AgentRequest(i, node, goal_nodes[i], priority=(
                since[i] + (n - i) / (n + 1),), **extra))
        if done:
            break
        if time.monotonic() > deadline:
            return None, {**stats, "ticks": t, "reason": f"no solution within {time_limit_s:g} s"}
        if planner == "astar" and t > 0:
            continue  # its paths were planned whole at tick 0
        result = algo.plan(PlanRequest(tick=t, agents=agents, graphs=graphs,
                                       reservations=res.copy(), rng=rng, deadline=deadline))
        stats["calls"] += 1
        if planner == "astar" and (result.failed or result.detours):
            return None, {**stats, "ticks": t, "reason": f"prioritized A* found no path for "
                                                        f"{len(result.failed)} agent(s)"}
        for a in agents:
            path = result.paths.get(a.agv)
            if path is not None:
                res.commit(path, 1, a.heading if tt else "keep")
    else:
        return None, {**stats, "ticks": MAX_TICKS, "reason": f"not done in {MAX_TICKS} ticks"}
    cols = graph.cols
    plan = Plan(tuple(tuple(divmod(v, cols) for v in c) for c in cells),
                headings=tuple(tuple(h) for h in heads) if tt else None)
    return plan, {**stats, "ticks": len(cells[0]) - 1}
