"""Distance tables to goal cells, shared by every robot and every timestep of a lifelong run.

A lifelong run asks for a new table whenever a robot's errand changes: on a Robot Runners
map of 70,000 cells with thousands of robots that is tens of tables per timestep and
thousands at the start. :class:`DistStore` keeps one table per goal cell, whoever asked for
it first, in a least recently used cache bounded in bytes (``budget_mb``); a table evicted
while a robot still holds it is found again (a weak reference) instead of being recomputed.

With ``reserve`` (the compiled lifelong step, :mod:`.pibt_compiled`, passes its robot count) every table is a row of one 2-D
array, :attr:`DistStore.slab`, so compiled code reads any robot's table by a row number; a
row is reused once nobody holds its table.

Tables are compact numpy arrays: ``uint16`` when every free cell reaches every other and
no distance reaches 65,535 (then obstacle cells, which no robot ever looks up, hold 65,535),
else ``int32`` with :data:`~warerover_phys.planning.graph.UNREACHABLE` where the goal cannot
be reached, as :meth:`MotionGraph.dist_to` gives. Either way every free cell holds the same
move count as :meth:`MotionGraph.dist_to`, so plans do not change.

They are filled by a breadth-first search compiled with numba
(:func:`~warerover_phys.planning.pibt.kernels.bfs_fill`: 1.3 ms CPU a table on the fulfill map
below, against 2.8 ms for the scipy route, at load 8 on 2 cores; 2026-11-26), else by scipy's compiled breadth-first search cut into levels (as
:func:`~warerover_phys.planning.graph.bfs_depths`) over the enterable cells only, the
compiled search called directly: on the 140 x 500 ``lorr2026_warehouse_fulfill`` map 3.0 ms
per search and its levels plus 0.6 ms to fill the table, at load average 6-9 on 2 cores (the
compiled search 0.9 ms of it, against 1.7 ms through ``breadth_first_order``), against
22 ms for ``bfs_depths`` over all 70,000 cells at a like load (unloaded, load 1: ``bfs_depths`` 5.2 ms, a numpy frontier search over a
neighbour array 16 ms, scipy's unweighted ``shortest_path`` 5.8 ms). A lazy search that
stops where the robots' cells are reached was not built: scipy's search cannot stop early,
and a numpy one that can is 16 ms for a whole table, so it would have to stop within the
first fifth of the map to pay.

>>> import numpy as np
>>> from warerover_phys.planning.oneshot.core import grid_graph
>>> store = DistStore(grid_graph(np.zeros((1, 4), dtype=bool)), budget_mb=1)
>>> store.get(3).tolist(), store.get(3).dtype.name, store.counters()["hits"]
([3, 2, 1, 0], 'uint16', 1)
"""

from __future__ import annotations

import time
import weakref
from collections import OrderedDict
from typing import Any

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order

from .graph import UNREACHABLE, MotionGraph

try:  # scipy's compiled search itself (private: used only if it answers as expected)
    from scipy.sparse.csgraph._traversal import _breadth_first_directed as _direct_bfs
except ImportError:  # pragma: no cover - another scipy
    _direct_bfs = None

__all__ = ["DistStore", "DEFAULT_BUDGET_MB"]


DEFAULT_BUDGET_MB = 1024.0
"""Bytes the cached tables may hold, in MiB: 7,600 ``uint16`` tables of a 70,000-cell map."""
_U16_FAR = np.iinfo(np.uint16).max


class DistStore:
    """Distance tables (moves from every cell to a goal cell), LRU-cached under a budget.

    ``graph``: the 1x1 motion graph (its ``neighbors`` lists); ``budget_mb``: MiB the cached
    tables may hold (tables robots still hold live on beyond it until they let go).
    """

    def __init__(self, graph: MotionGraph, budget_mb: float = DEFAULT_BUDGET_MB,
                 reserve: int | None = None, *, dtype: type | None = None,
                 share: DistStore | None = None, stores: int = 1) -> None:
        """``dtype``: the tables' dtype (default: :meth:`_choose_dtype`). ``share``: keep the
        tables in the slab of that store (its dtype, its rows: robots on two graphs, loaded
        and not, read one slab); the first store of such a pair reserves rows for
        ``stores`` caches."""
        if not budget_mb > 0:
            raise ValueError(f"budget_mb: expected a positive number, got {budget_mb!r}")
        n = graph.num_nodes
        self.num_nodes = n
        self._enterable = np.asarray(graph.enterable, dtype=bool).ravel()
        # The search runs over the enterable cells only (their own numbering: 38,643 of the
        # 70,000 cells of the fulfill map), 2x faster than over every cell.
        self._free = np.flatnonzero(self._enterable)
        m = len(self._free)
        self._cid = np.full(n, -1, dtype=np.int64)
        self._cid[self._free] = np.arange(m)
        counts = np.fromiter((len(ns) for ns in graph.neighbors), dtype=np.int64, count=n)
        dst = np.fromiter((v for ns in graph.neighbors for v in ns), dtype=np.int64,
                          count=int(counts.sum()))
        src = np.repeat(np.arange(n), counts)
        valid = np.asarray(graph.expandable_flat, dtype=bool)
        keep = valid[src] & self._enterable[src] & self._enterable[dst]
        # Tables give moves *to* the goal: search the reversed edges from it.
        self._rev = csr_matrix((np.ones(int(keep.sum()), dtype=np.int8),
                                (self._cid[dst[keep]], self._cid[src[keep]])), shape=(m, m))
        self._rev.sum_duplicates()
        self._rev.sort_indices()
        self._arange = np.arange(m, dtype=np.int32)
        self._indices = self._rev.indices.astype(np.int32)
        self._indptr = self._rev.indptr.astype(np.int32)
        self._direct = _direct_bfs is not None
        if self._direct and m:  # trust the private call only if it agrees with the public one
            want = breadth_first_order(self._rev, 0, directed=True, return_predecessors=True)
            got = self._search(0)
            self._direct = all(np.array_equal(a, b) for a, b in zip(want, got, strict=True))
        # numba's breadth-first search, imported here (not at module import: numba takes a
        # second or more to import): 1.3 ms a table on the fulfill map against 2.8 ms
        # through scipy (CPU, load 8 on 2 cores); the same depths
        from .pibt.kernels import AVAILABLE, bfs_fill
        self._bfs_fill = bfs_fill if AVAILABLE else None
        self.dtype = share.dtype if share is not None else (
            dtype if dtype is not None else self._choose_dtype())
        self.table_bytes = n * np.dtype(self.dtype).itemsize
        self.budget_bytes = int(budget_mb * 2**20)
        self.capacity = max(1, self.budget_bytes // self.table_bytes)
        """Tables the cache holds at most."""
        self.slab: np.ndarray | None = None
        """With ``reserve``: every table is a row of this one 2-D array (``slot``), so a
        compiled step reads any robot's table by its row number (:mod:`.pibt_numba`)."""
        self._rows: _Rows | None = None
        if share is not None:
            if share.slab is None or share.num_nodes != n:
                raise ValueError("share: a store with a slab over the same cells")
            self.slab, self._rows = share.slab, share._rows
        elif reserve is not None:
            # Rows for the cached tables and for one more table per robot (evicted but
            # still held): a robot holds one table, so the rows never run out (nor can
            # there be more tables than goal cells). np.empty only reserves the address
            # space; a row takes memory once a table is written into it.
            rows = min(stores * self.capacity + max(0, int(reserve)),
                       stores * max(1, len(self._free))) + 1
            self.slab = np.empty((rows, n), dtype=self.dtype)
            self._rows = _Rows()
        self._cache: OrderedDict[int, np.ndarray] = OrderedDict()
        self._live: weakref.WeakValueDictionary[int, np.ndarray] = weakref.WeakValueDictionary()
        self.hits = 0
        self.misses = 0
        self.revived = 0
        """Requests answered by a table evicted from the cache that a robot still held."""
        self.evictions = 0
        self.bfs_s = 0.0
        self.prefetched = 0
        self.prefetch_s = 0.0

    def _choose_dtype(self) -> type:
        """``uint16`` if the enterable cells form one strongly connected component whose
        distances all fit below 65,535, else ``int32``."""
        if len(self._free) == 0 or (self._rev != self._rev.T).nnz:
            return np.int32
        order, depth = self._bfs(0)
        # 2x the eccentricity of one cell bounds every distance in a symmetric graph.
        if len(order) == len(self._free) and 2 * (len(depth) and int(depth[-1])) < _U16_FAR:
            return np.uint16
        return np.int32

    def _search(self, source: int) -> tuple[np.ndarray, np.ndarray]:
        """scipy's breadth-first order and predecessors from ``source``: its compiled
        search called directly (skipping the checks and copies of the graph that
        ``breadth_first_order`` makes on every call: 1.1 against 1.9 ms on the fulfill
        map), else through ``breadth_first_order``."""
        if self._direct:
            m = len(self._free)
            order = np.empty(m, dtype=np.int32)
            pred = np.full(m, -9999, dtype=np.int32)
            order[0] = source
            try:
                k = _direct_bfs(source, self._indices, self._indptr, order, pred)
                return order[:k], pred
            except (TypeError, ValueError):  # pragma: no cover - another scipy
                self._direct = False
        return breadth_first_order(self._rev, source, directed=True, return_predecessors=True)

    def _bfs(self, source: int) -> tuple[np.ndarray, np.ndarray]:
        """(cells reached, in order, and their depths) of a search from compact cell
        ``source`` over the reversed edges. scipy's breadth-first search lists the reached
        cells level by level, each cell's parent earlier in the list than any later cell's
        parent; so the levels are cut where the parents' positions pass the previous
        level's end (as :func:`~warerover_phys.planning.graph.bfs_depths`)."""
        order, pred = self._search(source)
        k = len(order)
        pos = np.empty(len(self._free), dtype=np.int32)
        pos[order] = self._arange[:k]
        below = np.bincount(pos[pred[order[1:]]], minlength=k).cumsum()
        bounds = [0, 1]
        b = 1
        while b < k:
            b = 1 + int(below[b - 1])
            bounds.append(b)
        depth = np.repeat(np.arange(len(bounds) - 1, dtype=np.int32), np.diff(bounds))
        return order, depth

    def get(self, goal: int) -> np.ndarray:
        """The read-only table of moves to cell ``goal`` (linear index)."""
        table = self._cache.get(goal)
        if table is not None:
            self._cache.move_to_end(goal)
            self.hits += 1
            return table
        table = self._live.get(goal)
        if table is not None:
            self.revived += 1
        else:
            self.misses += 1
            t0 = time.perf_counter()
            table = self._compute(goal)
            self.bfs_s += time.perf_counter() - t0
            self._live[goal] = table
        self._cache[goal] = table
        while len(self._cache) > self.capacity:
            self._cache.popitem(last=False)
            self.evictions += 1
        return table

    def prefetch(self, goals) -> int:
        """Compute the tables of ``goals`` (cells, in the order given, repeats skipped) ahead
        of need, while the cache has room; returns how many it holds then. Counted as
        ``prefetched``, not as misses."""
        misses, bfs = self.misses, self.bfs_s
        for g in dict.fromkeys(int(x) for x in goals):
            if len(self._cache) >= self.capacity:
                break
            self.get(g)
        self.prefetched += self.misses - misses
        self.prefetch_s += self.bfs_s - bfs
        self.misses, self.bfs_s = misses, bfs
        return len(self._cache)

    def slot(self, table: np.ndarray) -> int:
        """The row of :attr:`slab` that holds ``table`` (a table this store gave)."""
        assert self.slab is not None, "slot: the store was made without reserve"
        return (table.ctypes.data - self.slab.ctypes.data) // self.slab.strides[0]

    def _compute(self, goal: int) -> np.ndarray:
        far = _U16_FAR if self.dtype is np.uint16 else UNREACHABLE
        if self.slab is not None:
            rows = self._rows
            if rows.slots:
                row = rows.slots.pop()
            elif rows.next_row < len(self.slab):
                row = rows.next_row
                rows.next_row += 1
            else:  # pragma: no cover - more tables held than robots reserved
                raise RuntimeError("DistStore: every slab row is held (reserve too small)")
            table = self.slab[row]
            table.fill(far)
            # the row is free again once nobody (cache, robot) holds the table
            weakref.finalize(table, rows.slots.append, row)
        else:
            table = np.full(self.num_nodes, far, dtype=self.dtype)
        if self._enterable[goal]:
            if self._bfs_fill is not None:
                self._bfs_fill(self._indptr, self._indices, self._free, int(self._cid[goal]), table)
            else:  # pragma: no cover - numba missing
                order, depth = self._bfs(int(self._cid[goal]))
                table[self._free[order]] = depth
        table.setflags(write=False)
        return table

    @property
    def slab_rows_in_use(self) -> int:
        """Rows of :attr:`slab` holding a table (0 without a slab)."""
        return 0 if self._rows is None else self._rows.next_row - len(self._rows.slots)

    def counters(self) -> dict[str, Any]:
        """Hits, misses (tables computed), revived, evictions, seconds of BFS, tables cached
        and their MiB, the dtype and the budget."""
        return {"hits": self.hits, "misses": self.misses, "revived": self.revived,
                "evictions": self.evictions, "bfs_s": self.bfs_s,
                "prefetched": self.prefetched, "prefetch_s": self.prefetch_s,
                "cached_tables": len(self._cache),
                "cached_mb": len(self._cache) * self.table_bytes / 2**20,
                "capacity_tables": self.capacity, "budget_mb": self.budget_bytes / 2**20,
                "dtype": np.dtype(self.dtype).name}


class _Rows:
    """The rows of a slab: those given back and where never-used ones start (shared by
    the stores that share the slab)."""

    __slots__ = ("slots", "next_row")

    def __init__(self) -> None:
        self.slots: list[int] = []
        self.next_row = 0
