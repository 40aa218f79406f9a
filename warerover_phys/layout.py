"""Warehouse layouts: a grid of typed cells plus what each shelf holds.

Cells are ``(row, col)``, row 0 at the top. A shelf of size ``s`` covers ``s x s`` cells from
its top-left anchor. Unloaded AGVs drive under shelves; an AGV carrying a shelf may not
(see :mod:`warerover_phys.planning.graph`).

A layout comes from one of four bases (see :class:`~warerover_phys.config.LayoutSpec`): an
ASCII ``grid``, an empty floor of ``size`` with structured lists, a MovingAI ``map``, or the
parametric ``generator``; shelf blocks, stations, parking and obstacles listed in the spec
are placed on top of the base.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .errors import LayoutError, ScenarioError

if TYPE_CHECKING:  # the scenario models (pydantic): not loaded by `warerover solve`
    from .config import GeneratorSpec, InventorySpec, LayoutSpec

__all__ = ["CellType", "Shelf", "Layout", "build_layout", "generate_base"]

Cell = tuple[int, int]


class CellType(IntEnum):
    FLOOR = 0
    OBSTACLE = 1
    SHELF = 2
    STATION = 3
    PARKING = 4


GRID_CHARS = {".": CellType.FLOOR, "#": CellType.OBSTACLE, "@": CellType.OBSTACLE,
              "T": CellType.OBSTACLE, "O": CellType.OBSTACLE, "W": CellType.OBSTACLE,
              "S": CellType.SHELF, "R": CellType.STATION, "P": CellType.PARKING,
              "A": CellType.FLOOR}


@dataclass(frozen=True, slots=True)
class Shelf:
    id: int
    anchor: Cell
    size: int
    skus: tuple[int, ...]

    @property
    def cells(self) -> tuple[Cell, ...]:
        r, c = self.anchor
        return tuple((r + i, c + j) for i in range(self.size) for j in range(self.size))


@dataclass(frozen=True, eq=False)
class Layout:
    """An immutable warehouse floor."""

    grid: np.ndarray
    """``(rows, cols)`` int8 array of :class:`CellType` values (read-only)."""
    cell_m: float
    shelves: tuple[Shelf, ...]
    stations: tuple[Cell, ...]
    parking: tuple[Cell, ...]
    access_points: tuple[Cell, ...]
    num_skus: int
    name: str = "layout"
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def rows(self) -> int:
        return int(self.grid.shape[0])

    @property
    def cols(self) -> int:
        return int(self.grid.shape[1])

    @property
    def obstacles(self) -> np.ndarray:
        return self.grid == CellType.OBSTACLE

    @property
    def shelf_mask(self) -> np.ndarray:
        return self.grid == CellType.SHELF

    @cached_property
    def sku_shelves(self) -> dict[int, tuple[int, ...]]:
        """SKU -> ids of the shelves that hold it."""
        out: dict[int, list[int]] = {}
        for shelf in self.shelves:
            for sku in shelf.skus:
                out.setdefault(sku, []).append(shelf.id)
        return {k: tuple(v) for k, v in out.items()}

    @cached_property
    def sku_sizes(self) -> tuple[int, ...]:
        """SKU -> container size class (the size of the shelves that hold it)."""
        sizes = [1] * self.num_skus
        for shelf in self.shelves:
            for sku in shelf.skus:
                sizes[sku] = shelf.size
        return tuple(sizes)

    def to_ascii(self) -> list[str]:
        chars = {v: k for k, v in GRID_CHARS.items() if k in ".#SRP"}
        rows = [[chars[CellType(v)] for v in row] for row in self.grid.tolist()]
        for r, c in self.access_points:
            rows[r][c] = "A"
        return ["".join(r) for r in rows]


# ------------------------------------------------------------------------------ building


def _grid_from_ascii(lines: list[str], file: str | None) -> np.ndarray:
    if not lines:
        raise ScenarioError("grid is empty", file=file, field="layout.grid")
    width = len(lines[0])
    grid = np.zeros((len(lines), width), dtype=np.int8)
    for r, line in enumerate(lines):
        if len(line) != width:
            raise ScenarioError(f"row {r} has {len(line)} cells, row 0 has {width}",
                                file=file, field=f"layout.grid[{r}]", value=line)
        for c, ch in enumerate(line):
            if ch not in GRID_CHARS:
                raise ScenarioError(f"unknown cell character at column {c} "
                                    f"(use one of {''.join(GRID_CHARS)})",
                                    file=file, field=f"layout.grid[{r}]", value=ch)
            grid[r, c] = GRID_CHARS[ch]
    return grid


def generate_base(gen: GeneratorSpec, fleet_size: int) -> np.ndarray:
    """Grid of a parametric warehouse: shelf blocks between aisles, stations and parking
    along two sides, an optional wall around everything.

    The shelf area is ``block_rows x block_cols`` blocks of ``block_shape`` shelves each,
    separated by ``aisle_width`` (between block columns) and ``cross_aisle_width`` (between
    block rows); ``border`` free cells separate it from the station and parking bands.
    """
    s = gen.shelf_size
    bh, bw = gen.block_shape[0] * s, gen.block_shape[1] * s
    area_h = gen.block_rows * bh + (gen.block_rows - 1) * gen.cross_aisle_width
    area_w = gen.block_cols * bw + (gen.block_cols - 1) * gen.aisle_width
    n_park = gen.parking or fleet_size
    side_len = {"left": area_h, "right": area_h, "top": area_w, "bottom": area_w}
    # Bands: stations in one cell-thick band; parking in as many rows as it needs, each row
    # of spots with a free lane beside it so no parked AGV is boxed in by others.
    park_rows = max(1, math.ceil(n_park / max(1, side_len[gen.parking_side] + 2 * gen.border)))
    park_depth = 2 * park_rows - 1
    if gen.station_side == gen.parking_side:
        raise ScenarioError("stations and parking must be on different sides",
                            field="layout.generator.parking_side", value=gen.parking_side)
    margin = {side: gen.border for side in ("left", "right", "top", "bottom")}
    margin[gen.station_side] += 1 + 1  # station band + one free lane in front of it
    margin[gen.parking_side] += park_depth + 1
    wall = 1 if gen.walls else 0
    rows = area_h + margin["top"] + margin["bottom"] + 2 * wall
    cols = area_w + margin["left"] + margin["right"] + 2 * wall
    from .config import MAX_CELLS

    if rows * cols > MAX_CELLS:
        raise ScenarioError(f"generated layout would be {rows} x {cols} cells (at most "
                            f"{MAX_CELLS:,})", field="layout.generator",
                            value=f"{rows}x{cols}")
    grid = np.zeros((rows, cols), dtype=np.int8)
    if wall:
        grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = CellType.OBSTACLE
    top, left = wall + margin["top"], wall + margin["left"]
    for br in range(gen.block_rows):
        for bc in range(gen.block_cols):
            r0 = top + br * (bh + gen.cross_aisle_width)
            c0 = left + bc * (bw + gen.aisle_width)
            grid[r0:r0 + bh, c0:c0 + bw] = CellType.SHELF
    _place_band(grid, gen.station_side, wall, gen.stations, CellType.STATION, depth=1,
                spread=True, field="layout.generator.stations")
    _place_band(grid, gen.parking_side, wall, n_park, CellType.PARKING, depth=park_depth,
                spread=False, field="layout.generator.parking", every_other=True)
    return grid


def _place_band(grid: np.ndarray, side: str, wall: int, count: int, kind: CellType, *,
                depth: int, spread: bool, field: str, every_other: bool = False) -> None:
    rows, cols = grid.shape
    # Cells of the band, listed along the side, one lane at a time from the wall inwards.
    lanes: list[list[Cell]] = []
    for d in range(depth):
        if side == "left":
            lane = [(r, wall + d) for r in range(wall + 1, rows - wall - 1)]
        elif side == "right":
            lane = [(r, cols - 1 - wall - d) for r in range(wall + 1, rows - wall - 1)]
        elif side == "top":
            lane = [(wall + d, c) for c in range(wall + 1, cols - wall - 1)]
        else:
            lane = [(rows - 1 - wall - d, c) for c in range(wall + 1, cols - wall - 1)]
        if not every_other or d % 2 == 0:
            lanes.append(lane)
    capacity = sum(len(lane) for lane in lanes)
    if count > capacity:
        raise ScenarioError(f"only {capacity} cells fit on the {side} side", field=field,
                            value=count)
    if spread:
        lane = lanes[0]
        idx = np.linspace(0, len(lane) - 1, num=count).round().astype(int) if count > 1 \
            else np.array([len(lane) // 2])
        cells = [lane[i] for i in dict.fromkeys(idx.tolist())]
    else:
        cells = [cell for lane in lanes for cell in lane][:count]
    for r, c in cells:
        grid[r, c] = kind


def _check_cell(cell: Cell, grid: np.ndarray, file: str | None, field: str,
                allowed: tuple[CellType, ...] = (CellType.FLOOR,)) -> None:
    r, c = cell
    if not (0 <= r < grid.shape[0] and 0 <= c < grid.shape[1]):
        raise ScenarioError(f"cell is outside the {grid.shape[0]}x{grid.shape[1]} layout",
                            file=file, field=field, value=list(cell))
    if grid[r, c] not in allowed:
        raise ScenarioError(f"cell is already {CellType(grid[r, c]).name.lower()}",
                            file=file, field=field, value=list(cell))


def _assign_inventory(shelf_cells: list[tuple[Cell, int]], inv: InventorySpec,
                      file: str | None) -> tuple[list[Shelf], int]:
    n_shelves = len(shelf_cells)
    if n_shelves == 0:
        raise ScenarioError("layout has no shelves", file=file, field="layout")
    num_skus = inv.num_skus if inv.num_skus is not None else 2 * n_shelves
    if num_skus > n_shelves * inv.skus_per_shelf:
        raise ScenarioError(f"{n_shelves} shelves x {inv.skus_per_shelf} SKUs per shelf "
                            f"cannot hold {num_skus} SKUs", file=file,
                            field="layout.inventory.num_skus", value=num_skus)
    rng = np.random.default_rng(inv.seed)
    sizes = sorted({size for _, size in shelf_cells})
    by_size = {s: [i for i, (_, size) in enumerate(shelf_cells) if size == s] for s in sizes}
    # SKUs are split between size classes in proportion to their shelves (at least one each).
    counts = {s: max(1, round(num_skus * len(by_size[s]) / n_shelves)) for s in sizes}
    counts[sizes[-1]] = max(1, num_skus - sum(counts[s] for s in sizes[:-1]))
    if sum(counts.values()) != num_skus:
        raise ScenarioError("too few SKUs for every shelf size class to have one",
                            file=file, field="layout.inventory.num_skus", value=num_skus)
    skus_of_shelf: dict[int, tuple[int, ...]] = {}
    next_sku = 0
    for s in sizes:
        ids = by_size[s]
        class_skus = np.arange(next_sku, next_sku + counts[s])
        next_sku += counts[s]
        slots = len(ids) * inv.skus_per_shelf
        reps = math.ceil(slots / len(class_skus))
        seq = np.concatenate([rng.permutation(class_skus) for _ in range(reps)])[:slots]
        for k, shelf_idx in enumerate(ids):
            chunk = seq[k * inv.skus_per_shelf:(k + 1) * inv.skus_per_shelf]
            skus_of_shelf[shelf_idx] = tuple(sorted(set(int(x) for x in chunk)))
    shelves = [Shelf(i, anchor, size, skus_of_shelf[i])
               for i, (anchor, size) in enumerate(shelf_cells)]
    return shelves, num_skus


def build_layout(spec: LayoutSpec, *, fleet_size: int = 0, file: str | None = None,
                 name: str = "layout", errands: bool = False) -> Layout:
    """Build (but do not yet check against a fleet) the layout a spec describes. With
    ``errands`` (errand tasks, no shelf orders) the floor may lack shelves and stations."""
    shelf_sizes: dict[Cell, int] = {}
    access: list[Cell] = []
    if spec.grid is not None:
        grid = _grid_from_ascii(spec.grid, file)
        access = [(r, c) for r, line in enumerate(spec.grid) for c, ch in enumerate(line)
                  if ch == "A"]
    elif spec.map is not None:
        from .inputs import describe
        from .problems.movingai import read_map

        kind = describe(spec.map)
        if kind != "a regular file":
            why = "MovingAI map file not found" if kind == "missing" else \
                f"MovingAI map is {kind}, not a regular file"
            raise ScenarioError(why, file=file, field="layout.map", value=spec.map)
        grid = np.where(read_map(spec.map).obstacles, CellType.OBSTACLE,
                        CellType.FLOOR).astype(np.int8)
    elif spec.generator is not None:
        grid = generate_base(spec.generator, fleet_size)
        if spec.generator.shelf_size > 1:
            shelf_sizes = _blocks_of_size(grid, spec.generator.shelf_size)
    else:
        assert spec.size is not None
        grid = np.zeros(spec.size, dtype=np.int8)

    for i, rect in enumerate(spec.obstacles):
        _fill_rect(grid, rect.origin, rect.rows, rect.cols, CellType.OBSTACLE, file,
                   f"layout.obstacles[{i}]")
    for i, block in enumerate(spec.shelf_blocks):
        r0, c0 = block.origin
        for br in range(block.rows):
            for bc in range(block.cols):
                anchor = (r0 + br * block.size, c0 + bc * block.size)
                _fill_rect(grid, anchor, block.size, block.size, CellType.SHELF, file,
                           f"layout.shelf_blocks[{i}]")
                if block.size > 1:
                    shelf_sizes[anchor] = block.size
    for i, cell in enumerate(spec.stations):
        _check_cell(tuple(cell), grid, file, f"layout.stations[{i}]")
        grid[cell[0], cell[1]] = CellType.STATION
    for i, rect in enumerate(spec.parking):
        _fill_rect(grid, rect.origin, rect.rows, rect.cols, CellType.PARKING, file,
                   f"layout.parking[{i}]")
    for i, cell in enumerate(spec.access_points):
        _check_cell(tuple(cell), grid, file, f"layout.access_points[{i}]",
                    allowed=(CellType.FLOOR, CellType.PARKING))
        access.append(tuple(cell))

    # Shelves: sized blocks first, the remaining shelf cells are 1x1 shelves.
    covered: set[Cell] = set()
    shelf_cells: list[tuple[Cell, int]] = []
    for anchor, size in sorted(shelf_sizes.items()):
        shelf_cells.append((anchor, size))
        covered.update((anchor[0] + i, anchor[1] + j) for i in range(size) for j in range(size))
    for r, c in zip(*np.nonzero(grid == CellType.SHELF), strict=True):
        if (int(r), int(c)) not in covered:
            shelf_cells.append(((int(r), int(c)), 1))
    shelf_cells.sort()
    if errands and not shelf_cells:
        shelves, num_skus = [], 0
    else:
        shelves, num_skus = _assign_inventory(shelf_cells, spec.inventory, file)

    stations = tuple((int(r), int(c)) for r, c in zip(*np.nonzero(grid == CellType.STATION),
                                                       strict=True))
    if spec.stations:  # keep the order the user listed them in
        stations = tuple(tuple(s) for s in spec.stations) + tuple(
            s for s in stations if s not in {tuple(x) for x in spec.stations})
    parking = tuple((int(r), int(c)) for r, c in zip(*np.nonzero(grid == CellType.PARKING),
                                                      strict=True))
    if not stations and not errands:
        raise LayoutError("layout has no receiving stations", file=file, field="layout.stations")
    grid.setflags(write=False)
    return Layout(grid=grid, cell_m=spec.cell_m, shelves=tuple(shelves), stations=stations,
                  parking=parking, access_points=tuple(access), num_skus=num_skus, name=name)


def _blocks_of_size(grid: np.ndarray, size: int) -> dict[Cell, int]:
    """Tile every shelf region of a generated grid into ``size x size`` shelves."""
    out: dict[Cell, int] = {}
    taken = np.zeros(grid.shape, dtype=bool)
    for r, c in zip(*np.nonzero(grid == CellType.SHELF), strict=True):
        r, c = int(r), int(c)
        if taken[r, c]:
            continue
        block = grid[r:r + size, c:c + size]
        if block.shape == (size, size) and (block == CellType.SHELF).all() \
                and not taken[r:r + size, c:c + size].any():
            out[(r, c)] = size
            taken[r:r + size, c:c + size] = True
    return out


def _fill_rect(grid: np.ndarray, origin: Cell, rows: int, cols: int, kind: CellType,
               file: str | None, field: str) -> None:
    r0, c0 = origin
    if r0 < 0 or c0 < 0 or r0 + rows > grid.shape[0] or c0 + cols > grid.shape[1]:
        raise ScenarioError(f"{rows}x{cols} cells at {list(origin)} reach outside the "
                            f"{grid.shape[0]}x{grid.shape[1]} layout", file=file, field=field,
                            value=list(origin))
    region = grid[r0:r0 + rows, c0:c0 + cols]
    bad = region[(region != CellType.FLOOR) & (region != kind)]
    if bad.size:
        raise ScenarioError(f"overlaps {CellType(bad[0]).name.lower()} cells", file=file,
                            field=field, value=list(origin))
    region[...] = kind


def layout_path_name(source: str | None) -> str:
    return Path(source).stem if source else "layout"
