"""The guide-path search of :mod:`.scatter` compiled with numba: the same paths.

:func:`~.scatter.guide_paths` plans the agents one after the other, each by an A* over cells
ordered by (collisions so far, f), against the space-time occupancy of the others' paths.
Here the occupancy table and the search are written again over flat integer arrays and
compiled with ``numba.njit(cache=True)``; every count and every comparison is the
reference's (:class:`~.scatter._Table`, :func:`~.scatter._search`), and the heap pops in
the same order (its entries compare as the reference's tuples ``(key, -g, node, parent)``,
which are all distinct), so for the same generator both give the same paths, collision
counts and rounds (``tests/planning/test_scatter_numba.py``).

The table: an agent is at most once on a tick, so its entry for tick ``t`` is row
``i * horizon + t``; the entries at (tick, node) are a doubly linked list from
``head[t * n + v]``, and each entry keeps the agent's next node (-1 at its path's end), so a
swap with a move ``v -> u`` is an entry at (t, u) whose next node is ``v``. ``count[t * n +
v]`` is the list's length; the paths ending at a node are another list (one entry per agent).

Compile time: the first call without numba's cache compiles (seconds); later processes
load the machine code from ``__pycache__`` (numba's import, ~0.35 s of CPU, and the load
count against the whole ``solve`` process, so :func:`~.scatter.guide_paths` uses this
module only for larger instances).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..graph import UNREACHABLE

__all__ = ["NbTable", "compiled_ready", "csr", "goal_bfs", "run_agents"]

_BIG = 1 << 24  # as scatter._BIG


def csr(neighbors: Sequence[Sequence[int]]) -> tuple[np.ndarray, np.ndarray]:
    """``neighbors`` lists as (indptr, indices) int64 arrays, in list order."""
    lengths = np.fromiter((len(x) for x in neighbors), dtype=np.int64, count=len(neighbors))
    indptr = np.zeros(len(neighbors) + 1, dtype=np.int64)
    np.cumsum(lengths, out=indptr[1:])
    indices = np.fromiter((u for x in neighbors for u in x), dtype=np.int64,
                          count=int(indptr[-1]))
    return indptr, indices


class NbTable:
    """The arrays of the occupancy table and of the paths (see the module text)."""

    def __init__(self, num_nodes: int, num_agents: int, horizon: int) -> None:
        n, h = num_nodes, horizon
        self.n, self.horizon = n, h
        self.count = np.zeros(h * n, dtype=np.int32)
        self.head = np.full(h * n, -1, dtype=np.int64)
        self.link = np.full((num_agents * h, 2), -1, dtype=np.int64)  # next, previous entry
        self.after = np.full(num_agents * h, -1, dtype=np.int64)  # the agent's next node
        self.end_head = np.full(n, -1, dtype=np.int64)
        self.end_link = np.full((num_agents, 2), -1, dtype=np.int64)
        self.end_last = np.zeros(num_agents, dtype=np.int64)
        self.paths = np.zeros((num_agents, h), dtype=np.int64)
        self.lengths = np.zeros(num_agents, dtype=np.int64)  # 0: no path
        # search scratch: lowest key pushed and parent per node, valid where stamp matches
        self.best = np.zeros(n, dtype=np.int64)
        self.best_stamp = np.zeros(n, dtype=np.int64)
        self.parent = np.zeros(n, dtype=np.int64)
        self.closed_stamp = np.zeros(n, dtype=np.int64)
        self.heap = np.zeros((1024, 4), dtype=np.int64)
        self.state = np.zeros(2, dtype=np.int64)  # collisions, search stamp


@njit(cache=True)
def _step_cost(count, head, link, after, end_head, end_link, end_last, n, u, v, t):
    """Collisions of a move u -> v from tick t to t + 1 (``_Table.step_cost``)."""
    c = count[(t + 1) * n + v]
    e = head[t * n + v]
    while e != -1:  # at v at t and at u at t + 1
        if after[e] == u:
            c += 1
        e = link[e, 0]
    j = end_head[v]
    while j != -1:
        if t + 1 > end_last[j]:
            c += 1
        j = end_link[j, 0]
    return c


@njit(cache=True)
def _path_cost(count, head, link, after, end_head, end_link, end_last, n, horizon, path,
               length):
    """``_Table._path_cost``: the path's step costs and the others passing its goal later."""
    c = 0
    for t in range(1, length):
        c += _step_cost(count, head, link, after, end_head, end_link, end_last, n,
                        path[t - 1], path[t], t - 1)
    goal = path[length - 1]
    for t in range(length, horizon):
        c += count[t * n + goal]
    return c


@njit(cache=True)
def _add(count, head, link, after, end_head, end_link, end_last, n, horizon, i, path, length):
    for t in range(length):
        v = path[t]
        e = i * horizon + t
        k = t * n + v
        after[e] = path[t + 1] if t + 1 < length else -1
        first = head[k]
        link[e, 0] = first
        link[e, 1] = -1
        if first != -1:
            link[first, 1] = e
        head[k] = e
        count[k] += 1
    goal = path[length - 1]
    first = end_head[goal]
    end_link[i, 0] = first
    end_link[i, 1] = -1
    if first != -1:
        end_link[first, 1] = i
    end_head[goal] = i
    end_last[i] = length - 1


@njit(cache=True)
def _remove(count, head, link, end_head, end_link, n, horizon, i, path, length):
    for t in range(length):
        k = t * n + path[t]
        e = i * horizon + t
        nx, pv = link[e, 0], link[e, 1]
        if pv != -1:
            link[pv, 0] = nx
        else:
            head[k] = nx
        if nx != -1:
            link[nx, 1] = pv
        count[k] -= 1
    nx, pv = end_link[i, 0], end_link[i, 1]
    if pv != -1:
        end_link[pv, 0] = nx
    else:
        end_head[path[length - 1]] = nx
    if nx != -1:
        end_link[nx, 1] = pv


@njit(cache=True)
def _less(heap, a, b):
    for c in range(4):
        if heap[a, c] != heap[b, c]:
            return heap[a, c] < heap[b, c]
    return False


@njit(cache=True)
def _swap_rows(heap, a, b):
    for c in range(4):
        x = heap[a, c]
        heap[a, c] = heap[b, c]
        heap[b, c] = x


@njit(cache=True)
def _search(indptr, indices, count, head, link, after, end_head, end_link, end_last, n,
            start, goal, dist, margin, best, best_stamp, parent, closed_stamp, heap, stamp,
            out):
    """``scatter._search``: writes the path into ``out`` and returns its length (0: none)
    and the heap (grown when full).

    A compiled kernel, long on purpose: numba compiles one function into one loop nest, and
    this one is the reference's A* step for step (open list, stamps, path read-back) so that
    both give the same paths; split into calls it would pass its twenty arrays at every
    expansion."""
    if start == goal:
        out[0] = start
        return 1, heap
    ds = dist[start]
    if ds >= UNREACHABLE:
        return 0, heap
    ub = ds + margin
    size = 1
    heap[0, 0] = ds
    heap[0, 1] = 0
    heap[0, 2] = start
    heap[0, 3] = -1
    while size > 0:
        key, neg_g, v, par = heap[0, 0], heap[0, 1], heap[0, 2], heap[0, 3]
        size -= 1
        if size > 0:  # pop: the last entry to the root, sifted down
            for c in range(4):
                heap[0, c] = heap[size, c]
            k = 0
            while True:
                left = 2 * k + 1
                if left >= size:
                    break
                m = left
                if left + 1 < size and _less(heap, left + 1, left):
                    m = left + 1
                if _less(heap, m, k):
                    _swap_rows(heap, m, k)
                    k = m
                else:
                    break
        if closed_stamp[v] == stamp:
            continue
        closed_stamp[v] = stamp
        parent[v] = par
        if v == goal:
            length = 0
            w = v
            while True:
                out[length] = w
                length += 1
                if w == start:
                    break
                w = parent[w]
            for a in range(length // 2):
                x = out[a]
                out[a] = out[length - 1 - a]
                out[length - 1 - a] = x
            return length, heap
        g = -neg_g
        t1 = g + 1
        c0 = key // _BIG
        for p in range(indptr[v], indptr[v + 1]):
            u = indices[p]
            if u == start or closed_stamp[u] == stamp:
                continue
            du = dist[u]
            if du >= UNREACHABLE:
                continue
            f = t1 + du
            if f > ub:
                continue
            cc = c0 + count[t1 * n + u]
            e = head[g * n + u]
            while e != -1:  # at u at g and at v at g + 1: a swap
                if after[e] == v:
                    cc += 1
                e = link[e, 0]
            j = end_head[u]
            while j != -1:
                if t1 > end_last[j]:
                    cc += 1
                j = end_link[j, 0]
            k2 = cc * _BIG + f
            if best_stamp[u] == stamp and best[u] <= k2:
                continue
            best_stamp[u] = stamp
            best[u] = k2
            if size == heap.shape[0]:
                grown = np.zeros((2 * size, 4), dtype=np.int64)
                grown[:size] = heap
                heap = grown
            heap[size, 0] = k2
            heap[size, 1] = -t1
            heap[size, 2] = u
            heap[size, 3] = v
            k = size
            size += 1
            while k > 0:  # sift up
                up = (k - 1) // 2
                if _less(heap, k, up):
                    _swap_rows(heap, k, up)
                    k = up
                else:
                    break
    return 0, heap


@njit(cache=True)
def _run(order, indptr, indices, starts, goals, dists, rows, margin, count, head, link, after,
         end_head, end_link, end_last, paths, lengths, best, best_stamp, parent, closed_stamp,
         heap, state, n, horizon):
    out = np.empty(horizon, dtype=np.int64)
    for i in order:
        length = lengths[i]
        if length > 0:
            old = paths[i]
            _remove(count, head, link, end_head, end_link, n, horizon, i, old, length)
            cost = _path_cost(count, head, link, after, end_head, end_link, end_last, n,
                              horizon, old, length)
            state[0] -= cost
            if cost == 0:  # no collision: nothing to gain; put it back
                _add(count, head, link, after, end_head, end_link, end_last, n, horizon, i,
                     old, length)
                continue
        state[1] += 1
        new_len, heap = _search(indptr, indices, count, head, link, after, end_head, end_link,
                                end_last, n, starts[i], goals[i], dists[rows[i]], margin,
                                best, best_stamp, parent, closed_stamp, heap, state[1], out)
        if new_len > 0:
            paths[i, :new_len] = out[:new_len]
            lengths[i] = new_len
        if lengths[i] > 0:
            state[0] += _path_cost(count, head, link, after, end_head, end_link, end_last, n,
                                   horizon, paths[i], lengths[i])
            _add(count, head, link, after, end_head, end_link, end_last, n, horizon, i,
                 paths[i], lengths[i])
    return heap


def run_agents(table: NbTable, order: np.ndarray, indptr: np.ndarray, indices: np.ndarray,
               starts: np.ndarray, goals: np.ndarray, dists: np.ndarray, rows: np.ndarray,
               margin: int) -> None:
    """Plan the agents of ``order`` one after the other as a round of
    :func:`~.scatter.guide_paths` does (remove, keep if collision-free, search, add):
    ``dists[rows[i]]`` is agent i's distance table; ``table.state[0]`` the collisions."""
    t = table
    t.heap = _run(order, indptr, indices, starts, goals, dists, rows, margin, t.count, t.head,
                  t.link, t.after, t.end_head, t.end_link, t.end_last, t.paths, t.lengths,
                  t.best, t.best_stamp, t.parent, t.closed_stamp, t.heap, t.state, t.n,
                  t.horizon)


@njit(cache=True)
def _goal_bfs(valid, enter, rows, cols, goals, out):
    """Breadth-first search from each goal over the 4-neighbour grid: a cell is reached
    from a reached 4-neighbour when it is ``valid`` (expandable); a goal that is not
    ``enter``-able is reached from nowhere (``out`` holds UNREACHABLE there)."""
    queue = np.empty(rows * cols, dtype=np.int64)
    for j in range(goals.shape[0]):
        d = out[j]
        g = goals[j]
        if not enter[g]:
            continue
        d[g] = 0
        head = 0
        tail = 1
        queue[0] = g
        while head < tail:
            v = queue[head]
            head += 1
            r = v // cols
            c = v - r * cols
            nd = d[v] + 1
            for k in range(4):
                if k == 0:
                    if c + 1 >= cols:
                        continue
                    u = v + 1
                elif k == 1:
                    if c == 0:
                        continue
                    u = v - 1
                elif k == 2:
                    if r + 1 >= rows:
                        continue
                    u = v + cols
                else:
                    if r == 0:
                        continue
                    u = v - cols
                if valid[u] and d[u] == UNREACHABLE:
                    d[u] = nd
                    queue[tail] = u
                    tail += 1


def goal_bfs(valid: np.ndarray, enter: np.ndarray, rows: int, cols: int,
             goals: Sequence[int]) -> np.ndarray:
    """``(len(goals), rows * cols)`` int32 tables of moves to each goal, the same as
    :func:`.oneshot._grid_bfs` (a plain grid: the moves are from each expandable cell,
    ``valid``, to each 4-neighbour that is enterable)."""
    out = np.full((len(goals), rows * cols), UNREACHABLE, dtype=np.int32)
    _goal_bfs(np.ascontiguousarray(valid, dtype=np.bool_).ravel(),
              np.ascontiguousarray(enter, dtype=np.bool_).ravel(), rows, cols,
              np.asarray(goals, dtype=np.int64), out)
    return out


def compiled_ready(also: Sequence = ()) -> bool:
    """Whether numba's on-disk cache holds machine code of this module's kernels and of the
    compiled functions ``also`` (:func:`.lacam.lacam_kernels`: this module sits below
    :mod:`.lacam_numba` and does not import it), so that using them costs a load, not a
    compile (20-30 s of CPU on the 2-core box). Reads numba's cache index (not a public
    API: where it cannot be read, assumed ready)."""
    try:
        return all(bool(f._cache._cache_file._load_index())
                   for f in (_run, _goal_bfs, *also))
    except Exception:  # pragma: no cover - another numba's cache internals  # noqa: BLE001
        return True
