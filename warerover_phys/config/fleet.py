"""Scenario schema: the fleet (AGV types and groups)."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import (
    Field,
    model_validator,
)

from .types import Cell, NonNegFloat, PosFloat, PosInt, _Model


class AgvTypeSpec(_Model):
    """One kind of AGV. Defaults follow RAWSim-O (0.35 m radius, 1.5 m/s, 1 m/s^2)."""

    footprint: PosInt = 1
    """Side of the square cell footprint: 1 = 1x1 cells, 2 = 2x2 cells."""
    body_m: tuple[PosFloat, PosFloat] = (0.7, 0.7)
    """Body length and width in metres; must fit in the footprint."""
    mass_kg: PosFloat = 100.0
    max_speed_mps: PosFloat = 1.5
    max_accel_mps2: PosFloat = 1.0
    max_turn_rate_radps: PosFloat = 2.5
    cargo_class: PosInt | None = None
    """Largest container / shelf size class the AGV may carry (default: its footprint)."""
    drive: Literal["diff", "omni"] = "diff"
    payload_kg: NonNegFloat = 0.0
    """Mass of the shelf it carries (kg). Physics with ``executor.payload: true``: a loaded
    AGV's acceleration limit is its drive force over the loaded mass,
    ``mass_kg x max_accel_mps2 / (mass_kg + payload_kg)``; 0 (default) = no change."""

    wheel_base_m: PosFloat | None = None
    """Differential drive: distance between the two drive wheels (metres), at most the body's
    width. With ``max_wheel_speed_mps`` each wheel's speed ``|v +- omega x wheel_base_m / 2|``
    is a limit of the no-slip drive (physics, ``executor.no_slip``). None: no wheel limit."""
    max_wheel_speed_mps: PosFloat | None = None
    """Differential drive: top speed of each drive wheel (m/s). It must allow the type's top
    speed driving straight and its turn rate in place (at least ``max_speed_mps`` and
    ``max_turn_rate_radps x wheel_base_m / 2``), so it binds only when the AGV turns while it
    drives (steering back onto its path)."""

    @model_validator(mode="after")
    def _wheel_limits(self) -> AgvTypeSpec:
        base, wheel = self.wheel_base_m, self.max_wheel_speed_mps
        if (base is None) != (wheel is None):
            raise ValueError("wheel_base_m and max_wheel_speed_mps go together: give both "
                             "or neither")
        if base is None or wheel is None:
            return self
        if self.drive == "omni":
            raise ValueError("wheel_base_m / max_wheel_speed_mps are differential-drive "
                             "limits (drive: diff)")
        if base > self.body_m[1] + 1e-9:
            raise ValueError(f"wheel_base_m {base:g} is wider than the body "
                             f"(body_m width {self.body_m[1]:g})")
        need = max(self.max_speed_mps, self.max_turn_rate_radps * base / 2)
        if wheel < need - 1e-9:
            raise ValueError(f"max_wheel_speed_mps {wheel:g} is below what driving straight "
                             f"at max_speed_mps and turning in place at max_turn_rate_radps "
                             f"need ({need:.4g}): lower those or raise it")
        return self

    @property
    def loaded_accel_mps2(self) -> float:
        """Acceleration limit while carrying a shelf (m/s^2), when payloads count."""
        return self.mass_kg * self.max_accel_mps2 / (self.mass_kg + self.payload_kg)

    @property
    def carries(self) -> int:
        return self.cargo_class if self.cargo_class is not None else self.footprint

    def can_carry(self, shelf_size: int) -> bool:
        """It lifts a shelf from under it: the shelf must match its footprint and cargo
        class."""
        return shelf_size == self.footprint and shelf_size <= self.carries

    def ticks_per_move(self, cell_m: float, tick_s: float) -> int:
        """Ticks one cell move takes at top speed (at least 1).

        A tiny tolerance keeps 1.0 m at 1.0 m/s with 1.0 s ticks at exactly one tick.
        """
        return max(1, math.ceil(cell_m / (self.max_speed_mps * tick_s) - 1e-9))


class AgvGroupSpec(_Model):
    type: str = "default"
    count: PosInt = 1
    starts: list[Cell] | None = None
    """Explicit start anchors (row, col); default: free parking spots in row-major order."""

    @model_validator(mode="after")
    def _starts_match_count(self) -> AgvGroupSpec:
        if self.starts is not None and len(self.starts) != self.count:
            raise ValueError(f"starts lists {len(self.starts)} cells for count {self.count}")
        return self


class FleetSpec(_Model):
    types: dict[str, AgvTypeSpec] = Field(default_factory=lambda: {"default": AgvTypeSpec()})
    agvs: list[AgvGroupSpec] = Field(min_length=1)

    @model_validator(mode="after")
    def _types_known(self) -> FleetSpec:
        for i, group in enumerate(self.agvs):
            if group.type not in self.types:
                raise ValueError(
                    f"agvs[{i}].type {group.type!r} is not one of {sorted(self.types)}")
        return self

    @property
    def size(self) -> int:
        return sum(g.count for g in self.agvs)
