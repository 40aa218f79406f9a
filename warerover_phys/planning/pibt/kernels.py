"""Lifelong PIBT steps compiled with numba: the same plans as the Python reference steps.

:func:`~.pibt.pibt_step` (with swaps, no forced moves, no guide, no per-robot tables) and
:func:`~.pibt_heading.heading_pibt_step` written again over flat integer arrays and compiled
with ``numba.njit(cache=True)``: the configuration, the robots' distance tables (rows of one
2-D array and each robot's row, :func:`robot_tables`), a neighbour table of the free-cell
graph (:class:`StepTables`), the tie-break values and the order of the robots (highest
priority first, as :func:`~.pibt.in_priority_order` sorts them). Every comparison, every
floating-point sum and every sort is the reference's, in the same order (stable insertion
sorts over at most five candidates), so for the same seed both give the same next cells,
headings and actions; ``tests/planning/test_pibt_numba.py`` checks it on random grids and
over whole lifelong runs. The Python steps stay the reference (and the fallback when numba
is missing: :data:`AVAILABLE`).

``facing=True`` is the ``turn-first`` rule's cost (:class:`~.pibt_heading.Facing`): a robot's distance
plus the quarter turns to face each of the four cells next to it, keyed as that class keys
them (``(row + dr) * cols + col + dc``, which wraps at the map's side columns; kept so that
plans stay the same).

Compile time: the first call in a process without numba's cache compiles (seconds); with
``cache=True`` later processes load the machine code from ``__pycache__``
(:func:`warm_up` does either).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..graph import UNREACHABLE

try:
    import numba
    from numba import njit
    AVAILABLE = True
except ImportError:  # pragma: no cover - numba is a dependency; the Python steps remain
    numba = None
    AVAILABLE = False

    def njit(*args, **kwargs):  # type: ignore[no-redef]
        if args and callable(args[0]):
            return args[0]
        return lambda f: f

__all__ = ["AVAILABLE", "StepTables", "step_tables", "pibt_step_nb", "robot_tables", "warm_up",
           "ACT_CODES", "bfs_fill", "priority_order", "nearest_open"]
# the heading steps (heading_step_nb, turn_first_nb) are in .heading_kernels

ACT_CODES = {"F": ord("F"), "R": ord("R"), "C": ord("C"), "W": ord("W")}
_F, _R, _C, _W = ord("F"), ord("R"), ord("C"), ord("W")
_UNR = UNREACHABLE
_STEP = ((0, 1), (1, 0), (0, -1), (-1, 0))


@dataclass(frozen=True)
class StepTables:
    """The free-cell graph as arrays (computed once per map)."""

    nbr: np.ndarray
    """``(cells, 4)`` int32: the neighbours of each cell in ``graph.neighbors`` order, -1
    padded."""
    deg: np.ndarray
    """``(cells,)`` int32: how many neighbours."""
    nbr_dir: np.ndarray
    """``(cells, 4)`` int32: the heading (0-3, east, south, west, north) pointing at each
    neighbour."""
    ahead: np.ndarray
    """``(cells, 4)`` int32: the neighbour ahead for each heading, -1 when none."""
    turns: np.ndarray
    """``(16, 4)`` int32: quarter turns from a heading to a heading in a bit set (2: empty)."""
    cols: int


def step_tables(neighbors: Sequence[Sequence[int]], cols: int) -> StepTables:
    """:class:`StepTables` of a graph's ``neighbors`` lists (cells ``row * cols + col``)."""
    from .heading import _TURNS
    cells = len(neighbors)
    nbr = np.full((cells, 4), -1, dtype=np.int32)
    nbr_dir = np.full((cells, 4), -1, dtype=np.int32)
    ahead = np.full((cells, 4), -1, dtype=np.int32)
    deg = np.zeros(cells, dtype=np.int32)
    for v, near in enumerate(neighbors):
        r, c = divmod(v, cols)
        deg[v] = len(near)
        for t, u in enumerate(near):
            h = _STEP.index((u // cols - r, u % cols - c))
            nbr[v, t] = u
            nbr_dir[v, t] = h
            ahead[v, h] = u
    return StepTables(nbr, deg, nbr_dir, ahead, np.asarray(_TURNS, dtype=np.int32), cols)


def robot_tables(tables: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The robots' distance tables as the steps read them: ``(slab, rows)``, a 2-D array of
    tables (one dtype) and the row of each robot's table (``DistStore(reserve=...)`` keeps
    its tables in such a slab already: ``(store.slab, rows)``). A ``numba.typed.List`` of
    arrays was 10x slower to read from compiled code (210 against 21 ns a read)."""
    ids: dict[int, int] = {}
    uniq: list[np.ndarray] = []
    rows = np.empty(len(tables), dtype=np.int64)
    for i, t in enumerate(tables):
        j = ids.setdefault(id(t), len(uniq))
        if j == len(uniq):
            uniq.append(t)
        rows[i] = j
    return np.stack(uniq), rows


# ---------------------------------------------------------------------------- cell PIBT

@njit(cache=True, inline="always")
def _dist(tables, i, v, facing, config, heading, cols):
    """Robot ``i``'s cost of cell ``v``: its table, plus (``facing``) the turns to face the
    cell as :class:`~.pibt_heading.Facing` counts them."""
    d = np.int64(tables[0][tables[1][i], v])
    if facing:
        here = config[i]
        r = here // cols
        c = here - r * cols
        hd = heading[i]
        extra = -1
        for h in range(4):
            if h == 0:
                key = r * cols + c + 1
            elif h == 1:
                key = (r + 1) * cols + c
            elif h == 2:
                key = r * cols + c - 1
            else:
                key = (r - 1) * cols + c
            if key == v:
                t = (h - hd) % 4
                extra = min(t, 4 - t)
        if extra > 0:
            d += extra
    return d


@njit(cache=True)
def _free_branches(v, came_from, agent, tables, nbr, deg, occ_now, goal, facing, config,
                   heading, cols):
    count = 0
    last = -1
    g = tables[2][agent]
    for t in range(deg[g, v]):
        u = nbr[g, v, t]
        a = occ_now[u]
        if u == came_from or _dist(tables, agent, u, facing, config, heading, cols) >= _UNR \
                or (deg[0, u] == 1 and a >= 0 and goal[a] == u):
            continue
        count += 1
        last = u
    return count, last


@njit(cache=True)
def _swap_required(pusher, puller, v_pusher, v_puller, tables, nbr, deg, occ_now, goal,
                   facing, config, heading, cols):
    while _dist(tables, pusher, v_puller, facing, config, heading, cols) < \
            _dist(tables, pusher, v_pusher, facing, config, heading, cols):
        count, nxt_v = _free_branches(v_puller, v_pusher, puller, tables, nbr, deg, occ_now,
                                      goal, facing, config, heading, cols)
        if count >= 2:
            return False
        if count == 0:
            break
        v_pusher, v_puller = v_puller, nxt_v
    dp_push = _dist(tables, pusher, v_pusher, facing, config, heading, cols)
    return _dist(tables, puller, v_pusher, facing, config, heading, cols) < \
        _dist(tables, puller, v_puller, facing, config, heading, cols) and (
            dp_push == 0 or _dist(tables, pusher, v_puller, facing, config, heading, cols)
            < dp_push)


@njit(cache=True)
def _swap_possible(agent, v_pusher, v_puller, tables, nbr, deg, occ_now, goal, facing, config,
                   heading, cols):
    origin = v_pusher
    while v_puller != origin:
        count, nxt_v = _free_branches(v_puller, v_pusher, agent, tables, nbr, deg, occ_now,
                                      goal, facing, config, heading, cols)
        if count >= 2:
            return True
        if count == 0:
            return False
        v_pusher, v_puller = v_puller, nxt_v
    return False


@njit(cache=True)
def _swap_partner(i, best, tables, nbr, deg, occ_now, nxt, goal, facing, config, heading,
                  cols):
    here = config[i]
    if best == here:
        return -1
    j = occ_now[best]
    if j >= 0 and nxt[j] == -1 and _swap_required(
            i, j, here, best, tables, nbr, deg, occ_now, goal, facing, config, heading, cols) \
            and _swap_possible(i, best, here, tables, nbr, deg, occ_now, goal, facing, config,
                               heading, cols):
        return j
    d_here = _dist(tables, i, here, facing, config, heading, cols)
    d_best = _dist(tables, i, best, facing, config, heading, cols)
    g = tables[2][i]
    for t in range(deg[g, here]):
        u = nbr[g, here, t]
        k = occ_now[u]
        if k < 0 or best == config[k]:
            continue
        if _dist(tables, k, best, facing, config, heading, cols) >= \
                _dist(tables, k, here, facing, config, heading, cols) and d_here >= d_best:
            continue
        if _swap_required(k, i, here, best, tables, nbr, deg, occ_now, goal, facing, config,
                          heading, cols) \
                and _swap_possible(i, best, here, tables, nbr, deg, occ_now, goal, facing,
                                   config, heading, cols):
            return k
    return -1


@njit(cache=True)
def _guide_next(gkeys, gvals, key):
    """The next cell of a guide path (:func:`~.lacam.kernels.guide_arrays`: sorted
    ``gkeys``, their next cells ``gvals``) at ``key = agent * cells + cell``; -1: none."""
    lo = 0
    hi = gkeys.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if gkeys[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    if lo < gkeys.shape[0] and gkeys[lo] == key:
        return gvals[lo]
    return -1


@njit(cache=True)
def _setup(f, i, ag, cand, ncand, part, idx, tables, nbr, deg, occ_now, nxt, goal, tie, facing,
           config, heading, cols, gkeys, gvals, cells):
    """Frame ``f`` of the push stack for robot ``i``: its candidate cells, best first (the
    reference's sort: stable, by distance plus tie), its guide cell (LaCAM's guide paths,
    ``gkeys`` / ``gvals``; none when empty) moved to the front before its swap partner is
    looked for (as the reference's ``push``), reversed when it has a swap partner."""
    here = config[i]
    keys = np.empty(5, dtype=np.float64)
    m = 0
    g = tables[2][i]
    m_here = deg[g, here]
    for t in range(m_here + 1):
        v = nbr[g, here, t] if t < m_here else here
        dv = _dist(tables, i, v, facing, config, heading, cols)
        if t < m_here and dv >= _UNR:
            continue
        key = float(dv) + tie[v]
        j = m  # stable insertion: equal keys keep their order
        while j > 0 and keys[j - 1] > key:
            keys[j] = keys[j - 1]
            cand[f, j] = cand[f, j - 1]
            j -= 1
        keys[j] = key
        cand[f, j] = v
        m += 1
    if gkeys.shape[0] > 0:
        first = _guide_next(gkeys, gvals, i * cells + here)
        if first >= 0 and first != cand[f, 0]:
            at = -1
            for j in range(m):
                if cand[f, j] == first:
                    at = j
                    break
            if at > 0:
                for j in range(at, 0, -1):
                    cand[f, j] = cand[f, j - 1]
                cand[f, 0] = first
    partner = _swap_partner(i, cand[f, 0], tables, nbr, deg, occ_now, nxt, goal, facing,
                            config, heading, cols)
    if partner >= 0:
        for j in range(m // 2):
            cand[f, j], cand[f, m - 1 - j] = cand[f, m - 1 - j], cand[f, j]
    ag[f] = i
    ncand[f] = m
    part[f] = partner
    idx[f] = 0


@njit(cache=True)
def _push(root, ag, cand, ncand, part, idx, tables, nbr, deg, occ_now, occ_next, nxt, goal,
          tie, facing, config, heading, cols, instack, acyclic, gkeys, gvals, cells):
    """The reference's recursive ``push(root, -1)`` run on an explicit stack (numba cannot
    cache recursive functions): a frame per robot asked to move, its next candidate in
    ``idx``; a child's answer resumes its parent at that candidate. ``acyclic``: no robot
    enters the cell of a robot on the stack (that would close a cycle of moves).
    ``gkeys`` / ``gvals`` / ``cells``: LaCAM's guide paths (empty: none; see
    :func:`_setup`); LaCAM's compiled step pushes with this function too."""
    f = 0
    _setup(0, root, ag, cand, ncand, part, idx, tables, nbr, deg, occ_now, nxt, goal, tie,
           facing, config, heading, cols, gkeys, gvals, cells)
    instack[root] = True
    ret = False
    resume = False
    while f >= 0:
        i = ag[f]
        here = config[i]
        if resume:
            resume = False
            if ret:
                q = idx[f]
                partner = part[f]
                if q == 0 and partner >= 0 and nxt[partner] == -1 and occ_next[here] < 0:
                    nxt[partner] = here  # pull the partner along behind us
                    occ_next[here] = partner
                instack[i] = False
                f -= 1
                resume = True
                continue
            idx[f] += 1
        descended = False
        while idx[f] < ncand[f]:
            q = idx[f]
            v = cand[f, q]
            if occ_next[v] >= 0:
                idx[f] += 1
                continue
            k = occ_now[v]
            if k >= 0 and k != i and (nxt[k] == here or (acyclic and instack[k])):
                idx[f] += 1
                continue
            nxt[i] = v
            occ_next[v] = i
            if k >= 0 and k != i and nxt[k] == -1:
                f += 1
                _setup(f, k, ag, cand, ncand, part, idx, tables, nbr, deg, occ_now, nxt, goal,
                       tie, facing, config, heading, cols, gkeys, gvals, cells)
                instack[k] = True
                descended = True
                break
            partner = part[f]
            if q == 0 and partner >= 0 and nxt[partner] == -1 and occ_next[here] < 0:
                nxt[partner] = here
                occ_next[here] = partner
            ret = True
            instack[i] = False
            f -= 1
            resume = True
            descended = True
            break
        if descended:
            continue
        nxt[i] = here
        occ_next[here] = i
        ret = False
        instack[i] = False
        f -= 1
        resume = True
    return ret


@njit(cache=True)
def _pibt_kernel(nbr, deg, config, goal, tables, order, tie, facing, heading, cols, held,
                 acyclic):
    n = config.shape[0]
    cells = nbr.shape[1]
    instack = np.zeros(n, dtype=np.bool_)
    occ_now = np.full(cells, -1, dtype=np.int64)
    occ_next = np.full(cells, -1, dtype=np.int64)
    nxt = np.full(n, -1, dtype=np.int64)
    ag = np.empty(n, dtype=np.int64)
    cand = np.empty((n, 5), dtype=np.int64)
    ncand = np.empty(n, dtype=np.int64)
    part = np.empty(n, dtype=np.int64)
    idx = np.empty(n, dtype=np.int64)
    no_guide = np.zeros(0, dtype=np.int64)
    for i in range(n):
        occ_now[config[i]] = i
    for i in range(n):  # held robots stay (the reference's forced moves onto their cells)
        if held[i]:
            nxt[i] = config[i]
            occ_next[config[i]] = i
    for r in range(n):
        i = order[r]
        if nxt[i] == -1:
            _push(i, ag, cand, ncand, part, idx, tables, nbr, deg, occ_now, occ_next, nxt, goal,
                  tie, facing, config, heading, cols, instack, acyclic, no_guide, no_guide,
                  cells)
    return nxt


def priority_order(prio) -> np.ndarray:
    """The robots highest priority first, ties in index order (as ``sorted(range(n),
    key=lambda i: -prio[i])``)."""
    return np.argsort(-np.asarray(prio, dtype=np.float64), kind="stable")


def pibt_step_nb(st: StepTables, config: np.ndarray, goal: np.ndarray, tables, order: np.ndarray,
                 tie: np.ndarray, heading: np.ndarray | None = None,
                 held: np.ndarray | None = None,
                 moves: tuple[tuple[StepTables, ...], np.ndarray] | None = None,
                 acyclic: bool = False) -> np.ndarray:
    """:func:`~.pibt.pibt_step` (``goals=goal``, swaps on) compiled: the next cell of every
    robot. ``tables``: :func:`robot_tables`; ``order``: :func:`priority_order` of the
    priorities; ``tie``: the tie-break per cell (float64). With ``heading``, the costs of
    the ``turn-first`` rule (see the module docstring). ``held``: a bool per robot, True
    for robots that must stay (the reference's ``forced`` moves onto their own cells).
    ``moves``: robots that move on graphs of their own (the reference's ``tables``, e.g.
    loaded AGVs on the loaded graph): the graphs' step tables (the first is ``st``, whose
    degrees decide dead ends) and each robot's graph index. ``acyclic``: no cycle of moves
    (robots rotating into each other's cells, which an action dependency graph cannot
    run; the reference's ``acyclic``)."""
    facing = heading is not None
    hd = np.asarray(heading if facing else np.zeros(1), dtype=np.int64)
    config = np.asarray(config, dtype=np.int64)
    held = np.zeros(len(config), dtype=np.bool_) if held is None else \
        np.asarray(held, dtype=np.bool_)
    if moves is None:
        nbr, deg, gi = st.nbr[None], st.deg[None], np.zeros(len(config), dtype=np.int64)
    else:
        nbr = np.stack([t.nbr for t in moves[0]])
        deg = np.stack([t.deg for t in moves[0]])
        gi = np.asarray(moves[1], dtype=np.int64)
    return _pibt_kernel(nbr, deg, config, np.asarray(goal, dtype=np.int64),
                        (tables[0], tables[1], gi), np.asarray(order, dtype=np.int64),
                        np.asarray(tie, dtype=np.float64), facing, hd, st.cols, held,
                        bool(acyclic))


# ------------------------------------------------------------------------- heading PIBT


@njit(cache=True)
def nearest_open(fr, fc, rr, rc):  # pragma: no cover - compiled
    """Greedy nearest-task assignment: robot ``q`` (row ``rr[q]``, column ``rc[q]``), in
    order, takes the untaken task nearest by Manhattan distance (first errand at ``fr``,
    ``fc``; the first such on ties); -1 from the first robot that finds none left."""
    m = fr.shape[0]
    taken = np.zeros(m, dtype=np.bool_)
    out = np.full(rr.shape[0], -1, dtype=np.int64)
    for q in range(rr.shape[0]):
        best = -1
        bd = 0
        for j in range(m):
            if taken[j]:
                continue
            d = abs(fr[j] - rr[q]) + abs(fc[j] - rc[q])
            if best < 0 or d < bd:
                best = j
                bd = d
        if best < 0:
            break
        taken[best] = True
        out[q] = best
    return out


@njit(cache=True)
def bfs_fill(indptr, indices, free, source, table):  # pragma: no cover - compiled
    """Breadth-first search from compact cell ``source`` over a CSR graph (``indptr``,
    ``indices``), writing each reached cell's depth into ``table`` at its map cell
    ``free[c]`` (the rest of ``table`` is left as it is): :class:`~.dist_store.DistStore`'s
    tables."""
    m = indptr.shape[0] - 1
    depth = np.full(m, -1, dtype=np.int32)
    queue = np.empty(m, dtype=np.int32)
    depth[source] = 0
    queue[0] = source
    head, tail = 0, 1
    while head < tail:
        v = queue[head]
        head += 1
        dv = depth[v] + 1
        for e in range(indptr[v], indptr[v + 1]):
            u = indices[e]
            if depth[u] < 0:
                depth[u] = dv
                queue[tail] = u
                tail += 1
    for q in range(tail):
        v = queue[q]
        table[free[v]] = depth[v]


def warm_up(dtype=np.uint16) -> None:
    """Compile (or load from numba's cache) the cell steps for tables of ``dtype`` on a 1 x 3
    corridor (the heading steps: :func:`.heading_kernels.warm_up`)."""
    if not AVAILABLE:
        return
    st = step_tables([(1,), (0, 2), (1,)], 3)
    tabs = robot_tables([np.array([2, 1, 0], dtype=dtype)])
    one = np.zeros(1, dtype=np.int64)
    pibt_step_nb(st, one, np.array([2]), tabs, one, np.zeros(3))
    pibt_step_nb(st, one, np.array([2]), tabs, one, np.zeros(3), heading=one)
    nearest_open(one, one, one, one)
