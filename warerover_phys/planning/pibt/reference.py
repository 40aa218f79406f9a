"""PIBT: priority inheritance with backtracking (Okumura et al., AIJ 2022).

One step moves every agent at once. Agents choose, in priority order, the neighbouring cell
closest to their goal; an agent that wants a cell held by a lower-priority agent lends it
its priority, and that agent must move out of the way first (recursively). If it cannot,
the higher agent tries its next cell. Priorities grow by one each step an agent is away
from its goal and drop back to their fractional part when it arrives, so nobody starves.

This module holds the step function shared by :mod:`lacam` (as its configuration
generator, with constraints) and a plain one-shot PIBT run.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence

import numpy as np

from ..graph import UNREACHABLE, MotionGraph

__all__ = ["pibt_step", "in_priority_order", "pibt_oneshot", "initial_priorities", "update_priorities"]

Cell = tuple[int, int]


def initial_priorities(dists: Sequence[np.ndarray], starts: Sequence[int]) -> list[float]:
    """Ties broken by distance: farther agents first (a value in [0, 1))."""
    d = [float(t[s]) for t, s in zip(dists, starts, strict=True)]
    top = max(d, default=0.0) + 1.0
    return [x / top for x in d]


def update_priorities(prio: list[float], config: Sequence[int], goals: Sequence[int]) -> list[float]:
    return [p - int(p) if q == g else p + 1.0
            for p, q, g in zip(prio, config, goals, strict=True)]


def in_priority_order(prio: Sequence[float], nxt: list, push: Callable[[int, int], object]
                      ) -> None:
    """PIBT's outer loop: ``push(i, -1)`` for every agent not yet decided (``nxt[i] ==
    -1``), highest ``prio`` first, with the recursion limit raised for the priority
    inheritance chains (up to one call per agent) and restored afterwards."""
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 4 * len(nxt) + 1000))
    try:
        for i in sorted(range(len(nxt)), key=lambda i: -prio[i]):
            if nxt[i] == -1:
                push(i, -1)
    finally:
        sys.setrecursionlimit(limit)


class _SwapContext:
    """What the swap rule of :func:`pibt_step` reads: the configuration, the agents'
    distance tables and neighbour lists, who stands where now, and the goals."""

    __slots__ = ("config", "dists", "tables", "neighbors", "occ_now", "goal_of")

    def __init__(self, config, dists, tables, neighbors, occ_now, goal_of):
        self.config, self.dists, self.tables = config, dists, tables
        self.neighbors, self.occ_now, self.goal_of = neighbors, occ_now, goal_of


def _free_branches(ctx: _SwapContext, v: int, came_from: int, agent: int) -> tuple[int, int]:
    """Neighbours of v that ``agent`` could step aside into (its own moves, cells it can
    still reach its goal from; not ``came_from``, not a dead end where an agent already
    sits on its goal), and the last one seen."""
    count, last = 0, -1
    d = ctx.dists[agent]
    neighbors, occ_now, goal_of = ctx.neighbors, ctx.occ_now, ctx.goal_of
    near = ctx.tables[agent][v] if ctx.tables is not None else neighbors[v]
    for u in near:
        a = occ_now.get(u)
        if u == came_from or d[u] >= UNREACHABLE or (
                len(neighbors[u]) == 1 and a is not None and goal_of is not None
                and goal_of[a] == u):
            continue
        count += 1
        last = u
    return count, last


def _swap_required(ctx: _SwapContext, pusher: int, puller: int, v_pusher: int,
                   v_puller: int) -> bool:
    d_push = ctx.dists[pusher]
    while d_push[v_puller] < d_push[v_pusher]:
        count, nxt_v = _free_branches(ctx, v_puller, v_pusher, puller)
        if count >= 2:
            return False  # room to step aside: no swap needed
        if count == 0:
            break
        v_pusher, v_puller = v_puller, nxt_v
    d_pull = ctx.dists[puller]
    return d_pull[v_pusher] < d_pull[v_puller] and (
        d_push[v_pusher] == 0 or d_push[v_puller] < d_push[v_pusher])


def _swap_possible(ctx: _SwapContext, agent: int, v_pusher: int, v_puller: int) -> bool:
    """Can ``agent`` back away from ``v_pusher`` through ``v_puller`` into a branch?"""
    origin = v_pusher
    while v_puller != origin:
        count, nxt_v = _free_branches(ctx, v_puller, v_pusher, agent)
        if count >= 2:
            return True
        if count == 0:
            return False
        v_pusher, v_puller = v_puller, nxt_v
    return False


def _swap_partner(ctx: _SwapContext, nxt: list[int], i: int, best: int) -> int:
    """The agent that ``i`` swaps places with to reach ``best`` (``-1``: none)."""
    config, dists, tables, occ_now = ctx.config, ctx.dists, ctx.tables, ctx.occ_now
    here = config[i]
    if best == here:
        return -1
    j = occ_now.get(best)
    if j is not None and nxt[j] == -1 and _swap_required(ctx, i, j, here, best) \
            and _swap_possible(ctx, i, best, here):
        return j
    d = dists[i]
    d_here, d_best = d[here], d[best]
    for u in (tables[i][here] if tables is not None else ctx.neighbors[here]):
        k = occ_now.get(u)
        if k is None or best == config[k]:
            continue
        dk = dists[k]
        if dk[best] >= dk[here] and d_here >= d_best:
            continue  # what _swap_required(k, i, here, best) answers without a walk
        if _swap_required(ctx, k, i, here, best) and _swap_possible(ctx, i, best, here):
            return k
    return -1


def _force(forced: Sequence[tuple[int, int]], config: Sequence[int], neighbors, occ_now: dict,
           nxt: list[int], occ_next: dict[int, int]) -> bool:
    """Enter the ``forced`` moves (agent, node) into ``nxt`` / ``occ_next``; False if they
    contradict each other (two on one cell, a swap, a move along no edge)."""
    for i, v in forced:
        if v in occ_next or (v != config[i] and v not in neighbors[config[i]]):
            return False
        k = occ_now.get(v)
        if k is not None and k != i and nxt[k] == config[i]:
            return False  # swap between two forced moves
        nxt[i] = v
        occ_next[v] = i
    return True


def pibt_step(graph: MotionGraph, config: Sequence[int], dists: Sequence[np.ndarray],
              prio: Sequence[float], tie: np.ndarray,
              forced: Sequence[tuple[int, int]] = (), goals: Sequence[int] | None = None,
              swap: bool = True, tables: Sequence[Sequence[tuple[int, ...]]] | None = None,
              guide: Sequence[dict[int, int]] | None = None, acyclic: bool = False,
              ) -> list[int] | None:
    """Next configuration from ``config`` (one node per agent), or None if ``forced``
    moves (agent, node) contradict each other.

    ``tie`` breaks ties between equally good cells (pass fresh random values each step to
    keep PIBT from repeating itself). With ``swap`` (needs ``goals``), two agents that must
    pass each other in a corridor swap places by backing one of them into a branch
    ("swap" of Okumura, AAMAS 2024), which plain PIBT cannot do. ``tables`` gives each agent
    its own neighbour lists (e.g. loaded AGVs keep to the aisles); an agent never steps onto
    a cell from which its goal is unreachable. ``guide`` (one-shot instances, :mod:`~warerover_phys.planning.oneshot.scatter`):
    ``guide[i][v]`` is the cell agent i tries first on ``v`` (its guide path's next cell).
    ``acyclic``: no agent enters the cell of an agent up its push chain (one still deciding),
    so the moves form no cycle (a rotation of agents into each other's cells, which an
    action dependency graph cannot execute).
    """
    n = len(config)
    neighbors = graph.neighbors
    nxt = [-1] * n
    occ_now = {v: i for i, v in enumerate(config)}
    occ_next: dict[int, int] = {}
    if not _force(forced, config, neighbors, occ_now, nxt, occ_next):
        return None
    goal_of = goals if goals is not None else None

    ctx = _SwapContext(config, dists, tables, neighbors, occ_now, goal_of)
    active: set[int] = set()

    def push(i: int, parent: int) -> bool:
        active.add(i)
        try:
            return choose(i)
        finally:
            active.discard(i)

    def choose(i: int) -> bool:
        here = config[i]
        d = dists[i]
        near = tables[i][here] if tables is not None else neighbors[here]
        # Python ints from numpy tables: a numpy scalar plus a float takes 10x longer.
        cands = sorted([v for v in near if d[v] < UNREACHABLE] + [here],
                       key=(lambda v: int(d[v]) + tie[v]) if isinstance(d, np.ndarray)
                       else (lambda v: d[v] + tie[v]))
        if guide is not None:
            first = guide[i].get(here)
            if first is not None and first != cands[0] and first in cands:
                cands.remove(first)
                cands.insert(0, first)
        partner = -1
        if swap and goal_of is not None:
            partner = _swap_partner(ctx, nxt, i, cands[0])
            if partner >= 0:
                cands.reverse()
        for idx, v in enumerate(cands):
            if v in occ_next:
                continue
            k = occ_now.get(v)
            if k is not None and k != i and (nxt[k] == here or (acyclic and k in active)):
                continue  # would swap places with an agent moving into our cell, or close
                # a cycle of moves (``acyclic``: k is still deciding, up our push chain)
            nxt[i] = v
            occ_next[v] = i
            if k is not None and k != i and nxt[k] == -1 and not push(k, i):
                continue
            if idx == 0 and partner >= 0 and nxt[partner] == -1 and here not in occ_next:
                nxt[partner] = here  # pull the partner along behind us
                occ_next[here] = partner
            return True
        nxt[i] = here
        occ_next[here] = i
        return False

    in_priority_order(prio, nxt, push)
    if len(occ_next) != n:
        return None  # a forced move left two agents on one cell
    return nxt


def pibt_oneshot(graph: MotionGraph, starts: Sequence[Cell], goals: Sequence[Cell],
                 deadline: float, seed: int = 0, max_steps: int | None = None,
                 guide: bool = False) -> tuple[list[list[Cell]] | None, dict]:
    """Plain PIBT until every agent stands on its goal (PIBT alone may livelock).
    ``guide``: follow guide paths (:mod:`~warerover_phys.planning.oneshot.scatter`)."""
    rng = np.random.default_rng(seed)
    s = [graph.node(c) for c in starts]
    g = [graph.node(c) for c in goals]
    dists = [graph.dist_to(c).tolist() for c in goals]  # lists: faster single reads
    nxt_of, guide_stats = None, None
    if guide:
        from ..oneshot.scatter import guide_for
        nxt_of, guide_stats = guide_for(graph, s, g, dists, seed, deadline)
    extra = {} if guide_stats is None else {"guide": guide_stats}
    prio = initial_priorities(dists, s)
    configs = [s]
    max_steps = max_steps or 20 * (graph.rows + graph.cols) + 1000
    while configs[-1] != g:
        if len(configs) > max_steps or time.monotonic() > deadline:
            return None, {"steps": len(configs) - 1, **extra}
        nxt = pibt_step(graph, configs[-1], dists, prio,
                        (rng.random(graph.num_nodes) * 0.5).tolist(), goals=g, guide=nxt_of)
        assert nxt is not None
        configs.append(nxt)
        prio = update_priorities(prio, nxt, g)
    return _to_paths(graph, configs), {"steps": len(configs) - 1, **extra}


def _to_paths(graph: MotionGraph, configs: list[list[int]]) -> list[list[Cell]]:
    cols = graph.cols
    return [[divmod(q[i], cols) for q in configs] for i in range(len(configs[0]))]
