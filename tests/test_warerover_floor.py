"""WareRover's own floor (layouts/warerover_basic.yaml, warerover_hetero.yaml) and the
scenario options that carry its rules: orders.requeue_after_ticks, orders.stations_by_size,
tasks.stops, scheduler.ta_cost."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from warerover_phys import load_scenario, run_episode
from warerover_phys.config import OrdersSpec
from warerover_phys.errors import ScenarioError
from warerover_phys.orders import OrderStream
from warerover_phys.sim import Simulation
from warerover_phys.world import OrderStatus, World

REPO = Path(__file__).resolve().parents[1]
BASIC = REPO / "layouts" / "warerover_basic.yaml"
HETERO = REPO / "layouts" / "warerover_hetero.yaml"
DATA = REPO.parent / "shared" / "data" / "warerover"
"""The converted facts of WareRover's maps, where this checkout has them."""


def _ascii(world: World) -> list[str]:
    return world.layout.to_ascii()


def test_basic_floor_is_warerovers():
    sc = load_scenario(BASIC)
    w = World.build(sc)
    lay = w.layout
    assert (lay.cols, lay.rows) == (20, 15) and not lay.obstacles.any()
    assert len(lay.shelves) == 32 and all(s.size == 1 and len(s.skus) == 1
                                          for s in lay.shelves)
    assert sorted(sku for s in lay.shelves for sku in s.skus) == list(range(32))
    assert {s.anchor for s in lay.shelves} == {(r, c) for r in (5, 6, 9, 10)
                                              for c in (*range(4, 8), *range(11, 15))}
    assert lay.stations == ((8, 0), (8, 19), (11, 0), (11, 19), (14, 4), (14, 7), (14, 11),
                            (14, 14))
    assert [w.cell(a.home) for a in w.agvs] == [(0, c) for c in range(1, 20, 2)]
    assert sc.orders.pattern == "oneshot" and sc.orders.oneshot.count == 100
    assert (sc.tasks.pick_ticks, sc.tasks.handover_ticks, sc.tasks.place_ticks) == (0, 0, 0)
    assert sc.orders.requeue_after_ticks == 30 and sc.max_ticks == 700
    assert all(a.ticks_per_move == 1 for a in w.agvs)
    # an empty AGV drives under shelves, a loaded one does not
    assert w.graphs.get(1, False).distance((5, 3), (5, 8)) == 5       # straight under
    assert w.graphs.get(1, True).distance((5, 3), (5, 8)) > 5         # around the block
    if (DATA / "basic_map.txt").is_file():
        want = (DATA / "basic_map.txt").read_text().split()
        assert _ascii(w) == want


def test_hetero_floor_is_warerovers():
    sc = load_scenario(HETERO)
    w = World.build(sc)
    lay = w.layout
    assert (lay.cols, lay.rows) == (20, 15)
    sizes = Counter(s.size for s in lay.shelves)
    assert sizes == {1: 16, 2: 4}
    assert sorted(s.anchor for s in lay.shelves if s.size == 2) == [(5, 11), (5, 13), (9, 11),
                                                                     (9, 13)]
    assert len(lay.stations) == 8 and lay.stations[1] == (8, 18) and lay.stations[3] == (11, 18)
    assert [a.k for a in w.agvs] == [1] * 6 + [2] * 2
    assert [w.cell(a.home) for a in w.agvs][6:] == [(0, 13), (0, 16)]
    assert sc.orders.large_fraction == 0.3
    if (DATA / "hetero_map.txt").is_file():
        want = (DATA / "hetero_map.txt").read_text().split()
        got = _ascii(w)
        # 2x2 stations are written as their anchor cell here; everything else matches
        for (r, c) in [(8, 19), (9, 18), (9, 19), (11, 19), (12, 18), (12, 19)]:
            want[r] = want[r][:c] + "." + want[r][c + 1:]
        assert got == want


@pytest.mark.parametrize("path", [BASIC, HETERO])
def test_short_runs_finish(path):
    for seed in (42, 43):
        m = run_episode(load_scenario(path), seed=seed).metrics
        assert m["success_rate"] == 1.0 and m["orders_generated"] == 100
        assert m["ticks"] < 700


def test_requeue_and_blind_trips_complete_each_order_once():
    res = run_episode(load_scenario(BASIC), seed=42)
    ev = res.events
    requeued = [e for e in ev if e["event"] == "order_requeued"]
    assert requeued and res.world.requeued == len(requeued)
    assert any(e["event"] == "blind_trip_ended" for e in ev)
    done = Counter(e["order"] for e in ev if e["event"] == "order_completed")
    assert sorted(done) == list(range(100)) and set(done.values()) == {1}
    # a re-queued order is assigned more than 30 ticks after its previous assignment
    last = {}
    for e in ev:
        if e["event"] == "order_assigned":
            last[e["order"]] = e["tick"]
        if e["event"] == "order_requeued":
            assert e["tick"] - last[e["order"]] > 30


def test_requeue_off_keeps_the_order_on_its_trip():
    sc = load_scenario(BASIC, [("orders.requeue_after_ticks", None)])
    res = run_episode(sc, seed=42)
    assert res.world.requeued == 0 and not res.world.blind_trips
    assert not any(e["event"] in ("order_requeued", "blind_trip_ended") for e in res.events)


def test_blind_trip_lifts_and_hands_over_nothing():
    sim = Simulation(load_scenario(BASIC, [("orders.requeue_after_ticks", 1)]), seed=42)
    w = sim.world
    while not w.blind_trips and not sim.done:
        sim.step()
    assert w.blind_trips
    tid = next(iter(w.blind_trips))
    trip = w.trips[tid]
    agv = w.agvs[trip.agv]
    owner = w.shelf_busy[trip.shelf]
    assert owner != tid                       # the shelf stays the first trip's
    while tid in w.blind_trips and not sim.done:
        assert not agv.loaded
        sim.step()
        assert w.shelf_busy.get(trip.shelf, owner) != tid
    assert not any(e["event"] == "order_completed" and e["agv"] == agv.id
                   and w.tick - 1 <= e["tick"] and e.get("trip") == tid for e in w.events)


def test_stops_by_order_id_and_ta_trip_cost():
    w = World.build(load_scenario(BASIC))
    from warerover_phys.orders import Order
    from warerover_phys.world import _stops_by_order_id
    sku = w.layout.shelves[0].skus[0]
    w.add_orders([Order(0, 0, sku, 5, 1), Order(1, 0, sku, 5, 1), Order(2, 0, sku, 2, 1),
                  Order(3, 0, sku, 5, 1)])
    assert _stops_by_order_id(w, [3, 0, 2, 1]) == [5, 2, 5]
    trip = w.start_trip(0, 0, [0, 1, 2, 3])
    assert trip.stops == (5, 2, 5)
    near = World.build(load_scenario(BASIC, [("tasks.stops", "nearest")]))
    near.add_orders([Order(0, 0, sku, 5, 1), Order(1, 0, sku, 2, 1), Order(2, 0, sku, 5, 1)])
    assert sorted(near.start_trip(0, 0, [0, 1, 2]).stops) == [2, 5]


def test_ta_cost_trip_prefers_small_groups():
    from warerover_phys.orders import Order
    from warerover_phys.schedulers import make_scheduler
    from warerover_phys.schedulers.base import SchedulerView

    def pick(cost: str) -> int:
        sc = load_scenario(BASIC, [("scheduler.ta_cost", cost), ("fleet.agvs.0.count", 1),
                                   ("fleet.agvs.0.starts", [[0, 1]])])
        w = World.build(sc)
        # SKU of shelf 0 (near): one order; SKU of shelf 31 (far): four orders, one station
        near, far = w.layout.shelves[0].skus[0], w.layout.shelves[31].skus[0]
        w.add_orders([Order(0, 0, near, 0, 1)] +
                     [Order(i, 0, far, 3, 1) for i in range(1, 5)])
        (a,) = make_scheduler(sc.scheduler).assign(SchedulerView(w), w.rngs["scheduler"])
        return a.shelf

    assert pick("trip") == 0 and pick("per_order") == 31


@given(seed=st.integers(0, 2**32 - 1))
def test_stations_by_size(seed):
    spec = OrdersSpec(pattern="oneshot", oneshot={"count": 60}, large_fraction=0.5,
                      stations_by_size={1: [0, 2, 4], 2: [1, 3]})
    orders = OrderStream(spec, [1] * 6 + [2] * 2, 8, np.random.default_rng(seed)).arrivals(0)
    for o in orders:
        assert o.station in ((0, 2, 4) if o.size == 1 else (1, 3))


def test_stations_by_size_names_a_real_station(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(HETERO.read_text().replace("2: [1, 3]", "2: [1, 9]").replace(
        "maps/", str(REPO / "layouts" / "maps") + "/"))
    with pytest.raises(ScenarioError) as info:
        World.build(load_scenario(bad))
    text = str(info.value)
    assert "bad.yaml" in text and "orders.stations_by_size" in text and "9" in text


def test_defaults_leave_statuses_alone():
    """Without the options a picked order is IN_PROGRESS, as before."""
    sim = Simulation(load_scenario(REPO / "layouts" / "paper_homogeneous.yaml"), seed=1)
    w = sim.world
    while not any(e["event"] == "shelf_picked" for e in w.events):
        sim.step()
    trip = w.trips[next(e["trip"] for e in w.events if e["event"] == "shelf_picked")]
    assert all(w.status[o] in (OrderStatus.IN_PROGRESS, OrderStatus.COMPLETED)
               for o in trip.orders)
