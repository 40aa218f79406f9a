"""The TA and RD schedulers as they were before they became array code (issue 30, item 2):
the reference the array versions must agree with, assignment for assignment and draw for
draw (``test_array_schedulers.py``, ``tools/bench_scheduler.py``).

Each (idle AGV, SKU) pair is costed in Python through ``view.trip_distance``; kept verbatim
apart from the class names. Do not "fix" it: it is the oracle.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from warerover_phys.planning.graph import UNREACHABLE
from warerover_phys.schedulers.base import Assignment

if TYPE_CHECKING:
    from warerover_phys.config import SchedulerSpec
    from warerover_phys.orders import Order
    from warerover_phys.schedulers.base import SchedulerView
    from warerover_phys.world import Agv

__all__ = ["ReferenceTA", "ReferenceRD"]

INFEASIBLE = 1e12


class ReferenceTA:
    name = "ta"

    def __init__(self, spec: SchedulerSpec) -> None:
        self.spec = spec

    def assign(self, world: SchedulerView, rng: np.random.Generator) -> list[Assignment]:
        pending = world.pending_orders()
        idle = world.idle_agvs()
        if not pending or not idle:
            return []
        groups: dict[int, list[Order]] = {}
        for order in pending:  # by id
            groups.setdefault(order.sku, []).append(order)
        skus = sorted(groups)
        cap = self.spec.max_orders_per_trip
        cost = np.full((len(idle), len(skus)), INFEASIBLE)
        best: dict[tuple[int, int], list[tuple[int, int]]] = {}
        for i, agv in enumerate(idle):
            for j, sku in enumerate(skus):
                options = self._shelf_options(world, agv, sku, groups[sku][:cap])
                if options:
                    best[(i, j)] = options
                    # Cheaper per order served: a trip for 3 orders beats one for 1.
                    cost[i, j] = options[0][0] if self.spec.ta_cost == "trip" else \
                        options[0][0] / min(len(groups[sku]), cap)
        from scipy.optimize import linear_sum_assignment  # slow to import

        rows, cols = linear_sum_assignment(cost)
        out: list[Assignment] = []
        taken_orders: set[int] = set()
        taken_shelves: set[int] = set()
        for i, j in sorted(zip(rows.tolist(), cols.tolist(), strict=True),
                           key=lambda ij: (cost[ij], ij)):
            if cost[i, j] >= INFEASIBLE:
                continue
            shelf = next((s for _, s in best[(i, j)] if s not in taken_shelves), None)
            if shelf is None:
                continue
            orders = [o.id for o in groups[skus[j]] if o.id not in taken_orders][:cap]
            if not orders:
                continue
            on_shelf = set(world.layout.shelves[shelf].skus)
            for order in pending:  # by id
                if len(orders) >= cap:
                    break
                if order.sku in on_shelf and order.id not in taken_orders \
                        and order.id not in orders:
                    orders.append(order.id)
            taken_orders.update(orders)
            taken_shelves.add(shelf)
            out.append(Assignment(idle[i].id, shelf, tuple(orders)))
        return out

    def _shelf_options(self, world: SchedulerView, agv: Agv, sku: int,
                       orders: list[Order]) -> list[tuple[int, int]]:
        """(trip length, shelf) for the nearest free shelves holding ``sku``, best first."""
        shelves = world.free_shelves_for(sku, agv)
        if not shelves:
            return []
        r, c = world.cell(agv.node)
        layout = world.layout
        shelves.sort(key=lambda s: (abs(layout.shelves[s].anchor[0] - r)
                                    + abs(layout.shelves[s].anchor[1] - c), s))
        stations = sorted({o.station for o in orders})
        options = []
        for sid in shelves[: self.spec.candidate_shelves]:
            d = world.trip_distance(agv, sid, stations)
            if d < UNREACHABLE:
                options.append((d, sid))
        options.sort()
        return options


class ReferenceRD:
    name = "rd"

    def __init__(self, spec: SchedulerSpec) -> None:
        self.spec = spec

    def assign(self, world: SchedulerView, rng: np.random.Generator) -> list[Assignment]:
        pending = world.pending_orders()
        idle = world.idle_agvs()
        if not pending or not idle:
            return []
        out: list[Assignment] = []
        taken_orders: set[int] = set()
        taken_shelves: set[int] = set()
        for i in rng.permutation(len(idle)):
            agv = idle[int(i)]
            options = []
            for order in pending:
                if order.id in taken_orders:
                    continue
                shelves = [s for s in world.free_shelves_for(order.sku, agv)
                           if s not in taken_shelves]
                if shelves:
                    options.append((order, shelves))
            if not options:
                continue
            order, shelves = options[int(rng.integers(len(options)))]
            shelf = shelves[int(rng.integers(len(shelves)))]
            taken_orders.add(order.id)
            taken_shelves.add(shelf)
            out.append(Assignment(agv.id, shelf, (order.id,)))
        return out
