"""The scheduler interface."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from ..layout import Layout
    from ..orders import Order
    from ..world import Agv, World
    from .costs import TripCosts

__all__ = ["Assignment", "Scheduler", "SchedulerView"]


@dataclass(frozen=True, slots=True)
class Assignment:
    """Send ``agv`` to fetch ``shelf`` and serve ``orders`` with it."""

    agv: int
    shelf: int
    orders: tuple[int, ...]


class SchedulerView:
    """What a scheduler may read of the world: queries only, no way to change it.

    The AGV and order objects it hands out are the world's own (copying them every tick
    would cost more than the scheduling); they are read-only by contract, and
    :func:`warerover_phys.testing.check_scheduler` catches a scheduler that writes them.
    """

    __slots__ = ("_world",)

    def __init__(self, world: World) -> None:
        object.__setattr__(self, "_world", world)

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError("SchedulerView is read-only: return Assignments instead")

    @property
    def tick(self) -> int:
        return self._world.tick

    @property
    def layout(self) -> Layout:
        return self._world.layout

    @property
    def agvs(self) -> tuple[Agv, ...]:
        return tuple(self._world.agvs)

    @property
    def orders(self) -> Mapping[int, Order]:
        return MappingProxyType(self._world.orders)

    @property
    def status(self) -> Mapping[int, int]:
        """Order id -> ``world.OrderStatus``."""
        return MappingProxyType(self._world.status)

    @property
    def shelf_busy(self) -> Mapping[int, int]:
        """Shelf id -> id of the trip that uses it."""
        return MappingProxyType(self._world.shelf_busy)

    @property
    def errand_rule(self) -> str | None:
        """With errand tasks (``orders.pattern: errands``), the rule that assigns them
        (``orders.errands.assign``: ``roundrobin``, ``greedy`` or ``pool``); else None."""
        w = self._world
        return w.scenario.orders.errands.assign if w.errands else None

    def pending_orders(self) -> list[Order]:
        """Pending orders, by id."""
        return self._world.pending_orders()

    def idle_agvs(self) -> list[Agv]:
        return self._world.idle_agvs()

    def free_shelves_for(self, sku: int, agv: Agv) -> list[int]:
        """Shelves holding ``sku`` that ``agv`` can carry and nobody is using."""
        return self._world.free_shelves_for(sku, agv)

    def usable_shelves(self) -> np.ndarray:
        """Bool per shelf id: :meth:`free_shelves_for` may list it (nobody is using it, or
        any shelf with ``orders.requeue_after_ticks``); carrying is checked apart."""
        return self._world.usable_shelves()

    def trip_costs(self) -> TripCosts:
        """Trip lengths as arrays, for many AGVs and shelves at once
        (:class:`~warerover_phys.schedulers.costs.TripCosts`: the same lengths as
        :meth:`trip_distance`, kept per motion-graph set)."""
        return self._world.trip_costs()

    def cell(self, node: int) -> tuple[int, int]:
        return self._world.cell(node)

    def node(self, cell: tuple[int, int]) -> int:
        return self._world.node(cell)

    def station_anchor(self, station: int, k: int) -> int:
        return self._world.station_anchor(station, k)

    def trip_distance(self, agv: Agv, shelf: int, stations: list[int]) -> int:
        """Path length of a trip: to the shelf unloaded, then loaded to each station."""
        return self._world.trip_distance(agv, shelf, stations)


@runtime_checkable
class Scheduler(Protocol):
    """Called every tick with a read-only :class:`SchedulerView`; returns trips for idle AGVs.

    The scheduler never changes the world: the loop checks and applies its assignments.
    """

    name: str

    def assign(self, world: SchedulerView, rng: np.random.Generator) -> list[Assignment]: ...
