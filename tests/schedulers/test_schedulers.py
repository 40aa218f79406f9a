"""TA and RD schedulers on small worlds."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

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


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 5), st.integers(0, 2)), min_size=1, max_size=6),
       st.integers(0, 1000))
def test_ta_matching_is_optimal(orders, seed):
    """Compare TA's AGV x SKU-group matching cost with brute force over all matchings."""
    w = World.build(scenario_from_dict({
        "layout": {"size": [8, 14], "shelf_blocks": [{"origin": [2, 3], "rows": 1, "cols": 6},
                                                    {"origin": [5, 3], "rows": 1, "cols": 6}],
                   "stations": [[0, 0], [7, 0], [0, 13]],
                   "parking": [{"origin": [7, 9], "cols": 3}],
                   "inventory": {"num_skus": 6, "skus_per_shelf": 1, "seed": seed}},
        "fleet": {"agvs": [{"count": 3}]}, "scheduler": {"max_orders_per_trip": 1}}))
    add(w, orders)
    ta = TaskAssignment(w.scenario.scheduler)
    out = ta.assign(w, np.random.default_rng(0))
    idle = w.idle_agvs()
    skus = sorted({o[0] for o in orders})
    first = {sku: [o for o in w.pending_orders() if o.sku == sku][:1] for sku in skus}

    def cost(agv, sku):  # the nearest candidate shelves by Manhattan distance, true trips
        r, c = w.cell(agv.node)
        near = sorted(w.free_shelves_for(sku, agv), key=lambda s: (
            abs(w.layout.shelves[s].anchor[0] - r) + abs(w.layout.shelves[s].anchor[1] - c), s))
        trips = [w.trip_distance(agv, s, [first[sku][0].station])
                 for s in near[:w.scenario.scheduler.candidate_shelves]]
        return min(trips, default=None)

    table = {(a.id, s): cost(a, s) for a in idle for s in skus}
    got = sum(table[(a.agv, w.orders[a.orders[0]].sku)] for a in out)
    best = None
    n = min(len(idle), len(skus))
    for agvs in itertools.permutations([a.id for a in idle], n):
        for groups in itertools.permutations(skus, n):
            pairs = list(zip(agvs, groups, strict=True))
            if any(table[p] is None for p in pairs):
                continue
            total = sum(table[p] for p in pairs)
            best = total if best is None else min(best, total)
    assert len(out) == n
    assert got == best
