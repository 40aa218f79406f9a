"""Types shared by :mod:`.reorder` (the decisions) and :mod:`.reorder_milp` (the program):
a candidate switch with its estimated effect, and what the program reads of the deciding
:class:`~.reorder.Reorderer`. In a module of their own so that neither of the two imports
the other for its types."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from .adg import ActionGraph
    from .switch import Group, SwitchableGraph

__all__ = ["Estimate", "Decider"]


@dataclass(frozen=True)
class Estimate:
    """A candidate switch with its estimated effect (seconds)."""

    group: Group
    wait_s: float
    """How long the waiting AGV would wait without the switch."""
    costs_s: dict[int, float]
    """Per AGV it passes: how long that AGV would wait for it with the switch."""
    times: dict[int, tuple[list[float], list[float]]]
    """Per AGV of the group: estimated start and finish times of its next actions."""
    behind: dict[int, int]
    """Per AGV of the group: the AGVs waiting on it (directly or down a chain): they win
    or lose as it does."""
    brake_s: float = 0.0
    """A driving candidate (:meth:`~.reorder.Reorderer.approaching`) that would wait:
    the time stopping and starting again would cost it, ``min(wait, speed /
    acceleration)`` (0 for a standing one)."""

    @property
    def cost_s(self) -> float:
        return sum(self.costs_s.values())

    @property
    def gain_s(self) -> float:
        """The estimated seconds won by the fleet: the waiting AGV's wait (and, driving,
        its stop) less the costs to the AGVs it passes, each times itself and the AGVs
        waiting on it."""
        b = self.behind
        return (self.wait_s + self.brake_s) * (1 + b.get(self.group.second, 0)) - sum(
            c * (1 + b.get(a, 0)) for a, c in self.costs_s.items())


class Decider(Protocol):
    """What :mod:`.reorder_milp` reads of the :class:`~.reorder.Reorderer` that calls it."""

    graph: SwitchableGraph
    adg: ActionGraph
    horizon: int
    margin_s: float
    node_limit: int
    time_limit_s: float | None
    wait_depth: int
    milp_band_s: float | None
    milp_max_vars: int | None
    milp_solves: int
    milp_fallbacks: int
    milp_clear: int
    milp_large: int

    def worth(self, e: Estimate) -> bool: ...

    def ready_s(self, a: int, t: float, depth: int = 0
                ) -> tuple[float, tuple[int, int] | None, bool]: ...

    def times(self, a: int, upto: int, t: float, depth: int = 0
              ) -> tuple[list[float], list[float]]: ...
