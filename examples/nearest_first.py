"""Nearest first: the oldest pending order first, served by the idle AGV with the shortest
trip to a free shelf that holds it; the trip also serves the next oldest orders for the
same shelf, up to ``max_orders_per_trip``.

A scheduler plug-in (``assign(world, rng) -> list[Assignment]``):

    scheduler: {name: "examples.nearest_first:NearestFirst", params: {max_orders_per_trip: 2}}

Run ``python -m examples.nearest_first`` to check it and run one episode with it.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from warerover_phys.planning.graph import UNREACHABLE
from warerover_phys.schedulers import Assignment

__all__ = ["NearestFirst"]


class NearestFirst:
    name = "nearest-first"

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid", frozen=True)  # misspelt keys are errors

        max_orders_per_trip: int = Field(2, ge=1)
        """Pending orders one shelf trip may serve (the oldest first)."""

    def __init__(self, spec, params: Params) -> None:  # the scenario's SchedulerSpec
        self.params = params

    def assign(self, world, rng) -> list[Assignment]:
        idle = list(world.idle_agvs())
        pending = sorted(world.pending_orders(), key=lambda o: (o.tick, o.id))
        taken_orders: set[int] = set()
        taken_shelves: set[int] = set()
        out = []
        for order in pending:
            if not idle:
                break
            if order.id in taken_orders:
                continue
            # (trip length, AGV id, shelf): the nearest AGV and shelf, ties by id.
            options = [(world.trip_distance(agv, shelf, [order.station]), agv.id, shelf)
                       for agv in idle for shelf in world.free_shelves_for(order.sku, agv)
                       if shelf not in taken_shelves]
            options = [o for o in options if o[0] < UNREACHABLE]
            if not options:
                continue
            _, agv_id, shelf = min(options)
            on_shelf = set(world.layout.shelves[shelf].skus)
            orders = [o.id for o in pending
                      if o.sku in on_shelf and o.id not in taken_orders]
            orders = orders[:self.params.max_orders_per_trip]
            out.append(Assignment(agv_id, shelf, tuple(orders)))
            taken_orders.update(orders)
            taken_shelves.add(shelf)
            idle = [a for a in idle if a.id != agv_id]
        return out


def main() -> None:
    from warerover_phys import load_scenario, run_episode
    from warerover_phys.testing import check_scheduler

    print(check_scheduler(NearestFirst))
    scenario = load_scenario("layouts/paper_homogeneous.yaml", [
        ("scheduler.name", "examples.nearest_first:NearestFirst"),
        ("scheduler.params", {"max_orders_per_trip": 2})])
    metrics = run_episode(scenario, seed=1).metrics
    print({k: metrics[k] for k in ("success_rate", "throughput", "ticks")})


if __name__ == "__main__":
    main()
