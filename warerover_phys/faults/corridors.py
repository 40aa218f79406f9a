"""Safety corridors: the walkway a maintenance person takes to a failed AGV.

When an AGV fails, a corridor opens from the cells it covers to the nearest maintenance
access point (or, on a layout without access points, the nearest walkable cell on the map
border). Geometry is in world metres (``x = (col + 0.5) * cell_m``, ``y = (row + 0.5) *
cell_m``, y grows downward):

- ``polygon`` is the person's space: a union of axis-aligned rectangles, one per straight run
  of the route (``width_m`` wide, centred on the line through the cells' centres, extended
  by ``width_m / 2`` past both end centres so runs join without notches) plus the bounding
  box of the failed AGV's footprint;
- ``zone`` is ``polygon`` buffered by ``margin_m`` (mitre joins): no AGV may reach into it;
- ``cells`` are the grid cells whose square overlaps ``zone`` (area > 1e-9 m^2): the planner
  treats them as blocked while the corridor is open.

Everything is clipped to the map rectangle ``[0, cols * cell_m] x [0, rows * cell_m]``.

>>> from warerover_phys.config import LayoutSpec
>>> from warerover_phys.layout import build_layout
>>> lay = build_layout(LayoutSpec(grid=["#####", "#..S#", "#...A", "#R..#", "#####"]))
>>> cor = plan_corridor(lay, 0, agv=7, footprint_cells=[2 * 5 + 1], width_m=1.0,
...                     margin_m=0.0)
>>> cor.route, cor.access
(((2, 1), (2, 2), (2, 3), (2, 4)), (2, 4))
>>> cor.rects
((1.0, 2.0, 5.0, 3.0), (1.0, 2.0, 2.0, 3.0))
>>> sorted(cor.cells) == [11, 12, 13, 14]
True
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import Polygon

from ..errors import LayoutError, ScenarioError
from ..layout import Layout

__all__ = ["Corridor", "plan_corridor", "cover_mask"]

Cell = tuple[int, int]
Rect = tuple[float, float, float, float]

AREA_EPS_M2 = 1e-9
"""A cell square must overlap a zone by more than this (m^2) to count as covered."""

_STEPS = ((-1, 0), (0, -1), (0, 1), (1, 0))


@dataclass(frozen=True)
class Corridor:
    """An open safety corridor (immutable).

    ``rects`` are ``(xmin, ymin, xmax, ymax)`` in metres; their union is ``polygon``.
    ``cells`` are flat indices ``row * cols + col``.
    """

    id: int
    agv: int
    """The failed AGV the corridor leads to."""
    access: Cell
    """The (row, col) cell where the person enters: an access point or a border cell."""
    route: tuple[Cell, ...]
    """Cells from one of the AGV's footprint cells to ``access`` (both included); just the
    footprint cells (sorted) when the AGV already stands on a target cell."""
    rects: tuple[Rect, ...]
    margin_m: float
    polygon: Polygon
    """The person's space (m): the union of ``rects``."""
    zone: Polygon
    """The protected zone (m): ``polygon`` buffered by ``margin_m``, mitre joins, clipped."""
    cells: frozenset[int]
    """Flat cells whose square overlaps ``zone`` by more than 1e-9 m^2."""
    width_m: float = 0.0
    """The width (m) the corridor was planned with."""


def plan_corridor(layout: Layout, corridor_id: int, agv: int, footprint_cells: Iterable[int],
                  width_m: float, margin_m: float,
                  walkable: np.ndarray | None = None) -> Corridor:
    """The corridor from a failed AGV's footprint to the nearest access point.

    Args:
        layout: the floor.
        corridor_id: id given to the corridor.
        agv: id of the failed AGV.
        footprint_cells: flat cells (``row * cols + col``) the AGV covers: one cell, its
            ``k x k`` block, or both blocks while it moves between two cells.
        width_m: corridor width in metres (the person's space across each run).
        margin_m: safety margin in metres around the person's space.
        walkable: optional ``(rows, cols)`` bool mask of cells a person may walk on
            (default: neither obstacles nor shelves). Footprint cells always count as
            walkable.

    Targets are ``layout.access_points`` if the layout has any, else the walkable cells of
    the map border. The route is a shortest 4-neighbour path from any footprint cell; among
    targets at the same distance the lowest ``(row, col)`` wins.

    Raises:
        ScenarioError: ``width_m`` is not positive or wider than the map
            (field ``faults.corridor_width_m``), or ``margin_m`` is negative
            (field ``faults.corridor_margin_m``), or a footprint cell is off the map.
        LayoutError: no target is reachable from the footprint.
    """
    rows, cols, cell_m = layout.rows, layout.cols, float(layout.cell_m)
    if not width_m > 0 or width_m > min(rows, cols) * cell_m:
        raise ScenarioError(f"corridor width must be positive and at most the map's smaller "
                            f"side ({min(rows, cols) * cell_m:g} m)",
                            field="faults.corridor_width_m", value=width_m)
    if not margin_m >= 0:
        raise ScenarioError("corridor margin must be >= 0 m", field="faults.corridor_margin_m",
                            value=margin_m)
    foot = sorted({int(f) for f in footprint_cells})
    if not foot:
        raise ValueError(f"AGV {agv}: empty footprint")
    if foot[0] < 0 or foot[-1] >= rows * cols:
        raise ScenarioError(f"AGV {agv}: footprint cell outside the {rows}x{cols} layout",
                            field="faults", value=foot)
    foot_cells = [divmod(f, cols) for f in foot]

    walk = (~(layout.obstacles | layout.shelf_mask) if walkable is None
            else np.array(walkable, dtype=bool, copy=True))
    if walk.shape != (rows, cols):
        raise ValueError(f"walkable mask has shape {walk.shape}, layout is {(rows, cols)}")
    for r, c in foot_cells:
        walk[r, c] = True

    route = _route(walk, foot_cells, layout, agv)
    access = route[-1]
    rects = [_bbox_rect(foot_cells, cell_m)]
    if len(route) > 1:
        rects = [_run_rect(a, b, width_m, cell_m) for a, b in _runs(route)] + rects
    else:  # the AGV stands on a target: its footprint is the whole route
        route = tuple(foot_cells)
    map_w, map_h = cols * cell_m, rows * cell_m
    clipped = []
    for x0, y0, x1, y1 in rects:
        x0, y0, x1, y1 = max(x0, 0.0), max(y0, 0.0), min(x1, map_w), min(y1, map_h)
        if x1 > x0 and y1 > y0:
            clipped.append((x0, y0, x1, y1))
    polygon = shapely.union_all(shapely.box(*np.array(clipped).T))
    zone = polygon.buffer(margin_m, join_style="mitre") if margin_m > 0 else polygon
    zone = zone.intersection(shapely.box(0.0, 0.0, map_w, map_h))
    return Corridor(id=corridor_id, agv=agv, access=access, route=tuple(route),
                    rects=tuple(clipped), margin_m=float(margin_m), polygon=polygon,
                    zone=zone, cells=_covered_cells(zone, rows, cols, cell_m),
                    width_m=float(width_m))


def cover_mask(corridors: Iterable[Corridor], rows: int, cols: int) -> np.ndarray:
    """``(rows, cols)`` bool mask: the union of the corridors' ``cells``."""
    mask = np.zeros(rows * cols, dtype=bool)
    for cor in corridors:
        if cor.cells:
            mask[np.fromiter(cor.cells, dtype=np.int64, count=len(cor.cells))] = True
    return mask.reshape(rows, cols)


# ------------------------------------------------------------------------------ helpers


def _route(walk: np.ndarray, sources: list[Cell], layout: Layout, agv: int) -> tuple[Cell, ...]:
    """Shortest path from a source to the nearest target (lowest (row, col) on ties).

    Among the shortest paths it takes the one that goes straight for as long as it can at
    each cell (few turns: few rectangles, a walkway a person can follow).
    """
    if layout.access_points:
        targets = {tuple(a) for a in layout.access_points if walk[a[0], a[1]]}
        what = "maintenance access point"
    else:
        border = np.zeros_like(walk)
        border[0, :] = border[-1, :] = border[:, 0] = border[:, -1] = True
        targets = {(int(r), int(c)) for r, c in zip(*np.nonzero(border & walk), strict=True)}
        what = "walkable border cell"
    dist = _bfs(walk, sources, stop=targets)
    reached = [t for t in targets if dist[t] >= 0]
    if not reached:
        raise LayoutError(f"no {what} is reachable on foot from failed AGV {agv} at cells "
                          f"{sources}: cannot open a safety corridor",
                          field="layout.access_points" if layout.access_points else "layout")
    level = min(int(dist[t]) for t in reached)
    target = min(t for t in reached if dist[t] == level)
    back = _bfs(walk, [target], stop=set(sources))
    cell = min(s for s in sources if back[s] == level)
    path, heading = [cell], None
    rows, cols = walk.shape
    while back[cell] > 0:
        steps = [(dr, dc) for dr, dc in _STEPS
                 if 0 <= cell[0] + dr < rows and 0 <= cell[1] + dc < cols
                 and back[cell[0] + dr, cell[1] + dc] == back[cell] - 1]
        heading = heading if heading in steps else steps[0]
        cell = (cell[0] + heading[0], cell[1] + heading[1])
        path.append(cell)
    return tuple(path)


def _bfs(walk: np.ndarray, sources: list[Cell], stop: set[Cell]) -> np.ndarray:
    """4-neighbour BFS distances (cells) from ``sources`` over ``walk`` (-1: not reached),
    finished with the level on which the first cell of ``stop`` is reached."""
    rows, cols = walk.shape
    dist = np.full((rows, cols), -1, dtype=np.int64)
    frontier = list(sources)
    for cell in frontier:
        dist[cell] = 0
    level = 0
    while frontier and not any(cell in stop for cell in frontier):
        level += 1
        nxt: list[Cell] = []
        for r, c in frontier:
            for dr, dc in _STEPS:
                n = (r + dr, c + dc)
                if 0 <= n[0] < rows and 0 <= n[1] < cols and walk[n] and dist[n] < 0:
                    dist[n] = level
                    nxt.append(n)
        frontier = nxt
    return dist


def _runs(route: Sequence[Cell]) -> list[tuple[Cell, Cell]]:
    """(first, last) cells of each maximal straight run; consecutive runs share a cell."""
    runs = []
    start = 0
    for i in range(1, len(route) - 1):
        d_in = (route[i][0] - route[i - 1][0], route[i][1] - route[i - 1][1])
        d_out = (route[i + 1][0] - route[i][0], route[i + 1][1] - route[i][1])
        if d_in != d_out:
            runs.append((route[start], route[i]))
            start = i
    runs.append((route[start], route[-1]))
    return runs


def _run_rect(a: Cell, b: Cell, width_m: float, cell_m: float) -> Rect:
    """Rectangle around the segment between two cell centres, ``width_m`` wide and
    extended by ``width_m / 2`` past both ends."""
    half = width_m / 2
    xa, ya = (a[1] + 0.5) * cell_m, (a[0] + 0.5) * cell_m
    xb, yb = (b[1] + 0.5) * cell_m, (b[0] + 0.5) * cell_m
    return (min(xa, xb) - half, min(ya, yb) - half, max(xa, xb) + half, max(ya, yb) + half)


def _bbox_rect(cells: Sequence[Cell], cell_m: float) -> Rect:
    r = [c[0] for c in cells]
    c = [c[1] for c in cells]
    return (min(c) * cell_m, min(r) * cell_m, (max(c) + 1) * cell_m, (max(r) + 1) * cell_m)


def _covered_cells(zone: Polygon, rows: int, cols: int, cell_m: float) -> frozenset[int]:
    """Flat cells whose square overlaps ``zone`` by more than :data:`AREA_EPS_M2`."""
    if zone.is_empty:
        return frozenset()
    x0, y0, x1, y1 = zone.bounds
    c0, c1 = max(0, int(np.floor(x0 / cell_m))), min(cols, int(np.ceil(x1 / cell_m)))
    r0, r1 = max(0, int(np.floor(y0 / cell_m))), min(rows, int(np.ceil(y1 / cell_m)))
    rr, cc = np.meshgrid(np.arange(r0, r1), np.arange(c0, c1), indexing="ij")
    rr, cc = rr.ravel(), cc.ravel()
    squares = shapely.box(cc * cell_m, rr * cell_m, (cc + 1) * cell_m, (rr + 1) * cell_m)
    shapely.prepare(zone)
    near = shapely.intersects(zone, squares)
    area = np.zeros(len(squares))
    area[near] = shapely.area(shapely.intersection(squares[near], zone))
    keep = area > AREA_EPS_M2
    return frozenset((rr[keep] * cols + cc[keep]).tolist())
