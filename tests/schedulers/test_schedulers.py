"""TA and RD schedulers on small worlds."""

from __future__ import annotations

import numpy as np

from warerover_phys import scenario_from_dict
from warerover_phys.orders import Order
from warerover_phys.schedulers import RandomDispatch, TaskAssignment
from warerover_phys.world import World

# Two shelves far apart; AGV 0 parks next to the left one, AGV 1 next to the right one.
GRID = ["R..................R",
        "....................",
        "P.S..............S.P"]


def make_world(scheduler: str = "ta", per_trip: int = 4) -> World:
    return World.build(scenario_from_dict({
        "layout": {"grid": GRID, "inventory": {"num_skus": 2, "skus_per_shelf": 1}},
        "fleet": {"agvs": [{"count": 2}]},
        "scheduler": {"name": scheduler, "max_orders_per_trip": per_trip}}))


def add(w: World, orders: list[tuple[int, int]]) -> None:
    """Orders as (sku, station)."""
    base = len(w.orders)
    w.add_orders([Order(base + i, 0, sku, st, 1) for i, (sku, st) in enumerate(orders)])


def sku_on(w: World, col: int) -> int:
    shelf = next(s for s in w.layout.shelves if s.anchor[1] == col)
    return shelf.skus[0]


def test_ta_sends_each_agv_to_its_nearer_shelf():
    w = make_world()
    left, right = sku_on(w, 2), sku_on(w, 17)
    add(w, [(right, 1), (left, 0)])
    out = TaskAssignment(w.scenario.scheduler).assign(w, np.random.default_rng(0))
    by_agv = {a.agv: a for a in out}
    assert w.layout.shelves[by_agv[0].shelf].anchor == (2, 2)  # AGV 0 parks at (2, 0)
    assert w.layout.shelves[by_agv[1].shelf].anchor == (2, 17)


def test_ta_batches_orders_of_one_shelf_into_one_trip():
    w = make_world(per_trip=3)
    left = sku_on(w, 2)
    add(w, [(left, 0), (left, 1), (left, 0), (left, 1)])
    out = TaskAssignment(w.scenario.scheduler).assign(w, np.random.default_rng(0))
    assert len(out) == 1 and len(out[0].orders) == 3  # capped at max_orders_per_trip
    trip = w.start_trip(out[0].agv, out[0].shelf, list(out[0].orders))
    assert sorted(trip.stops) == [0, 1]  # two stations, one trip


def test_rd_gives_one_random_order_per_idle_agv():
    w = make_world("rd")
    left = sku_on(w, 2)
    add(w, [(left, 0), (left, 1), (left, 0)])
    picks = set()
    for seed in range(20):
        out = RandomDispatch(w.scenario.scheduler).assign(w, np.random.default_rng(seed))
        assert len(out) == 1 and len(out[0].orders) == 1  # one shelf holds the SKU
        picks.add(out[0].orders[0])
    assert len(picks) > 1


def test_schedulers_do_not_change_the_world():
    for name, cls in (("ta", TaskAssignment), ("rd", RandomDispatch)):
        w = make_world(name)
        add(w, [(0, 0), (1, 1)])
        before = (dict(w.status), dict(w.shelf_busy), [a.state for a in w.agvs])
        cls(w.scenario.scheduler).assign(w, np.random.default_rng(0))
        assert before == (dict(w.status), dict(w.shelf_busy), [a.state for a in w.agvs])
