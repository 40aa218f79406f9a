"""RD, random dispatch: each idle AGV takes one random pending order it can serve and a
random free shelf that holds its SKU. The baseline of the paper."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .base import Assignment

if TYPE_CHECKING:
    from ..config import SchedulerSpec
    from .base import SchedulerView

__all__ = ["RandomDispatch"]


class RandomDispatch:
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
