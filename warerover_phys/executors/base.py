"""The executor interface."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    from ..world import World

__all__ = ["Executor", "StepReport"]


@dataclass
class StepReport:
    blocked: list[int] = field(default_factory=list)
    """AGVs that wanted to move but could not (their next cells were held)."""
    collisions: int = 0
    """Overlaps or swaps that happened anyway (0 for any valid plan); in physics, AGV-AGV
    contacts that began during the tick."""
    replan: list[int] = field(default_factory=list)
    """AGVs the executor asks the loop to replan now (dependency deadlock, deviation)."""


@runtime_checkable
class Executor(Protocol):
    name: str

    def step(self, world: World) -> StepReport:
        """Advance every AGV from ``world.tick`` to ``world.tick + 1`` (sets ``agv.pos``)."""
        ...
