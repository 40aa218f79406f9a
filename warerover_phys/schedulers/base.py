"""The scheduler interface."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from ..world import World

__all__ = ["Assignment", "Scheduler"]


@dataclass(frozen=True, slots=True)
class Assignment:
    """Send ``agv`` to fetch ``shelf`` and serve ``orders`` with it."""

    agv: int
    shelf: int
    orders: tuple[int, ...]


@runtime_checkable
class Scheduler(Protocol):
    """Called every tick with the whole world; returns trips for idle AGVs.

    The scheduler must not change the world: the loop applies its assignments.
    """

    name: str

    def assign(self, world: World, rng: np.random.Generator) -> list[Assignment]: ...
