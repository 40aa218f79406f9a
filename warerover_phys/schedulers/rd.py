"""RD, random dispatch: each idle AGV takes one random pending order it can serve and a
random free shelf that holds its SKU. The baseline of the paper.

The AGVs go in a random order; an AGV's options are the pending orders not yet taken whose
SKU is on some usable shelf it can carry that no earlier AGV took. Those are kept as counts
per SKU and AGV type (numpy arrays), so a call costs the draws, not idle AGVs x orders x
shelves in Python; the draws are the same as when every option list was built in full."""

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
        costs = world.trip_costs()
        usable = world.usable_shelves()
        sku_of = np.array([o.sku for o in pending], dtype=np.int64)
        skus, at = np.unique(sku_of, return_inverse=True)
        # Per AGV type: how many shelves it could take for each pending SKU.
        left: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for agv in idle:
            if agv.type_name not in left:
                ok = usable & costs.carry_mask(agv.type_name, agv.spec)
                j, _ = costs.sku_pairs(skus, ok)
                left[agv.type_name] = (ok, np.bincount(j, minlength=len(skus)))
        sku_index = {int(s): i for i, s in enumerate(skus.tolist())}
        open_order = np.ones(len(pending), dtype=bool)
        out: list[Assignment] = []
        taken_shelves: set[int] = set()
        done: set[str] = set()  # types with no options left (options only ever shrink)
        for i in rng.permutation(len(idle)):
            agv = idle[int(i)]
            if agv.type_name in done:
                continue
            ok, count = left[agv.type_name]
            options = np.flatnonzero(open_order & (count[at] > 0))
            if len(options) == 0:
                done.add(agv.type_name)
                if len(done) == len(left):
                    break  # the AGVs after this one draw nothing either
                continue
            pick = int(options[int(rng.integers(len(options)))])
            order = pending[pick]
            shelves = [s for s in world.free_shelves_for(order.sku, agv)
                       if s not in taken_shelves]
            shelf = shelves[int(rng.integers(len(shelves)))]
            open_order[pick] = False
            taken_shelves.add(shelf)
            for ok_t, count_t in left.values():  # the shelf is gone for every type
                if ok_t[shelf]:
                    for sku in set(world.layout.shelves[shelf].skus):
                        if sku in sku_index:
                            count_t[sku_index[sku]] -= 1
            out.append(Assignment(agv.id, shelf, (order.id,)))
        return out
