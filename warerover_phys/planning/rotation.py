"""Rotation-aware planning (issue 15): turns in place that take time.

With ``planner.rotations: true`` a differential-drive AGV is planned over states
``(anchor, heading)`` (heading: direction index 0 east, 1 south, 2 west, 3 north, as in
:data:`~warerover_phys.planning.sweep.DIR_OF`), with the actions of the League of Robot
Runners: move one cell *along its heading*, turn clockwise (+1) or counter-clockwise (-1) in
place, or wait; the A* family also turns half round in one action. A turn takes the ticks
the physics executor needs for it (:func:`turn_ticks`); omnidirectional AGVs never turn and
are planned as before.

Plans carry the heading of every state (:attr:`~warerover_phys.planning.paths.TimedPath.
headings`): a turn is a run of standing states at one anchor whose heading changes at its
last state; a move keeps the heading of its direction. The independent validator checks
them (:func:`~warerover_phys.validate.validate_headings`).

Distances over (anchor, heading) (:func:`rotation_dist`, in ticks: a move costs the AGV's
``ticks_per_move``, a quarter turn ``turn_ticks(.., 1)``, a half turn ``turn_ticks(.., 2)``)
guide every planner: the A* heuristic, and the ranking of the next actions in PIBT and
LaCAM (the LoRR entries' rule: an AGV whose best next cell is not ahead turns towards it).

>>> from warerover_phys.config import AgvTypeSpec
>>> small = AgvTypeSpec(max_turn_rate_radps=2.5)
>>> turn_ticks(small, 1.0, 1), turn_ticks(small, 1.0, 2)  # 0.63 s and 1.26 s
(1, 2)
>>> turn_ticks(AgvTypeSpec(drive="omni"), 1.0, 1)
0
"""

from __future__ import annotations

import heapq
from collections import OrderedDict
from collections.abc import Sequence

import numpy as np

from .motion import MotionModel

__all__ = ["turn_s", "turn_ticks", "agent_turn_ticks", "rotating", "quarters",
           "rotation_dist", "rotation_graph", "rotation_dist_csr", "graph_rotation_dist", "turn_towards", "UNREACHABLE_T"]

UNREACHABLE_T = 1 << 30
"""Ticks to the goal from a state that cannot reach it (:func:`rotation_dist`)."""


def turn_s(agv_type, quarters: int) -> float:
    """Seconds the physics executor needs to turn ``agv_type`` in place by ``quarters``
    quarter turns: the motion model's :meth:`~.motion.MotionModel.turn_s` (its reference
    heading turns at ``max_turn_rate_radps`` from the first step, no angular acceleration
    limit, and the body follows within
    :data:`~warerover_phys.executors.control.ALIGN_EPS_RAD`)."""
    return MotionModel.of(agv_type, cell_m=1.0).turn_s(quarters)


def turn_ticks(agv_type, tick_s: float, quarters: int = 1) -> int:
    """Ticks a turn in place of ``quarters`` quarter turns takes in a plan: the motion
    model's turn time in whole ticks of ``tick_s`` seconds (:meth:`~.motion.MotionModel.
    ticks`: at least 1); 0 for omnidirectional AGVs, which never turn."""
    if getattr(agv_type, "drive", "diff") != "diff" or quarters <= 0:
        return 0
    return MotionModel.ticks(turn_s(agv_type, quarters), tick_s)


def agent_turn_ticks(agv_type, tick_s: float) -> tuple[int, int] | None:
    """``(quarter turn ticks, half turn ticks)`` of a differential-drive type, None for an
    omnidirectional one (the value of :attr:`~warerover_phys.planning.base.AgentRequest.
    turn_ticks`)."""
    q = turn_ticks(agv_type, tick_s, 1)
    return (q, turn_ticks(agv_type, tick_s, 2)) if q else None


def rotating(agent) -> bool:
    """Is this :class:`~warerover_phys.planning.base.AgentRequest` planned with rotations?"""
    return agent.turn_ticks is not None


def quarters(h0: int, h1: int) -> int:
    """Quarter turns between two headings (0, 1 or 2)."""
    d = (h1 - h0) % 4
    return min(d, 4 - d)


def turn_towards(h: int, d: int) -> int:
    """The heading after one quarter turn from ``h`` towards direction ``d`` (``h`` itself
    if it faces ``d``; clockwise for a half turn)."""
    diff = (d - h) % 4
    if diff == 0:
        return h
    return (h + 1) % 4 if diff in (1, 2) else (h - 1) % 4


def rotation_dist(neighbors: Sequence[tuple[int, ...]], expandable: Sequence[bool], cols: int,
                  goal: int, m: int, quarter: int, half: int) -> np.ndarray:
    """Ticks to reach ``goal`` (any heading) from every state, as an ``(nodes, 4)`` int64
    array indexed ``[anchor, heading]`` (:data:`UNREACHABLE_T` where none): moves of ``m``
    ticks along the heading (only out of ``expandable`` anchors), quarter turns of
    ``quarter`` ticks and half turns of ``half`` ticks. Exact for one AGV alone (Dijkstra,
    backwards from the goal)."""
    n = len(neighbors)
    dist = np.full((n, 4), UNREACHABLE_T, dtype=np.int64)
    if not 0 <= goal < n:
        return dist
    step = (1, cols, -1, -cols)
    heap = [(0, goal * 4 + d) for d in range(4)]
    dist[goal, :] = 0
    flat = dist.reshape(-1)
    while heap:
        c, sid = heapq.heappop(heap)
        if c > flat[sid]:
            continue
        v, d = divmod(sid, 4)
        # A move into v along d came from u = v - step[d], facing d.
        u = v - step[d]
        if 0 <= u < n and expandable[u] and v in neighbors[u]:
            s2 = u * 4 + d
            if c + m < flat[s2]:
                flat[s2] = c + m
                heapq.heappush(heap, (c + m, s2))
        for d2, cost in (((d + 1) % 4, quarter), ((d + 3) % 4, quarter), ((d + 2) % 4, half)):
            s2 = v * 4 + d2
            if c + cost < flat[s2]:
                flat[s2] = c + cost
                heapq.heappush(heap, (c + cost, s2))
    dist.setflags(write=False)
    return dist


def rotation_graph(neighbors: Sequence[tuple[int, ...]], expandable: Sequence[bool], cols: int,
                   m: int, quarter: int, half: int):
    """The *reversed* state graph of :func:`rotation_dist` as a scipy CSR matrix over the
    ``4 * nodes`` states ``anchor * 4 + heading``: an edge ``s -> s'`` of weight ``w`` says
    that ``s'`` reaches ``s`` in ``w`` ticks (a move of ``m`` ticks along the heading out of
    an ``expandable`` anchor; quarter and half turns in place). ``None`` where a cost is not
    positive (scipy reads an explicit 0 as no edge): :func:`rotation_dist` is used then."""
    if min(m, quarter, half) <= 0:
        return None
    from scipy.sparse import csr_matrix

    n = len(neighbors)
    step = (1, cols, -1, -cols)
    src, dst, w = [], [], []
    for u in range(n):
        if not expandable[u]:
            continue
        for v in neighbors[u]:
            for d in range(4):
                if v - u == step[d]:
                    # forward (u, d) -> (v, d): reversed, (v, d) -> (u, d)
                    src.append(v * 4 + d)
                    dst.append(u * 4 + d)
                    w.append(m)
    states = np.arange(4 * n, dtype=np.int64)
    heads = states % 4
    base = states - heads
    for off, cost in ((1, quarter), (3, quarter), (2, half)):
        src.extend(states.tolist())
        dst.extend((base + (heads + off) % 4).tolist())
        w.extend([cost] * (4 * n))
    return csr_matrix((np.asarray(w, dtype=np.float64), (np.asarray(src, dtype=np.int64),
                                                         np.asarray(dst, dtype=np.int64))),
                      shape=(4 * n, 4 * n))


def rotation_dist_csr(rev, n: int, goal: int) -> np.ndarray:
    """:func:`rotation_dist` over the reversed state graph ``rev`` (:func:`rotation_graph`,
    ``n`` anchors) with scipy's Dijkstra from the goal's four states: the same table."""
    from scipy.sparse.csgraph import dijkstra

    dist = np.full((n, 4), UNREACHABLE_T, dtype=np.int64)
    if not 0 <= goal < n:
        return dist
    d = dijkstra(rev, directed=True, indices=[goal * 4 + h for h in range(4)],
                 min_only=True)
    flat = dist.reshape(-1)
    ok = np.isfinite(d)
    flat[ok] = d[ok].astype(np.int64)
    dist.setflags(write=False)
    return dist


ROT_TABLE_BUDGET_BYTES = 1 << 28
"""Memory the (anchor, heading) distance tables cached on one motion graph may take
(:func:`graph_rotation_dist`; at least 256 tables are kept)."""


def graph_rotation_dist(graph, goal: int, m: int, quarter: int, half: int) -> np.ndarray:
    """:func:`rotation_dist` on a :class:`~warerover_phys.planning.graph.MotionGraph`,
    computed with scipy over the graph's cached reversed state graph
    (:func:`rotation_graph`) and cached on the graph (the most recent goals and costs, as
    many as :data:`ROT_TABLE_BUDGET_BYTES` allows and at least 256: a fleet of hundreds of
    AGVs with distinct goals must not evict its own tables every tick)."""
    cache = graph.__dict__.setdefault("_rot_cache", OrderedDict())
    key = (goal, m, quarter, half)
    out = cache.get(key)
    if out is None:
        n = len(graph.neighbors)
        graphs = graph.__dict__.setdefault("_rot_graphs", {})
        costs = (m, quarter, half)
        if costs not in graphs:
            graphs[costs] = rotation_graph(graph.neighbors, graph.expandable_flat, graph.cols,
                                           m, quarter, half)
        rev = graphs[costs]
        if rev is None:
            out = rotation_dist(graph.neighbors, graph.expandable_flat, graph.cols, goal, m,
                                quarter, half)
        else:
            out = rotation_dist_csr(rev, n, goal)
        cache[key] = out
        cap = max(256, ROT_TABLE_BUDGET_BYTES // max(1, 32 * n))
        while len(cache) > cap:
            cache.popitem(last=False)
    else:
        cache.move_to_end(key)
    return out
