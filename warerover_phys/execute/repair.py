"""Rotations repaired (:func:`repair_cycles`): each replaced by a local detour found as a
sliding puzzle around it, spliced into the plan, and the whole plan re-timed."""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..layout import Layout
from ..plans.model import Plan
from .cycles import Cycle, _cycles_dense
from .floor import PlanError
from .validation import _dense


@dataclass(frozen=True)
class Repair:
    """One repaired rotation: the agents of its local detour, and how long the detour is."""

    timestep: int
    """The rotation's timestep in the plan as given."""
    agents: tuple[int, ...]
    """The agents that move in the detour: the rotation's, and neighbours that step aside
    and back."""
    cells: tuple[tuple[int, int], ...]
    """The rotation's cells (row, column) just before it."""
    moves: int
    """Single-cell moves of the detour that replaces the rotation's one timestep."""

    def as_dict(self) -> dict[str, Any]:
        return {"timestep": self.timestep, "agents": list(self.agents),
                "cells": [list(c) for c in self.cells], "moves": self.moves}


def repair_cycles(plan: Plan, layout: Layout, sizes: list[int], *, strict: bool = False,
                  source: str | None = None, max_rounds: int | None = None,
                  ) -> tuple[Plan, list[Repair]]:
    """Break every rotation with a local detour, then re-time the plan (see the module
    docstring). ``strict``: raise :class:`PlanError` naming the first rotation instead.
    ``max_rounds``: most rotations repaired (default: ten per agent). A plan without
    rotations comes back as it is."""
    cols = layout.cols
    pos = _dense(plan)
    cycles = _cycles_dense(pos, cols)
    if not cycles:
        return plan, []
    first = cycles[0]
    if strict:
        raise PlanError(f"agents {list(first.agents)} move round a cycle through cells "
                        f"{[list(c) for c in first.cells]} (no execution order exists; "
                        "drop --strict to repair it)", file=source, agent=first.agents[0],
                        timestep=first.timestep)
    floor = _PuzzleFloor(layout)
    release = np.arange(len(pos), dtype=np.int64)  # each row's timestep in the given plan
    repairs: list[Repair] = []
    limit = max_rounds if max_rounds is not None else 10 * max(1, plan.num_agents)
    while cycles:
        if len(repairs) >= limit:
            raise PlanError(f"rotations remain after {limit} repairs", file=source)
        cyc = cycles[0]
        row = cyc.timestep
        moves, agents = _detour(pos, row, cyc, floor, sizes, cols, source,
                                int(release[row]))
        pos, release = _splice(pos, release, row, moves, cols)
        repairs.append(Repair(int(release[row + len(moves)]), agents, cyc.cells, len(moves)))
        cycles = _cycles_dense(pos, cols, start=row - 1)
    paths = _retime(pos, release, sizes, cols)
    return Plan(paths, rows=plan.rows, cols=plan.cols, map_name=plan.map_name,
                meta=plan.meta, fmt=plan.fmt), repairs


DETOUR_EXPANSIONS = 100_000
"""Search budget (joint states expanded) of one local detour."""
DETOUR_STAGES = ((2, -1), (3, -1), (3, 1), (4, 2), (6, 3))
"""The detour searches tried in turn: (how far from the rotation's cells the detour may go,
how far from them other 1x1 agents may step aside and back; -1: none may)."""
DETOUR_HELPERS = 8
"""Most neighbours that step aside in one detour."""


class _PuzzleFloor:
    """The moves of one 1x1 AGV between flat cell indices."""

    def __init__(self, layout: Layout) -> None:
        from ..planning.graph import GraphSet

        g = GraphSet(layout).get(1, False)
        self.neighbors = g.neighbors
        self.through = g.expandable_flat  # sinks (shelves ...) only as an agent's own cell


def _detour(pos: np.ndarray, row: int, cyc: Cycle, floor: _PuzzleFloor, sizes: list[int],
            cols: int, source: str | None, given_t: int, *,
            blocked: frozenset[int] = frozenset(), fixed: frozenset[int] = frozenset(),
            ) -> tuple[list[tuple[int, int]], tuple[int, ...]]:
    """Single-cell moves ``(agent, flat cell)``, one at a time, that take the rotation's
    agents from their cells at ``row - 1`` to their cells at ``row`` while everyone else
    stands (stages: :data:`DETOUR_STAGES`), and the agents that move. ``blocked``: more
    flat cells the detour may not use; ``fixed``: agents that may not step aside (the
    open-loop gap's recorded plans: AGVs mid-move or at work)."""
    before, after = pos[row - 1], pos[row]
    flat_b = before[:, 0] * cols + before[:, 1]
    flat_a = after[:, 0] * cols + after[:, 1]
    ring = list(cyc.agents)
    ring_cells = {int(flat_b[i]) for i in ring}
    k = np.asarray(sizes)
    for radius, helper_radius in DETOUR_STAGES:
        region = _region(floor, ring_cells, radius)
        helpers: list[int] = []
        if helper_radius >= 0:
            near = _region(floor, ring_cells, helper_radius)
            helpers = [int(i) for i in np.flatnonzero(k == 1)
                       if int(i) not in cyc.agents and int(i) not in fixed
                       and int(flat_b[i]) in near]
            helpers = helpers[:DETOUR_HELPERS]
        agents = ring + helpers
        free = region - _footprints(before, k, cols, exclude=set(agents)) - blocked
        starts = [int(flat_b[i]) for i in agents]
        goals = [int(flat_a[i]) for i in ring] + starts[len(ring):]
        found = _solve_puzzle(floor, free, starts, goals)
        if found is not None:
            return ([(agents[a], cell) for a, cell in found],
                    tuple(sorted({agents[a] for a, _ in found})))
    raise PlanError(f"cannot repair the rotation of agents {ring} through cells "
                    f"{[list(c) for c in cyc.cells]}: no local detour within "
                    f"{DETOUR_STAGES[-1][0]} cells of it (run with --strict to see it, or "
                    "fix the plan)", file=source, agent=ring[0], timestep=given_t)


def _footprints(cells: np.ndarray, k: np.ndarray, cols: int, exclude: set[int]) -> set[int]:
    """Flat cells covered by the agents at ``cells`` (anchors, footprints ``k``), but those
    of the agents in ``exclude``."""
    out: set[int] = set()
    for i, (r, c) in enumerate(cells.tolist()):
        if i in exclude:
            continue
        for dr in range(int(k[i])):
            for dc in range(int(k[i])):
                out.add((r + dr) * cols + c + dc)
    return out


def _region(floor: _PuzzleFloor, cells: set[int], radius: int) -> set[int]:
    """Cells within ``radius`` moves of ``cells``."""
    seen = set(cells)
    frontier = list(cells)
    for _ in range(radius):
        nxt = []
        for u in frontier:
            for v in floor.neighbors[u]:
                if v not in seen:
                    seen.add(v)
                    nxt.append(v)
        frontier = nxt
    return seen


def _solve_puzzle(floor: _PuzzleFloor, free: set[int], starts: list[int],
                  goals: list[int]) -> list[tuple[int, int]] | None:
    """Fewest single-cell moves ``(agent index, cell)``, one agent at a time, each into an
    empty cell of ``free``, from ``starts`` to ``goals``: A* on the joint state with the sum
    of distances as its (admissible) heuristic. None if there is none within
    :data:`DETOUR_EXPANSIONS`."""
    own = set(starts) | set(goals)
    usable = {v for v in free if floor.through[v] or v in own}
    dist = []
    for g in goals:  # breadth-first distances to each goal within the usable cells
        d = {g: 0}
        frontier = [g]
        while frontier:
            nxt = []
            for u in frontier:
                for v in floor.neighbors[u]:
                    if v in usable and v not in d:
                        d[v] = d[u] + 1
                        nxt.append(v)
            frontier = nxt
        dist.append(d)
    start, goal = tuple(starts), tuple(goals)
    if any(s not in d for s, d in zip(start, dist, strict=True)):
        return None
    parent: dict[tuple[int, ...], tuple[tuple[int, ...], int, int] | None] = {start: None}
    cost = {start: 0}
    h0 = sum(d[c] for c, d in zip(start, dist, strict=True))
    heap = [(h0, 0, start)]
    expanded = 0
    while heap:
        _, g_cost, state = heapq.heappop(heap)
        if state == goal:
            moves = []
            while (link := parent[state]) is not None:
                state, a, cell = link
                moves.append((a, cell))
            return moves[::-1]
        if g_cost > cost[state]:
            continue
        expanded += 1
        if expanded > DETOUR_EXPANSIONS:
            return None
        taken = set(state)
        h = sum(d[c] for c, d in zip(state, dist, strict=True))
        for a, u in enumerate(state):
            da = dist[a]
            for v in floor.neighbors[u]:
                if v in taken or v not in da:
                    continue
                nxt = state[:a] + (v,) + state[a + 1:]
                ng = g_cost + 1
                if ng < cost.get(nxt, 1 << 60):
                    cost[nxt] = ng
                    parent[nxt] = (state, a, v)
                    heapq.heappush(heap, (ng + h - da[u] + da[v], ng, nxt))
    return None


def _splice(pos: np.ndarray, release: np.ndarray, row: int, moves: list[tuple[int, int]],
            cols: int) -> tuple[np.ndarray, np.ndarray]:
    """``pos`` with one row per detour move inserted before ``row``, everyone else
    standing; the detour ends where ``row`` has its agents (the rotation's agents stand
    through ``row``, the others make their own moves of ``row``). The inserted rows are
    released at the rotation's timestep."""
    cur = pos[row - 1].copy()
    rows = []
    for agent, cell in moves:
        cur = cur.copy()
        cur[agent] = divmod(cell, cols)
        rows.append(cur)
    new = np.concatenate([pos[:row], np.asarray(rows).reshape(-1, *pos.shape[1:]),
                          pos[row:]])
    rel = np.concatenate([release[:row], np.full(len(rows), release[row]), release[row:]])
    return new, rel


def _retime(pos: np.ndarray, release: np.ndarray, sizes: list[int], cols: int,
            ) -> tuple[tuple[tuple[int, int], ...], ...]:
    """The plan ``pos`` executed as early as its order allows, no move before its own
    timestep in the given plan (``release``): each agent makes its moves in turn, each cell
    is visited in the same order as in ``pos``, and an agent may enter a cell in the
    timestep its last visitor leaves it (following), but never round a cycle. A plan without
    detours comes back unchanged; a detour delays only what waits on it."""
    n = pos.shape[1]
    moves, holder, turn, begun = _retime_moves(pos, release, sizes, cols)
    ptr = [0] * n
    out: list[list[tuple[int, int]]] = [[(int(pos[0, i, 0]), int(pos[0, i, 1]))]
                                        for i in range(n)]
    pending = sum(len(m) for m in moves)
    tick = 0
    while pending:
        tick += 1
        ready = [i for i in range(n) if ptr[i] < len(moves[i])
                 and moves[i][ptr[i]][0] <= tick
                 and all(turn[(v, i, ptr[i])] == begun[v] + 1 for v in moves[i][ptr[i]][1])]
        chosen = _retime_chosen(ready, moves, ptr, holder)
        if not chosen:
            if all(moves[i][ptr[i]][0] <= tick for i in range(n) if ptr[i] < len(moves[i])):
                raise AssertionError("re-timing a cycle-free plan stalled")  # pragma: no cover
            for i in range(n):
                out[i].append(out[i][-1])
            continue
        for i in chosen:
            for v in moves[i][ptr[i]][2]:
                if holder.get(v) == i:
                    del holder[v]
        for i in chosen:
            for v in moves[i][ptr[i]][1]:
                holder[v] = i
                begun[v] += 1
            out[i].append(moves[i][ptr[i]][3])
            ptr[i] += 1
            pending -= 1
        for i in range(n):
            if i not in chosen:
                out[i].append(out[i][-1])
    return tuple(_trim(p) for p in out)


def _retime_moves(pos: np.ndarray, release: np.ndarray, sizes: list[int], cols: int):
    """For :func:`_retime`: each agent's moves (release, cells entered, cells left, new
    anchor), who holds each cell at the start, each visit's place in its cell's order
    (``(cell, agent, move) -> place``; place 0 is the cell's first occupant) and the visits
    begun at each cell (0)."""
    n = pos.shape[1]
    k = [int(s) for s in sizes]

    def cells_of(p: np.ndarray, i: int) -> frozenset[int]:
        r, c = int(p[0]), int(p[1])
        return frozenset((r + dr) * cols + c + dc for dr in range(k[i]) for dc in range(k[i]))

    anchors = pos[..., 0] * cols + pos[..., 1]
    changed = anchors[1:] != anchors[:-1]
    # Each agent's moves (release, cells entered, cells left, new anchor), and every visit
    # to a cell as (row it starts, agent, move index; -1 for where the agent starts).
    moves: list[list[tuple[int, frozenset[int], frozenset[int], tuple[int, int]]]] = []
    starts: list[tuple[int, int, int, int]] = []
    holder: dict[int, int] = {}
    for i in range(n):
        occ = cells_of(pos[0, i], i)
        for v in occ:
            holder[v] = i
        mine = []
        for s in (np.flatnonzero(changed[:, i]) + 1).tolist():
            new = cells_of(pos[s, i], i)
            starts.extend((s, i, len(mine), v) for v in new - occ)
            mine.append((int(release[s]), new - occ, occ - new,
                         (int(pos[s, i, 0]), int(pos[s, i, 1]))))
            occ = new
        moves.append(mine)
    starts.sort()
    turn: dict[tuple[int, int, int], int] = {}  # (cell, agent, move) -> its place at the cell
    count: dict[int, int] = {}
    for _, i, m, v in starts:
        count[v] = count.get(v, 0) + 1
        turn[(v, i, m)] = count[v]  # visit 0 is the cell's first occupant (or none)
    begun = dict.fromkeys(count, 0)  # visits begun at each cell after the first
    return moves, holder, turn, begun


def _retime_chosen(ready: list[int], moves: list, ptr: list[int], holder: dict[int, int]
                   ) -> set[int]:
    """For :func:`_retime`: the ready agents that move this timestep: into free cells, or
    following an agent that moves this timestep and leaves the cell."""
    chosen: set[int] = set()
    waiting: dict[int, list[int]] = {}
    work = list(ready)
    while work:
        i = work.pop()
        if i in chosen:
            continue
        entered = moves[i][ptr[i]][1]
        ok = True
        for v in entered:
            h = holder.get(v)
            if h is None:
                continue
            if h not in chosen:
                waiting.setdefault(h, []).append(i)  # it may follow h this timestep
                ok = False
                break
            if v not in moves[h][ptr[h]][2]:
                ok = False  # h moves but keeps this cell
                break
        if ok:
            chosen.add(i)
            work.extend(waiting.pop(i, []))
    return chosen


def _trim(path: list[tuple[int, int]]) -> tuple[tuple[int, int], ...]:
    """``path`` without the copies of its last cell at its end."""
    end = len(path)
    while end > 1 and path[end - 2] == path[-1]:
        end -= 1
    return tuple(path[:end])
