"""Distance tables to goal cells, shared by every robot and every timestep of a lifelong run.

A lifelong run asks for a new table whenever a robot's errand changes: on a Robot Runners
map of 70,000 cells with thousands of robots that is tens of tables per timestep and
thousands at the start. :class:`DistStore` keeps one table per goal cell, whoever asked for
it first, in a least recently used cache bounded in bytes (``budget_mb``); a table evicted
while a robot still holds it is found again (a weak reference) instead of being recomputed.

Tables are compact numpy arrays: ``uint16`` when every free cell reaches every other and
no distance reaches 65,535 (then obstacle cells, which no robot ever looks up, hold 65,535),
else ``int32`` with :data:`~warerover_phys.planning.graph.UNREACHABLE` where the goal cannot
be reached, as :meth:`MotionGraph.dist_to` gives. Either way every free cell holds the same
move count as :meth:`MotionGraph.dist_to`, so plans do not change.

They are filled by :func:`~warerover_phys.planning.graph.bfs_depths` (scipy's compiled
breadth-first search cut into levels): 5.2 ms per table on the 140 x 500
``lorr2026_warehouse_fulfill`` map, against 16 ms for a numpy frontier search over a
neighbour array and 5.8 ms for scipy's unweighted ``shortest_path`` (2 shared cores).

>>> import numpy as np
>>> from warerover_phys.planning.oneshot import grid_graph
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

from .graph import UNREACHABLE, MotionGraph, bfs_depths

__all__ = ["DistStore", "DEFAULT_BUDGET_MB"]

DEFAULT_BUDGET_MB = 1024.0
"""Bytes the cached tables may hold, in MiB: 7,600 ``uint16`` tables of a 70,000-cell map."""
_U16_FAR = np.iinfo(np.uint16).max


class DistStore:
    """Distance tables (moves from every cell to a goal cell), LRU-cached under a budget.

    ``graph``: the 1x1 motion graph (its ``neighbors`` lists); ``budget_mb``: MiB the cached
    tables may hold (tables robots still hold live on beyond it until they let go).
    """

    def __init__(self, graph: MotionGraph, budget_mb: float = DEFAULT_BUDGET_MB) -> None:
        if not budget_mb > 0:
            raise ValueError(f"budget_mb: expected a positive number, got {budget_mb!r}")
        n = graph.num_nodes
        self.num_nodes = n
        counts = np.fromiter((len(ns) for ns in graph.neighbors), dtype=np.int64, count=n)
        dst = np.fromiter((v for ns in graph.neighbors for v in ns), dtype=np.int64,
                          count=int(counts.sum()))
        src = np.repeat(np.arange(n), counts)
        valid = np.asarray(graph.expandable_flat, dtype=bool)
        keep = valid[src]
        # Tables give moves *to* the goal: search the reversed edges from it.
        self._rev = csr_matrix((np.ones(int(keep.sum()), dtype=np.int8),
                                (dst[keep], src[keep])), shape=(n, n))
        self._enterable = np.asarray(graph.enterable, dtype=bool).ravel()
        self.dtype = self._choose_dtype(graph)
        self.table_bytes = n * np.dtype(self.dtype).itemsize
        self.budget_bytes = int(budget_mb * 2**20)
        self.capacity = max(1, self.budget_bytes // self.table_bytes)
        """Tables the cache holds at most."""
        self._cache: OrderedDict[int, np.ndarray] = OrderedDict()
        self._live: weakref.WeakValueDictionary[int, np.ndarray] = weakref.WeakValueDictionary()
        self.hits = 0
        self.misses = 0
        self.revived = 0
        """Requests answered by a table evicted from the cache that a robot still held."""
        self.evictions = 0
        self.bfs_s = 0.0

    def _choose_dtype(self, graph: MotionGraph) -> type:
        """``uint16`` if the free cells form one strongly connected component whose
        distances all fit below 65,535, else ``int32``."""
        free = np.flatnonzero(self._enterable)
        if len(free) == 0 or (self._rev != self._rev.T).nnz:
            return np.int32
        d = bfs_depths(self._rev, int(free[0]))
        reached = d[free] < UNREACHABLE
        # 2x the eccentricity of one cell bounds every distance in a symmetric graph.
        if reached.all() and 2 * int(d[free].max()) < _U16_FAR:
            return np.uint16
        return np.int32

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

    def _compute(self, goal: int) -> np.ndarray:
        depth = bfs_depths(self._rev, goal)
        if not self._enterable[goal]:
            depth[:] = UNREACHABLE
        if self.dtype is np.uint16:
            table = np.minimum(depth, _U16_FAR).astype(np.uint16)
        else:
            table = depth
        table.setflags(write=False)
        return table

    def counters(self) -> dict[str, Any]:
        """Hits, misses (tables computed), revived, evictions, seconds of BFS, tables cached
        and their MiB, the dtype and the budget."""
        return {"hits": self.hits, "misses": self.misses, "revived": self.revived,
                "evictions": self.evictions, "bfs_s": self.bfs_s,
                "cached_tables": len(self._cache),
                "cached_mb": len(self._cache) * self.table_bytes / 2**20,
                "capacity_tables": self.capacity, "budget_mb": self.budget_bytes / 2**20,
                "dtype": np.dtype(self.dtype).name}
