"""Trip lengths for schedulers as arrays: every idle AGV x candidate shelf in one compiled pass.

A trip is the drive to the shelf unloaded, then loaded from the shelf to each station in
turn (:meth:`World.trip_distance <warerover_phys.world.World.trip_distance>`). The two parts
are kept apart:

- *to the shelf*: per footprint ``k`` one table ``(cells, shelves)``, column ``s`` the moves
  from every cell to shelf ``s``'s anchor on the unloaded graph (the breadth-first search
  :meth:`~warerover_phys.planning.graph.MotionGraph.dist_to` runs, compiled; filled the
  first time a scheduler looks at the shelf). Rows by cell, so the lengths from one AGV to
  many shelves are read from one row. ``uint16`` below 65,535 cells: 25 MB on the
  1,680-shelf industrial floor (cells x shelves x 2 bytes; int32 above, twice that);
- *with the shelf*: the loaded legs shelf -> stations, which do not depend on the AGV: for
  1x1 AGVs (one loaded graph) a shelves x stations table plus station -> station lengths,
  for bigger ones (a loaded graph per shelf carried) per ``(k, shelf, stations)``.

A :class:`TripCosts` belongs to one set of motion graphs: when corridors open or close the
world's graphs are replaced and :meth:`World.trip_costs <warerover_phys.world.World.trip_costs>`
starts a new one, as :meth:`World.trip_distance <warerover_phys.world.World.trip_distance>`
starts a new cache. Every length equals ``World.trip_distance``'s, move for move.

:meth:`TripCosts.options` is what TA ranks: per idle AGV and SKU, the nearest
``candidate_shelves`` usable shelves by Manhattan distance (ties by shelf id) and the
shortest of their trips (:mod:`.costs_nb`); the ranked shelves of the pairs it picks.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..planning.graph import UNREACHABLE
from ..planning.pibt.kernels import AVAILABLE as BFS_AVAILABLE
from ..planning.pibt.kernels import bfs_fill
from .costs_nb import best_trips, ranked_options

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    from ..config import AgvTypeSpec
    from ..fleet import Agv
    from ..layout import Layout
    from ..planning.graph import GraphSet, MotionGraph

__all__ = ["TripCosts", "OptionTable", "ranges"]

_FAR16 = np.iinfo(np.uint16).max
LEG_CACHE = 200_000
"""Loaded-leg lengths of AGVs bigger than 1x1 kept before the cache starts over (as the
world's trip cache)."""


def ranges(starts: np.ndarray, lens: np.ndarray) -> np.ndarray:
    """The concatenated index ranges ``starts[i] .. starts[i] + lens[i] - 1``.

    >>> ranges(np.array([5, 0, 9]), np.array([2, 0, 3])).tolist()
    [5, 6, 9, 10, 11]
    """
    total = int(lens.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    ends = np.cumsum(lens)
    offsets = np.repeat(starts - (ends - lens), lens)
    return np.arange(total, dtype=np.int64) + offsets


class TripCosts:
    """Trip lengths on one :class:`~warerover_phys.planning.graph.GraphSet`.

    ``station_anchor(station, k)`` is the world's (anchors do not depend on closed cells).
    """

    def __init__(self, layout: Layout, graphs: GraphSet,
                 station_anchor: Callable[[int, int], int]) -> None:
        self.layout, self.graphs = layout, graphs
        self._station_anchor = station_anchor
        cols = layout.cols
        self.num_nodes = layout.rows * cols
        shelves = layout.shelves
        self.num_shelves = len(shelves)
        self.anchor_rc = np.array([s.anchor for s in shelves], dtype=np.int64).reshape(-1, 2)
        self.anchor_node = self.anchor_rc[:, 0] * cols + self.anchor_rc[:, 1]
        self.size = np.array([s.size for s in shelves], dtype=np.int64)
        # SKU -> shelves (layout.sku_shelves order) as one flat array with offsets.
        sku_shelves = layout.sku_shelves
        top = max([layout.num_skus - 1, *sku_shelves]) + 1
        lens = np.zeros(top, dtype=np.int64)
        for sku, ids in sku_shelves.items():
            lens[sku] = len(ids)
        self._sku_ptr = np.concatenate(([0], np.cumsum(lens)))
        self._sku_shelf = np.array([s for sku in range(top) for s in sku_shelves.get(sku, ())],
                                   dtype=np.int64)
        self._to_shelf: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._legs: dict[tuple[int, int, tuple[int, ...]], int] = {}
        self._first: np.ndarray | None = None
        self._anchor_nbrs: np.ndarray | None = None
        self._stations: dict[tuple[int, int], int] = {}
        self._carry: dict[str, np.ndarray] = {}

    # ----------------------------------------------------------------------- lookups

    def carry_mask(self, type_name: str, spec: AgvTypeSpec) -> np.ndarray:
        """Bool per shelf: an AGV of this type can lift it."""
        mask = self._carry.get(type_name)
        if mask is None:
            sizes = {int(z): spec.can_carry(int(z)) for z in np.unique(self.size)}
            mask = self._carry[type_name] = np.array([sizes[int(z)] for z in self.size],
                                                     dtype=bool)
        return mask

    def sku_pairs(self, skus: np.ndarray, usable: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(j, shelf)`` for every usable shelf holding ``skus[j]``, by ``j`` then in
        ``layout.sku_shelves`` order."""
        top = len(self._sku_ptr) - 1
        inside = (skus >= 0) & (skus < top)
        safe = np.where(inside, skus, 0)
        starts = self._sku_ptr[safe]
        lens = np.where(inside, self._sku_ptr[safe + 1] - starts, 0)
        shelf = self._sku_shelf[ranges(starts, lens)]
        j = np.repeat(np.arange(len(skus), dtype=np.int64), lens)
        keep = usable[shelf]
        return j[keep], shelf[keep]

    def to_shelves(self, k: int, nodes: np.ndarray, shelves: np.ndarray) -> np.ndarray:
        """Unloaded moves from each of ``nodes`` to each of ``shelves``' anchors
        (``(len(nodes), len(shelves))`` int64, :data:`UNREACHABLE` where none), as
        :meth:`MotionGraph.distance` gives them (an unloaded graph has no sinks, so a node
        it does not expand has no moves at all: the table's UNREACHABLE there is
        ``distance``'s too)."""
        dist, far = self._table(k, shelves)
        out = dist[nodes][:, shelves].astype(np.int64)
        out[out == far] = UNREACHABLE
        return out

    def _table(self, k: int, shelves: np.ndarray) -> tuple[np.ndarray, int]:
        """The ``(cells, shelves)`` table of footprint ``k`` with ``shelves``' columns
        filled, and the value it holds where there is no way."""
        got = self._to_shelf.get(k)
        if got is None:
            # Distances below the node count fit uint16 on maps under 65,535 cells; the
            # columns take memory only once written.
            dtype = np.uint16 if self.num_nodes < _FAR16 else np.int32
            got = self._to_shelf[k] = (np.zeros((self.num_nodes, self.num_shelves), dtype),
                                       np.zeros(self.num_shelves, dtype=bool))
        dist, filled = got
        missing = shelves[~filled[shelves]]
        if len(missing):
            self._fill(self.graphs.get(k, False), dist, np.unique(missing))
            filled[missing] = True
        return dist, (_FAR16 if dist.dtype == np.uint16 else UNREACHABLE)

    def _fill(self, graph: MotionGraph, table: np.ndarray, shelves: np.ndarray) -> None:
        """Columns ``shelves`` of ``table``: the moves to each shelf's anchor, searched
        back from it over the graph's reversed edges, the search
        :meth:`MotionGraph.dist_to` runs (numba's, as :class:`.DistStore` uses: 0.23 ms a
        table on the industrial floor against 1.2 ms through scipy, load 9 on 2 cores)."""
        far = _FAR16 if table.dtype == np.uint16 else UNREACHABLE
        rev = graph._rev  # the CSR dist_to searches
        indptr, indices = rev.indptr.astype(np.int32), rev.indices.astype(np.int32)
        every = np.arange(self.num_nodes, dtype=np.int64)
        enterable = graph.enterable.ravel()
        col = np.empty(self.num_nodes, dtype=table.dtype)
        for s in shelves.tolist():
            goal = int(self.anchor_node[s])
            col.fill(far)
            if not enterable[goal]:
                pass  # no way in (dist_to: every cell UNREACHABLE)
            elif BFS_AVAILABLE:
                bfs_fill(indptr, indices, every, goal, col)
            else:  # pragma: no cover - numba is a dependency
                col[:] = np.minimum(graph.dist_to(divmod(goal, self.layout.cols)), far)
            table[:, s] = col

    def legs(self, k: int, j: np.ndarray, shelf: np.ndarray,
             stations: Sequence[tuple[int, ...]]) -> np.ndarray:
        """Loaded moves of each pair ``p``: from ``shelf[p]``'s anchor to each of
        ``stations[j[p]]`` in turn (int64, at most :data:`UNREACHABLE`)."""
        if k > 1:  # the loaded graph depends on the shelf carried
            return np.array([min(self.leg(k, s, stations[jj]), UNREACHABLE)
                             for jj, s in zip(j.tolist(), shelf.tolist(), strict=True)],
                            dtype=np.int64)
        # 1x1: one loaded graph; shelf -> first station from a table, the rest per SKU.
        first = np.array([st[0] if st else -1 for st in stations], dtype=np.int64)
        tail = np.array([sum(self._between(a, b) for a, b in zip(st, st[1:], strict=False))
                         for st in stations], dtype=np.int64)
        head = self._first_legs(shelf, first[j])
        return np.minimum(head + tail[j], UNREACHABLE)

    def _first_legs(self, shelf: np.ndarray, station: np.ndarray) -> np.ndarray:
        """Loaded moves (1x1) from each shelf's anchor to its station (-1: none, 0)."""
        if self._first is None:
            self._first = np.full((self.num_shelves, len(self.layout.stations)), -1,
                                  dtype=np.int64)
        has = station >= 0
        st = np.where(has, station, 0)
        for t in np.unique(st[has & (self._first[shelf, st] < 0)]).tolist():
            self._first[:, t] = self._first_column(t)
        return np.where(has, self._first[shelf, st], 0)

    def _first_column(self, station: int) -> np.ndarray:
        """Loaded moves (1x1) from every shelf's anchor to ``station``'s, as
        :meth:`MotionGraph.distance` counts them: a cell the graph expands reads the goal's
        table; a sink (a shelf's home: every anchor of a 1x1 shelf) is left through its
        best neighbour (a shelf's anchor is never a station's)."""
        loaded = self.graphs.get(1, True)
        goal = self._station_anchor(station, 1)
        table = np.append(loaded.dist_to(divmod(goal, self.layout.cols)), UNREACHABLE)
        if self._anchor_nbrs is None:  # neighbours of each anchor, padded with the extra cell
            nbrs = [loaded.neighbors[a] for a in self.anchor_node.tolist()]
            width = max((len(n) for n in nbrs), default=0)
            self._anchor_nbrs = np.array([n + (self.num_nodes,) * (width - len(n))
                                          for n in nbrs], dtype=np.int64).reshape(-1, width)
        via = table[self._anchor_nbrs].min(axis=1, initial=UNREACHABLE).astype(np.int64)
        via = np.where(via >= UNREACHABLE, UNREACHABLE, via + 1)
        expandable = np.asarray(loaded.expandable_flat, dtype=bool)[self.anchor_node]
        return np.where(expandable, table[self.anchor_node], via)

    def _between(self, a: int, b: int) -> int:
        """Loaded moves (1x1) from station ``a``'s anchor to station ``b``'s."""
        d = self._stations.get((a, b))
        if d is None:
            loaded = self.graphs.get(1, True)
            cols = self.layout.cols
            d = self._stations[(a, b)] = loaded.distance(
                divmod(self._station_anchor(a, 1), cols), divmod(self._station_anchor(b, 1), cols))
        return d

    def leg(self, k: int, shelf: int, stations: tuple[int, ...]) -> int:
        """Loaded moves from ``shelf``'s anchor to each of ``stations`` in turn, as
        :meth:`World.trip_distance <warerover_phys.world.World.trip_distance>` adds them."""
        key = (k, shelf, stations)
        d = self._legs.get(key)
        if d is None:
            if len(self._legs) > LEG_CACHE:
                self._legs.clear()
            loaded = self.graphs.get(k, True, shelf)
            here = self.layout.shelves[shelf].anchor
            d = 0
            for st in stations:
                target = divmod(self._station_anchor(st, k), self.layout.cols)
                d += loaded.distance(here, target)
                here = target
            self._legs[key] = d
        return d

    # ----------------------------------------------------------------------- options

    def options(self, agvs: Sequence[Agv], skus: Sequence[int],
                stations: Sequence[tuple[int, ...]], usable: np.ndarray,
                candidates: int) -> OptionTable:
        """Per AGV ``i`` and SKU ``j``: the ``candidates`` usable shelves holding
        ``skus[j]`` that the AGV can carry nearest to it by Manhattan distance (ties by
        shelf id), with their trip lengths via ``stations[j]``; see :class:`OptionTable`.
        ``usable``: bool per shelf (free, or any with ``orders.requeue_after_ticks``)."""
        table = OptionTable(len(agvs), len(skus))
        by_type: dict[str, list[int]] = {}
        for i, agv in enumerate(agvs):
            by_type.setdefault(agv.type_name, []).append(i)
        sku_arr = np.asarray(skus, dtype=np.int64)
        cols = self.layout.cols
        for name, rows in by_type.items():
            agv = agvs[rows[0]]
            j, shelf = self.sku_pairs(sku_arr, usable & self.carry_mask(name, agv.spec))
            if len(shelf) == 0:
                continue
            starts, lens = _runs(j)
            nodes = np.array([agvs[i].node for i in rows], dtype=np.int64)
            dist, far = self._table(agv.k, shelf)
            args = (dist, far, nodes, nodes // cols, nodes % cols, self.anchor_rc[:, 0],
                    self.anchor_rc[:, 1], shelf, starts, starts + lens,
                    self.legs(agv.k, j, shelf, stations), candidates, UNREACHABLE)
            rows_arr = np.asarray(rows, dtype=np.int64)
            best_trips(*args, rows_arr, j[starts], table.best)
            table.add_block(rows_arr, j[starts], args)
        return table


def _runs(j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and lengths of the runs of equal values in sorted ``j``."""
    if len(j) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    starts = np.flatnonzero(np.concatenate(([True], j[1:] != j[:-1])))
    return starts, np.diff(np.append(starts, len(j)))


class OptionTable:
    """Trip options per AGV ``i`` and SKU ``j``: :attr:`best` ``(agvs, skus)`` int64 is the
    shortest trip (:data:`UNREACHABLE` where there is none); :meth:`ranked` gives the
    candidate shelves of chosen pairs, shortest trip first (ties by shelf id)."""

    def __init__(self, num_agvs: int, num_skus: int) -> None:
        self.best = np.full((num_agvs, num_skus), UNREACHABLE, dtype=np.int64)
        self._blocks: list[tuple[np.ndarray, np.ndarray, tuple]] = []

    def add_block(self, rows: np.ndarray, skus: np.ndarray, args: tuple) -> None:
        """AGVs ``rows`` x SKU columns ``skus`` (runs in order) and the arguments of
        :func:`~.costs_nb.best_trips` they were costed with."""
        self._blocks.append((rows, skus, args))

    def ranked(self, pairs: Sequence[tuple[int, int]]) -> dict[tuple[int, int], list[int]]:
        """For each ``(i, j)`` of ``pairs``, the candidate shelves with a trip, best
        first (empty where there is none)."""
        out: dict[tuple[int, int], list[int]] = {p: [] for p in pairs}
        if not pairs:
            return out
        at = np.array(pairs, dtype=np.int64).reshape(-1, 2)
        for rows, skus, args in self._blocks:
            local = np.full(len(self.best), -1, dtype=np.int64)
            local[rows] = np.arange(len(rows))
            run = np.full(self.best.shape[1], -1, dtype=np.int64)
            run[skus] = np.arange(len(skus))
            mine = np.flatnonzero((local[at[:, 0]] >= 0) & (run[at[:, 1]] >= 0))
            if len(mine) == 0:
                continue
            keep = args[11]  # candidates
            shelves = np.empty((len(mine), keep), dtype=np.int64)
            ranked_options(*args, local[at[mine, 0]], run[at[mine, 1]], shelves)
            for m, row in zip(mine.tolist(), shelves.tolist(), strict=True):
                out[pairs[m]] = [s for s in row if s >= 0]
        return out
