"""Where an AGV of a given footprint may stand, and how far everything is from a goal.

A *node* is the flat index ``row * cols + col`` of an AGV's anchor (its top-left cell). For a
``k x k`` AGV an anchor is *valid* if all ``k x k`` cells are inside the grid and passable:

- unloaded AGVs drive under shelves, so only obstacles block them;
- loaded AGVs (carrying a shelf) are blocked by obstacles and by other shelves. For 1x1 AGVs
  one graph serves every shelf: the home anchors of 1x1 shelves are *sinks*, which a loaded
  AGV may enter (to put its shelf back, only as its goal) and leave when it starts on one,
  but never drives through. A bigger AGV leaving its shelf's home overlaps the home's own
  cells for a while, so its loaded graph is built per carried shelf (those cells are free).

Cells can be *closed* for a while (safety corridors around failed AGVs): no move may enter
an anchor whose footprint touches a closed area from outside; an AGV already inside may only
move one step nearer the area's edge at a time, so it leaves by the shortest way.

Distances are exact shortest-path move counts on this graph, computed once per goal (scipy's
breadth-first search cut into levels: 1.5-2x faster than its unweighted Dijkstra on a
70,000-cell map) and kept in a least recently used cache bounded in bytes
(:data:`TABLE_BUDGET_BYTES`).
"""

from __future__ import annotations

from collections import OrderedDict
from typing import TYPE_CHECKING

import numpy as np

from ..layout import CellType, Layout
from .headings import dead_ends, turn_dist

if TYPE_CHECKING:  # scipy is imported where a search runs (`warerover solve` does without)
    from scipy.sparse import csr_matrix

__all__ = ["MotionGraph", "GraphSet", "UNREACHABLE"]

UNREACHABLE = np.iinfo(np.int32).max // 4
TABLE_BUDGET_BYTES = 1 << 30
"""Memory the distance tables of one motion graph may hold (1 GiB): 3,800 goals on a
70,000-cell map, any number on a warehouse floor."""
Cell = tuple[int, int]


def _window_all(mask: np.ndarray, k: int) -> np.ndarray:
    """``out[r, c]`` is True iff ``mask[r:r+k, c:c+k]`` is all True (and inside the grid)."""
    rows, cols = mask.shape
    out = np.zeros_like(mask, dtype=bool)
    if k > rows or k > cols:
        return out
    integral = np.pad(mask.astype(np.int32), ((1, 0), (1, 0))).cumsum(0).cumsum(1)
    sums = (integral[k:, k:] - integral[:-k, k:] - integral[k:, :-k] + integral[:-k, :-k])
    out[: rows - k + 1, : cols - k + 1] = sums == k * k
    return out


def bfs_depths(graph: csr_matrix, source: int) -> np.ndarray:
    """Unweighted shortest-path lengths from ``source`` along ``graph``'s edges (int32,
    :data:`UNREACHABLE` where none). scipy's breadth-first search lists the reached nodes
    level by level, each node's parent earlier in the list than any later node's parent; so
    the levels are cut where the parents' positions pass the previous level's end."""
    from scipy.sparse.csgraph import breadth_first_order

    n = graph.shape[0]
    order, pred = breadth_first_order(graph, source, directed=True, return_predecessors=True)
    depth = np.full(n, UNREACHABLE, dtype=np.int32)
    depth[source] = 0
    if len(order) == 1:
        return depth
    pos = np.empty(n, dtype=np.int64)
    pos[order] = np.arange(len(order))
    parent_pos = pos[pred[order[1:]]]  # nondecreasing
    # step[b] = 1 + (parents before position b): where the level after one ending at b ends
    below = np.bincount(parent_pos, minlength=len(order)).cumsum()
    step = (1 + np.concatenate(([0], below))).tolist()
    bounds = [0, 1]
    while bounds[-1] < len(order):
        bounds.append(step[bounds[-1]])
    sizes = np.diff(bounds)
    depth[order] = np.repeat(np.arange(len(sizes), dtype=np.int32), sizes)
    return depth


def _exit_moves(closed: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Per anchor in ``closed``, the fewest 4-neighbour moves over ``valid`` anchors to a
    valid anchor outside ``closed`` (0 outside; a large number where there is none)."""
    rows, cols = closed.shape
    far = rows * cols + 1
    out = np.where(closed, far, 0).astype(np.int64)
    frontier = [(int(r), int(c)) for r, c in np.argwhere(closed)
                if valid[r, c] and any(0 <= r + dr < rows and 0 <= c + dc < cols
                                       and valid[r + dr, c + dc] and not closed[r + dr, c + dc]
                                       for dr, dc in ((0, 1), (1, 0), (0, -1), (-1, 0)))]
    for r, c in frontier:
        out[r, c] = 1
    d = 1
    while frontier:
        d += 1
        nxt = []
        for r, c in frontier:
            for dr, dc in ((0, 1), (1, 0), (0, -1), (-1, 0)):
                rr, cc = r + dr, c + dc
                if 0 <= rr < rows and 0 <= cc < cols and closed[rr, cc] and valid[rr, cc] \
                        and out[rr, cc] == far:
                    out[rr, cc] = d
                    nxt.append((rr, cc))
        frontier = nxt
    return out


class MotionGraph:
    """Anchors and moves of one AGV class (footprint ``k``, loaded or not) on a layout."""

    def __init__(self, layout: Layout, k: int, loaded: bool, carrying: int | None = None,
                 cache_tables: int = 0, closed: np.ndarray | None = None) -> None:
        self.layout = layout
        self.closed_cells = closed
        self.k = k
        self.loaded = loaded
        self.carrying = carrying if loaded and k > 1 else None
        self.rows, self.cols = layout.rows, layout.cols
        grid = layout.grid
        passable = grid != CellType.OBSTACLE
        if loaded:
            passable &= grid != CellType.SHELF
            if self.carrying is not None:
                for cell in layout.shelves[self.carrying].cells:
                    passable[cell] = True
        self.valid = _window_all(passable, k)
        sinks = np.zeros_like(self.valid)
        if loaded and k == 1:
            for shelf in layout.shelves:
                if shelf.size == k:
                    sinks[shelf.anchor] = True
        self.sinks = sinks
        self.has_sinks = bool(sinks.any())
        self.enterable = self.valid | sinks
        # Per closed area (one mask each), the anchors whose footprint touches it:
        # exit-only for that area.
        areas = [] if closed is None else [m for m in np.reshape(
            closed, (-1, self.rows, self.cols)) if m.any()]
        self._closed_areas = [~_window_all(~m, k) for m in areas]
        # Moves (over this graph's anchors) to the nearest anchor outside *every* closed
        # area: an AGV in one area next to another (two corridors side by side), or whose
        # nearest way out is blocked (a loaded AGV beside shelves), still has a way out.
        steps = _exit_moves(np.logical_or.reduce(self._closed_areas), self.valid) \
            if areas else None
        self._exit_steps = [steps for _ in self._closed_areas]
        """Per closed area, moves from each anchor to the nearest anchor outside all."""
        self.closed = (np.logical_or.reduce(self._closed_areas) if self._closed_areas
                       else np.zeros_like(self.valid))
        self.expandable_flat: list[bool] = self.valid.ravel().tolist()
        self._build_edges()
        n = self.rows * self.cols
        self._cap = cache_tables or max(32, int(TABLE_BUDGET_BYTES // max(1, 4 * n)))
        self._tables: OrderedDict[int, np.ndarray] = OrderedDict()

    # -------------------------------------------------------------------------- structure

    def _build_edges(self) -> None:
        rows, cols = self.rows, self.cols
        n = rows * cols
        src, dst = [], []
        idx = np.arange(n).reshape(rows, cols)
        # A move u -> v needs u enterable (the start may be a sink) and v enterable; moves
        # out of a sink are kept in the adjacency but only taken from the start node.
        for dr, dc in ((0, 1), (1, 0), (0, -1), (-1, 0)):
            r0, r1 = max(0, -dr), rows - max(0, dr)
            c0, c1 = max(0, -dc), cols - max(0, dc)
            u = idx[r0:r1, c0:c1]
            v = idx[r0 + dr:r1 + dr, c0 + dc:c1 + dc]
            ok = self.enterable[r0:r1, c0:c1] & self.enterable[r0 + dr:r1 + dr, c0 + dc:c1 + dc]
            # Into a closed area only from inside the same area, and there only one step
            # nearer its edge: an AGV inside takes the shortest way out.
            for area, out in zip(self._closed_areas, self._exit_steps, strict=True):
                into = area[r0 + dr:r1 + dr, c0 + dc:c1 + dc]
                ok &= ~into | (area[r0:r1, c0:c1] & (
                    out[r0 + dr:r1 + dr, c0 + dc:c1 + dc] < out[r0:r1, c0:c1]))
            src.append(u[ok])
            dst.append(v[ok])
        src_a = np.concatenate(src)
        dst_a = np.concatenate(dst)
        flat_valid = self.valid.ravel()
        # Adjacency lists used by the searches (sorted for determinism).
        order = np.lexsort((dst_a, src_a))
        src_a, dst_a = src_a[order], dst_a[order]
        starts = np.searchsorted(src_a, np.arange(n + 1))
        self._adj_src = starts
        self._adj_dst = dst_a
        self.neighbors: list[tuple[int, ...]] = [
            tuple(dst_a[starts[i]:starts[i + 1]].tolist()) for i in range(n)]
        # Reversed graph for distance-to-goal tables: a forward edge u->v exists in the
        # plain graph if u is valid (expandable); reversed it is v->u.
        keep = flat_valid[src_a]
        self._rev_edges = (dst_a[keep], src_a[keep])
        self._rev_csr: csr_matrix | None = None

    @property
    def _rev(self) -> csr_matrix:
        """The reversed graph (scipy CSR), built on first use."""
        if self._rev_csr is None:
            from scipy.sparse import csr_matrix

            n = self.rows * self.cols
            rows, cols = self._rev_edges
            self._rev_csr = csr_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)),
                                       shape=(n, n))
        return self._rev_csr

    @property
    def num_nodes(self) -> int:
        return self.rows * self.cols

    def node(self, cell: Cell) -> int:
        return cell[0] * self.cols + cell[1]

    def cell(self, node: int) -> Cell:
        return divmod(node, self.cols)

    def expandable(self, node: int) -> bool:
        return self.expandable_flat[node]

    def is_enterable(self, cell: Cell) -> bool:
        r, c = cell
        return 0 <= r < self.rows and 0 <= c < self.cols and bool(self.enterable[r, c])

    def footprint(self, anchor: Cell) -> tuple[Cell, ...]:
        r, c = anchor
        k = self.k
        return tuple((r + i, c + j) for i in range(k) for j in range(k))

    def succ(self, node: int, is_start: bool = False) -> tuple[int, ...]:
        """Nodes one move away. Sinks are left only when they are the search's start."""
        if is_start or self.expandable_flat[node]:
            return self.neighbors[node]
        return ()

    # -------------------------------------------------------------------------- distances

    def dist_to(self, goal: Cell) -> np.ndarray:
        """Moves from every node to ``goal`` (flat int32 array, UNREACHABLE where none)."""
        g = self.node(goal)
        table = self._tables.get(g)
        if table is not None:
            self._tables.move_to_end(g)
            return table
        table = bfs_depths(self._rev, g)
        if not self.enterable.ravel()[g]:
            table[:] = UNREACHABLE
        table.setflags(write=False)
        self._tables[g] = table
        if len(self._tables) > self._cap:
            self._tables.popitem(last=False)
        return table

    def distance(self, start: Cell, goal: Cell) -> int:
        """Moves from ``start`` to ``goal``; a sink start is left through its neighbours."""
        table = self.dist_to(goal)
        s = self.node(start)
        if s == self.node(goal):
            return 0
        if self.expandable(s):
            return int(table[s])
        best = min((int(table[v]) for v in self.neighbors[s]), default=UNREACHABLE)
        return UNREACHABLE if best >= UNREACHABLE else best + 1

    def static_path(self, start: Cell, goal: Cell) -> list[int]:
        """A shortest path of anchor nodes ignoring other AGVs (empty if unreachable)."""
        table = self.dist_to(goal)
        node, g = self.node(start), self.node(goal)
        if self.distance(start, goal) >= UNREACHABLE:
            return []
        path = [node]
        while node != g:
            node = min(self.succ(node, is_start=(node == path[0])),
                       key=lambda v: (int(table[v]) if self.expandable_flat[v] or v == g
                                      else UNREACHABLE, v))
            path.append(node)
        return path

    def dead_ends(self, no_turn: frozenset[int]) -> frozenset[tuple[int, int]]:
        """States ``(anchor, direction index)`` a turn-aware AGV must never enter on this
        graph (:func:`~warerover_phys.planning.sweep.dead_ends`), cached per mask."""
        if not no_turn:
            return frozenset()
        cache = self.__dict__.setdefault("_dead_cache", {})
        out = cache.get(no_turn)
        if out is None:
            out = cache[no_turn] = dead_ends(self.neighbors, no_turn, self.cols,
                                             self.expandable_flat)
        return out

    def turn_dist(self, no_turn: frozenset[int], goal: int,
                  goal_dead: frozenset[int] | None = None) -> dict[tuple[int, int], int]:
        """Moves to ``goal`` from each state ``(anchor, heading index)`` of a turn-aware AGV
        on this graph (:func:`~warerover_phys.planning.sweep.turn_dist`), cached."""
        cache = self.__dict__.setdefault("_reach_cache", OrderedDict())
        key = (no_turn, goal, goal_dead)
        out = cache.get(key)
        if out is None:
            out = cache[key] = turn_dist(self.neighbors, no_turn, self.dead_ends(no_turn),
                                         self.cols, goal, goal_dead, self.expandable_flat)
            if len(cache) > 256:
                cache.popitem(last=False)
        return out

    def reachable_from(self, start: Cell) -> np.ndarray:
        """Boolean (rows, cols) mask of anchors reachable from ``start`` (unloaded graphs
        are symmetric, so this is the set that can reach ``start`` too)."""
        return (self.dist_to(start) < UNREACHABLE).reshape(self.rows, self.cols)

    def goal_anchor(self, cell: Cell) -> Cell | None:
        """The anchor whose footprint covers ``cell`` that a ``k x k`` AGV uses to reach it:
        ``cell`` itself if valid, else the nearest valid anchor covering it."""
        r, c = cell
        k = self.k
        options = sorted((dr + dc, dr, dc) for dr in range(k) for dc in range(k))
        for _, dr, dc in options:
            a = (r - dr, c - dc)
            if 0 <= a[0] < self.rows and 0 <= a[1] < self.cols and self.valid[a]:
                return a
        return None


class GraphSet:
    """The motion graphs of one layout, built lazily per (footprint, loaded, carried shelf).

    The carried shelf matters only for loaded AGVs bigger than 1x1; those graphs are kept in
    a small LRU cache.
    """

    def __init__(self, layout: Layout, per_shelf_cache: int = 64,
                 closed: np.ndarray | None = None) -> None:
        self.layout = layout
        self.closed = closed if closed is not None and closed.any() else None
        """Bool mask of closed cells, ``(rows, cols)`` or one per area ``(n, rows, cols)``
        (see the module doc), or None."""
        self._graphs: dict[tuple[int, bool], MotionGraph] = {}
        self._per_shelf: OrderedDict[tuple[int, int], MotionGraph] = OrderedDict()
        self._cap = per_shelf_cache

    def get(self, k: int, loaded: bool, shelf: int | None = None) -> MotionGraph:
        if loaded and k > 1 and shelf is not None:
            key2 = (k, shelf)
            graph = self._per_shelf.get(key2)
            if graph is None:
                graph = self._per_shelf[key2] = MotionGraph(self.layout, k, True, shelf,
                                                            closed=self.closed)
                if len(self._per_shelf) > self._cap:
                    self._per_shelf.popitem(last=False)
            else:
                self._per_shelf.move_to_end(key2)
            return graph
        key = (k, loaded)
        graph = self._graphs.get(key)
        if graph is None:
            graph = self._graphs[key] = MotionGraph(self.layout, k, loaded, closed=self.closed)
        return graph
