"""Scenario schema: the layout (grid, map or generator, shelves, stations, parking)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import (
    Field,
    field_validator,
    model_validator,
)

from .types import MAX_SIDE, Bool, Cell, NonNegInt, PosFloat, PosInt, Seed, Side, _Model


class RectSpec(_Model):
    """A rectangle of cells: top-left ``origin`` (row, col) and its size in cells."""

    origin: Cell
    rows: PosInt = 1
    cols: PosInt = 1


class ShelfBlockSpec(_Model):
    """A block of ``rows`` x ``cols`` shelves, each ``size`` x ``size`` cells, packed tight."""

    origin: Cell
    rows: PosInt = 1
    cols: PosInt = 1
    size: PosInt = 1


class InventorySpec(_Model):
    """Which SKUs each shelf holds. Drawn once from ``seed`` (fixed with the layout)."""

    num_skus: PosInt | None = None
    """Number of distinct SKUs (default: 2 x number of shelves)."""
    skus_per_shelf: Annotated[PosInt, Field(le=10_000)] = 4
    seed: Seed = 0


class GeneratorSpec(_Model):
    """Parametric warehouse: a grid of shelf blocks with aisles, stations on one side."""

    block_rows: PosInt = 4
    block_cols: PosInt = 4
    block_shape: tuple[PosInt, PosInt] = (2, 4)
    """Shelves per block (rows, cols)."""
    shelf_size: PosInt = 1
    aisle_width: PosInt = 1
    cross_aisle_width: PosInt = 1
    border: PosInt = 2
    """Free cells between the outer wall of blocks and the station / parking sides."""
    stations: PosInt = 8
    station_side: Literal["left", "right", "top", "bottom"] = "left"
    parking: NonNegInt = 0
    """Parking cells (0: one per AGV in the fleet, filled in at load)."""
    parking_side: Literal["left", "right", "top", "bottom"] = "bottom"
    walls: Bool = True


class LayoutSpec(_Model):
    """Where the cells come from: exactly one of ``grid``, ``map`` or ``generator``.

    ``grid`` is ASCII rows (``.`` floor, ``#`` obstacle, ``S`` shelf, ``R`` receiving
    station, ``P`` parking, ``A`` maintenance access point); ``size`` with the lists below
    builds a structured layout on an empty floor; ``map`` reads a MovingAI ``.map`` file
    (``@ O T W`` are obstacles). Shelf blocks, stations, parking, obstacles and access points
    listed here are placed on top of whichever base was chosen.
    """

    cell_m: PosFloat = 1.0
    size: tuple[Side, Side] | None = None
    """(rows, cols) of an empty floor for a structured layout."""
    grid: list[str] | None = None
    map: str | None = None
    generator: GeneratorSpec | None = None
    shelf_blocks: list[ShelfBlockSpec] = Field(default_factory=list)
    stations: list[Cell] = Field(default_factory=list)
    parking: list[RectSpec] = Field(default_factory=list)
    obstacles: list[RectSpec] = Field(default_factory=list)
    access_points: list[Cell] = Field(default_factory=list)
    inventory: InventorySpec = InventorySpec()

    @field_validator("grid", mode="before")
    @classmethod
    def _split_grid(cls, value: Any) -> Any:
        if isinstance(value, str):
            return [line for line in value.strip("\n").splitlines()]
        return value

    @field_validator("grid")
    @classmethod
    def _grid_size(cls, value: list[str] | None) -> list[str] | None:
        if value is not None and (len(value) > MAX_SIDE or
                                  any(len(row) > MAX_SIDE for row in value)):
            raise ValueError(f"grid is larger than {MAX_SIDE} x {MAX_SIDE} cells")
        return value

    @model_validator(mode="after")
    def _one_base(self) -> LayoutSpec:
        bases = [n for n in ("size", "grid", "map", "generator") if getattr(self, n) is not None]
        if len(bases) != 1:
            raise ValueError(
                "give exactly one of size, grid, map, generator"
                + (f" (found {', '.join(bases)})" if bases else ""))
        return self
