"""The LNS's single-agent search compiled with numba, over a dense space-time occupancy table.

:mod:`~warerover_phys.planning.refine.lns` re-plans a few agents at a time against everybody
else's paths. In Python that search (:func:`~.refine._sipp`) took ~95% of the LNS's CPU at
700 agents on warehouse-10-20-10-2-1 (tens of milliseconds a search). Here the same search
runs compiled:

- :class:`DensePlan` keeps the kept paths as one flat ``int32`` array ``occ[t * n + v]``
  (the agent at node v at tick t, -1 if none; ticks below a horizon ``H``, 1.5x the
  longest path + 32, grown when a longer path comes in; a search's cost bound is capped
  below ``H``) and ``parked[v]`` (the tick from which an agent stands on its goal v
  for good). Adding or taking out a path is two numpy assignments, nothing is rebuilt.
- :func:`st_astar` is space-time A* over (node, tick) states, the search of
  :func:`~.refine._astar` (the reference): vertex and swap conflicts with every kept path,
  no cell on which an agent is parked, the goal reached at a tick from which it stays free
  for good; ``f = max(t + h, earliest)``, ties broken towards the goal, then later ticks;
  cost at most ``ub``. Every state of a search has ``g = t``, so a state is pushed once
  (a stamp array, no closed set to clear) and its first parent is kept. It finds the same
  costs as ``_astar`` and ``_sipp`` (the tests compare them on random floors); the paths
  may differ among equals.

Compiled with ``numba.njit(cache=True)``: the first process without numba's cache compiles
it (about a second, see :func:`warm_up`), later ones load it from ``__pycache__``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

try:
    from numba import njit
    AVAILABLE = True
except ImportError:  # pragma: no cover - numba is a dependency; refine falls back to _sipp
    AVAILABLE = False

    def njit(*args, **kwargs):  # type: ignore[no-redef]
        if args and callable(args[0]):
            return args[0]
        return lambda f: f

__all__ = ["AVAILABLE", "DensePlan", "st_astar", "csr", "warm_up"]

NONE = np.int32(-1)
NEVER = np.int32(2**31 - 1)
"""``parked[v]`` when nobody parks on v."""


def csr(neighbors: Sequence[Sequence[int]]) -> tuple[np.ndarray, np.ndarray]:
    """The neighbour lists as ``(ptr, idx)``: node v's neighbours are ``idx[ptr[v]:ptr[v+1]]``."""
    ptr = np.zeros(len(neighbors) + 1, dtype=np.int64)
    ptr[1:] = np.cumsum([len(nb) for nb in neighbors])
    idx = np.fromiter((u for nb in neighbors for u in nb), dtype=np.int32, count=int(ptr[-1]))
    return ptr, idx


class DensePlan:
    """Space-time occupancy of all kept paths as flat arrays (see the module docstring).

    ``paths[i]`` is agent i's node list up to its cost tick (it stays on its goal after)."""

    def __init__(self, num_nodes: int, paths: list[list[int]]) -> None:
        self.n = num_nodes
        self.horizon = 0
        self.occ = np.zeros(0, dtype=np.int32)
        self._grow(_room(max((len(p) for p in paths), default=1)))
        self.parked = np.full(num_nodes, NEVER, dtype=np.int32)
        self.paths: list[list[int]] = [[] for _ in paths]
        self.heap_pri = np.zeros(1 << 12, dtype=np.int64)
        self.heap_key = np.zeros(1 << 12, dtype=np.int64)
        for i, p in enumerate(paths):
            self.add(i, p)

    def _grow(self, horizon: int) -> None:
        n = self.n
        if horizon * n >= 2**31:
            raise ValueError(f"space-time table too large: {horizon} ticks x {n} nodes")
        occ = np.full(horizon * n, NONE, dtype=np.int32)
        occ[:self.occ.size] = self.occ
        self.occ = occ
        self.horizon = horizon
        self.seen = np.zeros(horizon * n, dtype=np.int32)
        self.parent = np.zeros(horizon * n, dtype=np.int32)
        self.gen = 0

    def _keys(self, path: list[int]) -> np.ndarray:
        return np.arange(len(path), dtype=np.int64) * self.n + np.asarray(path, dtype=np.int64)

    def add(self, i: int, path: list[int]) -> None:
        if len(path) + 16 > self.horizon:
            self._grow(_room(len(path)))
        self.occ[self._keys(path)] = i
        self.parked[path[-1]] = len(path) - 1
        self.paths[i] = path

    def remove(self, i: int) -> list[int]:
        path = self.paths[i]
        self.occ[self._keys(path)] = NONE
        self.parked[path[-1]] = NEVER
        return path

    def who(self, t: int, v: int) -> int | None:
        """The agent at node v at tick t (None if nobody's path is there then)."""
        if t >= self.horizon:
            return None
        j = int(self.occ[t * self.n + v])
        return None if j < 0 else j

    def ticks_at(self, v: int) -> np.ndarray:
        """The ticks at which some kept path is at v (before parking), ascending."""
        return np.flatnonzero(self.occ[v::self.n] >= 0)

    def search(self, ptr: np.ndarray, idx: np.ndarray, start: int, goal: int,
               dist: np.ndarray, ub: int, max_expansions: int,
               work: list[int] | None = None) -> list[int] | None:
        """:func:`st_astar` from ``start`` (tick 0) to ``goal`` against the kept paths."""
        ub = min(ub, self.horizon - 1)
        if ub < 0:
            return None
        need = 5 * max_expansions + 8
        if self.heap_pri.size < need:  # at most 5 pushes per expansion: never full
            self.heap_pri = np.zeros(need, dtype=np.int64)
            self.heap_key = np.zeros(need, dtype=np.int64)
        self.gen += 1
        if self.gen >= 2**31 - 2:
            self.seen[:] = 0
            self.gen = 1
        path, expanded = st_astar(ptr, idx, self.occ, self.parked, self.n, self.horizon,
                                  start, goal, dist, ub, max_expansions, self.seen,
                                  self.parent, self.gen, self.heap_pri, self.heap_key)
        if work is not None:
            work[0] += int(expanded)
        return None if path.size == 0 else path.tolist()


def _room(longest: int) -> int:
    """The horizon given to paths of up to ``longest`` nodes: searches may find paths up to
    it (their bound is capped there); a longer path put in grows the table."""
    return longest + longest // 2 + 32


_TBITS = 21
_HBITS = 21
_TMASK = (1 << _TBITS) - 1


@njit(cache=True, inline="always")
def _push(pri, key, size, p, k):
    i = size
    while i > 0:
        up = (i - 1) >> 1
        if pri[up] <= p:
            break
        pri[i] = pri[up]
        key[i] = key[up]
        i = up
    pri[i] = p
    key[i] = k


@njit(cache=True, inline="always")
def _pop(pri, key, size):
    """Remove the root of a heap of ``size`` entries (the caller reads it first)."""
    last = size - 1
    p = pri[last]
    k = key[last]
    i = 0
    while True:
        c = 2 * i + 1
        if c >= last:
            break
        if c + 1 < last and pri[c + 1] < pri[c]:
            c += 1
        if pri[c] >= p:
            break
        pri[i] = pri[c]
        key[i] = key[c]
        i = c
    if last > 0:
        pri[i] = p
        key[i] = k


@njit(cache=True)
def st_astar(ptr, idx, occ, parked, n, horizon, start, goal, dist, ub, max_expansions,
             seen, parent, gen, heap_pri, heap_key):
    """Shortest space-time path (node array) from ``start`` at tick 0 to ``goal`` (staying
    there for good) of cost at most ``ub`` (< ``horizon``) avoiding every path in ``occ``;
    an empty array if none is found within ``max_expansions`` expansions. Returns
    ``(path, states expanded)``."""
    empty = np.zeros(0, dtype=np.int64)
    if parked[goal] != 2**31 - 1:
        return empty, 0
    earliest = 0
    for t in range(horizon - 1, -1, -1):
        if occ[t * n + goal] >= 0:
            earliest = t + 1
            break
    h0 = dist[start]
    f0 = h0 if h0 > earliest else earliest
    if f0 > ub:
        return empty, 0
    size = 0
    seen[start] = gen
    parent[start] = -1
    _push(heap_pri, heap_key, size, (f0 << (_TBITS + _HBITS)) | (h0 << _TBITS) | _TMASK,
          start)
    size += 1
    expanded = 0
    cap = heap_pri.size
    while size > 0:
        key = heap_key[0]
        _pop(heap_pri, heap_key, size)
        size -= 1
        t = key // n
        v = key - t * n
        if v == goal and t >= earliest:
            path = np.empty(t + 1, dtype=np.int64)
            k = key
            for s in range(t, -1, -1):
                path[s] = k % n
                k = parent[k]
            return path, expanded
        expanded += 1
        if expanded > max_expansions:
            return empty, expanded
        t1 = t + 1
        base = t1 * n
        for m in range(ptr[v], ptr[v + 1] + 1):
            u = idx[m] if m < ptr[v + 1] else v
            k1 = base + u
            if seen[k1] == gen or occ[k1] >= 0 or parked[u] <= t1:
                continue
            if u != v:
                j = occ[t * n + u]
                if j >= 0 and occ[base + v] == j:
                    continue  # swap with agent j
            h = dist[u]
            f = t1 + h
            if f < earliest:
                f = earliest
            if f > ub:
                continue
            if size >= cap:
                return empty, expanded
            seen[k1] = gen
            parent[k1] = key
            _push(heap_pri, heap_key, size,
                  (f << (_TBITS + _HBITS)) | (h << _TBITS) | (_TMASK - t1), k1)
            size += 1
    return empty, expanded


def warm_up() -> None:
    """Compile (or load from numba's cache) :func:`st_astar` on a 2-node instance."""
    plan = DensePlan(2, [[0]])
    ptr, idx = csr([(1,), (0,)])
    plan.search(ptr, idx, 1, 1, np.zeros(2, dtype=np.int32), 4, 10)
