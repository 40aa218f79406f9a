"""TA, task assignment: pending orders are grouped by SKU, every (idle AGV, group) pair is
costed by true path distances (AGV -> shelf unloaded, shelf -> stations loaded), and the
Hungarian method (scipy's ``linear_sum_assignment``) picks the cheapest matching. A trip
then also serves other pending orders whose SKUs sit on the same shelf, up to
``max_orders_per_trip``.

The costs of all idle AGVs x candidate shelves come from cached distance tables in one numpy
pass (:mod:`.costs`): 1,000 idle AGVs x 200 pending orders on the 1,680-shelf industrial
floor in milliseconds, where costing each pair in Python took seconds."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..planning.graph import UNREACHABLE
from .base import Assignment

if TYPE_CHECKING:
    from ..config import SchedulerSpec
    from ..orders import Order
    from ..world import Agv
    from .base import SchedulerView
    from .costs import OptionTable

__all__ = ["TaskAssignment"]

INFEASIBLE = 1e12


class TaskAssignment:
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
        stations = [tuple(sorted({o.station for o in groups[sku][:cap]})) for sku in skus]
        # Per (AGV, SKU): the nearest candidate shelves by Manhattan distance, costed by
        # their trips (AGV -> shelf unloaded, shelf -> the group's stations loaded).
        table = world.trip_costs().options(idle, skus, stations, world.usable_shelves(),
                                           self.spec.candidate_shelves)
        if self.spec.ta_cost == "trip":
            per = table.best.astype(np.float64)
        else:  # cheaper per order served: a trip for 3 orders beats one for 1
            per = table.best / np.minimum([len(groups[sku]) for sku in skus], cap)[None, :]
        cost = np.where(table.best < UNREACHABLE, per, INFEASIBLE)
        from scipy.optimize import linear_sum_assignment  # slow to import

        rows, cols = linear_sum_assignment(cost)
        return self._commit(world, idle, pending, groups, skus, cost, table,
                            sorted(zip(rows.tolist(), cols.tolist(), strict=True),
                                   key=lambda ij: (cost[ij], ij)))

    def _commit(self, world: SchedulerView, idle: list[Agv], pending: list[Order],
                groups: dict[int, list[Order]], skus: list[int], cost: np.ndarray,
                table: OptionTable, pairs: list[tuple[int, int]]) -> list[Assignment]:
        """Trips for the matched pairs, cheapest first: the first option shelf nobody took,
        the SKU's orders, then other pending orders whose SKUs sit on that shelf (by id)."""
        cap = self.spec.max_orders_per_trip
        out: list[Assignment] = []
        taken_orders: set[int] = set()
        taken_shelves: set[int] = set()
        options = table.ranked([ij for ij in pairs if cost[ij] < INFEASIBLE])
        for i, j in pairs:
            if cost[i, j] >= INFEASIBLE:
                continue
            shelf = next((s for s in options[(i, j)] if s not in taken_shelves), None)
            if shelf is None:
                continue
            orders = [o.id for o in groups[skus[j]] if o.id not in taken_orders][:cap]
            if not orders:
                continue
            if len(orders) < cap:
                chosen = set(orders)
                on_shelf = sorted(o.id for sku in set(world.layout.shelves[shelf].skus)
                                   for o in groups.get(sku, ()))
                for oid in on_shelf:  # the pending orders of the shelf's SKUs, by id
                    if len(orders) >= cap:
                        break
                    if oid not in taken_orders and oid not in chosen:
                        orders.append(oid)
                        chosen.add(oid)
            taken_orders.update(orders)
            taken_shelves.add(shelf)
            out.append(Assignment(idle[i].id, shelf, tuple(orders)))
        return out
