"""The array schedulers (TA, RD) give the same assignments as the Python ones they replaced.

Every tick of whole episodes, the shipped scheduler and the reference copy of the old one
(``reference_schedulers.py``) are asked on the same world with the same generator state:
the assignments must be equal and the generator must end in the same state (RD's draws).
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from reference_schedulers import ReferenceRD, ReferenceTA

from warerover_phys import load_scenario, scenario_from_dict
from warerover_phys.faults.model import _close_cells
from warerover_phys.orders import Order
from warerover_phys.planning.graph import UNREACHABLE, GraphSet
from warerover_phys.schedulers import RandomDispatch, TaskAssignment
from warerover_phys.schedulers.base import SchedulerView
from warerover_phys.sim import Simulation
from warerover_phys.world import AgvState, World

LAYOUTS = Path(__file__).resolve().parents[2] / "layouts"
PAPER = ("paper_homogeneous", "paper_heterogeneous", "paper_fault", "warerover_basic",
         "warerover_hetero")


class Twin:
    """Asks the shipped scheduler and the reference on the same view and generator state,
    checks they agree, and returns the shipped one's answer."""

    def __init__(self, spec) -> None:
        pair = {"ta": (TaskAssignment, ReferenceTA), "rd": (RandomDispatch, ReferenceRD)}
        new, ref = pair[spec.name]
        self.name = spec.name
        self.new, self.ref = new(spec), ref(spec)
        self.calls = self.assigned = 0

    def assign(self, view, rng):
        probe = copy.deepcopy(rng)
        want = self.ref.assign(view, probe)
        got = self.new.assign(view, rng)
        assert got == want, f"tick {view.tick}: {got} != reference {want}"
        assert rng.bit_generator.state == probe.bit_generator.state, \
            f"tick {view.tick}: the generator was drawn differently"
        self.calls += 1
        self.assigned += len(got)
        return got


def run_twin(path: Path, scheduler: str, seed: int, overrides=(), ticks: int | None = None):
    sc = load_scenario(path, [("scheduler.name", scheduler), *overrides])
    sim = Simulation(sc, seed=seed)
    twin = sim.scheduler = Twin(sc.scheduler)
    limit = sc.max_ticks if ticks is None else ticks
    while not sim.done and sim.world.tick < limit:
        sim.step()
    return twin, sim


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("scheduler", ["ta", "rd"])
@pytest.mark.parametrize("layout", PAPER)
def test_same_assignments_as_reference_over_episodes(layout, scheduler, seed):
    twin, sim = run_twin(LAYOUTS / f"{layout}.yaml", scheduler, seed)
    assert twin.assigned > 0 and twin.calls == sim.world.tick


@pytest.mark.parametrize("seed", [3, 4])
@pytest.mark.parametrize("scheduler", ["ta", "rd"])
def test_same_assignments_with_more_orders_and_trip_cost(scheduler, seed):
    """A longer order list (groups of several orders, shelves out on trips) and TA's
    ``trip`` cost, on the heterogeneous floor (1x1 and 2x2 AGVs, two shelf sizes)."""
    twin, _ = run_twin(LAYOUTS / "paper_heterogeneous.yaml", scheduler, seed,
                       [("orders.oneshot.count", 80), ("scheduler.ta_cost", "trip"),
                        ("scheduler.candidate_shelves", 2)], ticks=250)
    assert twin.assigned > 20


@pytest.mark.parametrize("scheduler", ["ta", "rd"])
def test_same_assignments_on_the_industrial_floor(scheduler):
    """1,680 shelves, 2,000 SKUs, a constant order stream, lifelong PIBT."""
    twin, _ = run_twin(LAYOUTS / "industrial.yaml", scheduler, 5,
                       [("fleet.agvs.0.count", 120), ("orders.constant.batch", 60)], ticks=40)
    assert twin.assigned > 60


TWO_TYPES = [
    ("fleet.types.slow", {"footprint": 1, "body_m": [0.7, 0.7], "max_speed_mps": 0.5,
                          "max_accel_mps2": 1.0, "max_turn_rate_radps": 2.5}),
    ("fleet.agvs", [{"type": "agv", "count": 100}, {"type": "slow", "count": 60}]),
]


@pytest.mark.parametrize("scheduler", ["ta", "rd"])
def test_same_assignments_with_many_shelves_per_sku_and_two_types(scheduler):
    """150 SKUs on 1,680 shelves (about 45 shelves each: the Manhattan cut to
    ``candidate_shelves`` and its ties matter) and two AGV types that carry the same
    shelves (a shelf one type takes is gone for the other)."""
    twin, sim = run_twin(LAYOUTS / "industrial.yaml", scheduler, 6,
                         [*TWO_TYPES, ("layout.inventory.num_skus", 150),
                          ("orders.constant.batch", 40)], ticks=40)
    types = {sim.world.agvs[a["agv"]].type_name for a in sim.world.events
             if a["event"] == "trip_started"}
    assert twin.assigned > 60 and types == {"agv", "slow"}


def ask_both(w: World, scheduler: str, seed: int = 0):
    """The shipped scheduler's and the reference's assignments on ``w``, checked equal."""
    twin = Twin(w.scenario.scheduler.model_copy(update={"name": scheduler}))
    return twin.assign(SchedulerView(w), np.random.default_rng(seed))


# The AGV parks at (2, 9); a shelf at each end holds SKU 0; the station is at (0, 9).
CORRIDOR_GRID = [".........R..........",
                 "....................",
                 "S........P.........S",
                 "...................."]


def test_closed_cells_start_new_trip_costs():
    """Closing cells (a corridor) replaces the motion graphs: the trip costs start over
    exactly then, and the choice of shelf follows the new distances (left shelf 9 + 11
    moves, right 10 + 12; with column 4 closed below row 0 the left one takes 13 + 11)."""
    w = World.build(scenario_from_dict({
        "layout": {"grid": CORRIDOR_GRID, "inventory": {"num_skus": 1, "skus_per_shelf": 1}},
        "fleet": {"agvs": [{"count": 1}]}, "scheduler": {"candidate_shelves": 2}}))
    w.add_orders([Order(0, 0, 0, 0, 1)])
    left = next(s.id for s in w.layout.shelves if s.anchor == (2, 0))
    costs = w.trip_costs()
    assert [a.shelf for a in ask_both(w, "ta")] == [left]
    assert w.trip_costs() is costs  # same graphs, same cache
    mask = np.zeros((w.layout.rows, w.layout.cols), dtype=bool)
    mask[1:, 4] = True
    w.graphs = GraphSet(w.layout, closed=mask)
    assert [a.shelf for a in ask_both(w, "ta")] != [left]
    assert w.trip_costs() is not costs
    assert w.trip_costs().to_shelves(1, np.array([w.agvs[0].node]), np.array([left])) == 13
    mask[:, 15] = mask[:, 4] = True  # walled in: no shelf can be reached, no trip
    w.graphs = GraphSet(w.layout, closed=mask)
    assert ask_both(w, "ta") == []
    w.graphs = GraphSet(w.layout)  # the corridors close again
    assert [a.shelf for a in ask_both(w, "ta")] == [left]


def test_closing_a_real_corridor_renews_the_costs():
    """The fault model's own cell closing (``faults.model._close_cells``) swaps the graphs."""
    w = World.build(load_scenario(LAYOUTS / "paper_fault.yaml"))
    costs = w.trip_costs()
    _close_cells(w)
    assert w.trip_costs() is not costs


@pytest.mark.parametrize("seed", range(6))
def test_rd_a_shelf_taken_by_one_type_is_gone_for_the_other(seed):
    """One shelf holds the SKU, two AGV types can carry it, two orders wait: whichever AGV
    draws first takes the shelf; the other has no option left (and draws nothing)."""
    w = World.build(scenario_from_dict({
        "layout": {"grid": ["R..................R", "....................",
                            "P.S................P"],
                   "inventory": {"num_skus": 1, "skus_per_shelf": 1}},
        "fleet": {"types": {"a": {"footprint": 1}, "b": {"footprint": 1, "max_speed_mps": 0.5}},
                  "agvs": [{"type": "a", "count": 1}, {"type": "b", "count": 1}]}}))
    w.add_orders([Order(0, 0, 0, 0, 1), Order(1, 0, 0, 1, 1)])
    assert len(ask_both(w, "rd", seed)) == 1


@pytest.mark.parametrize("closed", [False, True])
def test_trip_costs_equal_the_worlds_trip_distances(closed):
    """Both footprints of the heterogeneous floor, with and without a closed area: the
    unloaded part for AGV cells (any cell, also ones the graph does not expand) x every
    shelf, and whole trips, equal ``MotionGraph.distance`` and ``World.trip_distance``."""
    w = World.build(load_scenario(LAYOUTS / "paper_heterogeneous.yaml"))
    if closed:
        mask = np.zeros((w.layout.rows, w.layout.cols), dtype=bool)
        mask[3:6, 4:9] = True
        w.graphs = GraphSet(w.layout, closed=mask)
    costs = w.trip_costs()
    rng = np.random.default_rng(1)
    shelves = np.arange(len(w.layout.shelves))
    for k in (1, 2):
        graph = w.graphs.get(k, False)
        nodes = rng.choice(w.layout.rows * w.layout.cols, 40, replace=False)
        # Standing on a shelf's anchor, and in the last cell (no 2x2 AGV fits there).
        nodes = np.append(nodes, [*costs.anchor_node[:3], w.layout.rows * w.layout.cols - 1])
        assert k == 1 or not graph.expandable(int(nodes[-1]))
        got = costs.to_shelves(k, nodes, shelves)
        want = [[graph.distance(w.cell(int(n)), w.layout.shelves[s].anchor) for s in shelves]
                for n in nodes.tolist()]
        assert got.tolist() == want
    for agv in w.agvs:
        carry = costs.carry_mask(agv.type_name, agv.spec)
        ids = np.flatnonzero(carry)
        for stations in ((0,), (1, 0), (0, 1, 2)):
            stations = tuple(s for s in stations if s < len(w.layout.stations))
            j = np.zeros(len(ids), dtype=np.int64)
            legs = costs.legs(agv.k, j, ids, [stations])
            trips = costs.to_shelves(agv.k, np.array([agv.node]), ids)[0] + legs
            want = [w.trip_distance(agv, int(s), list(stations)) for s in ids]
            assert np.minimum(trips, UNREACHABLE).tolist() == np.minimum(want, UNREACHABLE) \
                .tolist()


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), orders=st.integers(1, 30), agvs=st.integers(1, 8),
       busy=st.integers(0, 4), candidates=st.integers(1, 4), per_trip=st.integers(1, 4),
       trip_cost=st.booleans(), requeue=st.booleans())
def test_same_assignments_on_random_worlds(seed, orders, agvs, busy, candidates, per_trip,
                                           trip_cost, requeue):
    """Random AGV cells, orders, shelves out on trips and scheduler settings on a floor
    with 1x1 and 2x2 AGVs: both schedulers agree with the reference."""
    rng = np.random.default_rng(seed)
    sc = load_scenario(LAYOUTS / "paper_heterogeneous.yaml", [
        ("scheduler.candidate_shelves", candidates), ("scheduler.max_orders_per_trip", per_trip),
        ("scheduler.ta_cost", "trip" if trip_cost else "per_order"),
        ("orders.requeue_after_ticks", 30 if requeue else None),
        ("layout.inventory.seed", seed)])
    w = World.build(sc)
    for agv in w.agvs:  # anywhere its unloaded graph lets it stand
        valid = np.flatnonzero(w.graphs.get(agv.k, False).valid.ravel())
        node = int(rng.choice(valid))
        agv.pos = (node, node)
    skus = sorted(w.layout.sku_shelves)
    w.add_orders([Order(i, 0, int(rng.choice(skus)), int(rng.integers(len(w.layout.stations))),
                        1) for i in range(orders)])
    for n, sid in enumerate(rng.choice(len(w.layout.shelves), busy, replace=False).tolist()):
        w.shelf_busy[sid] = 1000 + n
    for agv in rng.choice(len(w.agvs), len(w.agvs) - agvs if agvs < len(w.agvs) else 0,
                          replace=False).tolist():
        w.agvs[agv].state = AgvState.TO_SHELF  # not idle
    for name in ("ta", "rd"):
        ask_both(w, name, seed)


def test_bench_scheduler_runs_and_agrees(tmp_path):
    """tools/bench_scheduler.py on a small fleet: its table, JSON, and old == new."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "bench_scheduler", Path(__file__).resolve().parents[2] / "tools" / "bench_scheduler.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    out = tmp_path / "b.json"
    assert bench.main(["--agvs", "30", "--orders", "20", "--reps", "2", "--old-reps", "1",
                       "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert {(r["scheduler"], r["impl"]) for r in doc["rows"]} == {
        ("ta", "new"), ("ta", "old"), ("rd", "new"), ("rd", "old")}
    assert all(r["same_as_old"] for r in doc["rows"]) and doc["rows"][0]["assigned_mean"] > 0


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("scheduler", ["ta", "rd"])
def test_same_assignments_with_many_orders_and_frequent_failures(scheduler, seed):
    """150 orders and an AGV failure every few ticks: corridors open and close all the
    time, so the motion graphs (and the trip costs) are replaced again and again."""
    twin, sim = run_twin(LAYOUTS / "paper_fault.yaml", scheduler, seed,
                         [("orders.oneshot.count", 150), ("faults.random.prob_per_tick", 0.03),
                          ("faults.random.repair_ticks", 15)], ticks=600)
    assert twin.assigned > 30 and len(sim.world.corridor_log) > 20


def test_an_agv_that_reaches_no_shelf_is_no_candidate():
    """AGV 0 is walled in by closed cells; AGV 1 is near the right shelf. TA must cost AGV
    0 as infeasible (not as a long trip, which would pull AGV 1 to the left shelf to
    leave the cheaper-per-order right group to AGV 0)."""
    grid = [".........R..........",
            "....................",
            "S........P.........S",
            "..................P."]
    w = World.build(scenario_from_dict({
        "layout": {"grid": grid, "inventory": {"num_skus": 2, "skus_per_shelf": 1}},
        "fleet": {"agvs": [{"count": 2}]}}))
    left = next(s for s in w.layout.shelves if s.anchor == (2, 0))
    right = next(s for s in w.layout.shelves if s.anchor == (2, 19))
    w.add_orders([Order(0, 0, left.skus[0], 0, 1), Order(1, 0, right.skus[0], 0, 1),
                  Order(2, 0, right.skus[0], 0, 1)])
    walled = next(a for a in w.agvs if w.cell(a.node) == (2, 9))
    mask = np.zeros((w.layout.rows, w.layout.cols), dtype=bool)
    mask[1:4, 8:11] = True
    mask[2, 9] = False  # a ring of closed cells around it
    w.graphs = GraphSet(w.layout, closed=mask)
    out = ask_both(w, "ta")
    assert [(a.agv, a.shelf) for a in out] == [(1 - walled.id, right.id)]


def test_a_shelf_the_agv_cannot_reach_is_not_its_fallback():
    """Both shelves hold both SKUs; a closed area around the left shelf keeps AGVs out
    (though a loaded AGV could leave it for the station). Two orders
    (one per SKU, one per trip): the first trip takes the right shelf, the second AGV's
    only reachable option is gone, so it gets no trip (not the unreachable left shelf)."""
    grid = [".........R..........",
            "....................",
            "S........P.........S",
            "..................P."]
    w = World.build(scenario_from_dict({
        "layout": {"grid": grid, "inventory": {"num_skus": 2, "skus_per_shelf": 2}},
        "fleet": {"agvs": [{"count": 2}]},
        "scheduler": {"max_orders_per_trip": 1, "candidate_shelves": 2}}))
    right = next(s for s in w.layout.shelves if s.anchor == (2, 19))
    w.add_orders([Order(0, 0, 0, 0, 1), Order(1, 0, 1, 0, 1)])
    mask = np.zeros((w.layout.rows, w.layout.cols), dtype=bool)
    mask[1:4, 0:2] = True  # no way in; a loaded AGV inside may leave (to the station)
    w.graphs = GraphSet(w.layout, closed=mask)
    left = next(s for s in w.layout.shelves if s.anchor == (2, 0))
    assert w.trip_costs().legs(1, np.array([0]), np.array([left.id]), [(0,)])[0] < 20
    assert [a.shelf for a in ask_both(w, "ta")] == [right.id]
