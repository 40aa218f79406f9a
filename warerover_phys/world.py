"""The live state of one episode: AGVs, shelves, orders and trips.

Schedulers read it whole; the loop in :mod:`warerover_phys.sim` changes it only through the
methods here, so the order and AGV life cycles are in one place:

- an order is exactly one of PENDING -> ASSIGNED -> IN_PROGRESS -> COMPLETED;
- an AGV runs the task chain IDLE -> TO_SHELF -> PICKING -> TO_STATION -> HANDOVER
  (-> TO_STATION -> HANDOVER ...) -> RETURNING -> PLACING -> IDLE; an IDLE AGV drives to its
  home parking spot and may be given a new trip on the way;
- with errand tasks (``orders.pattern: errands``, :mod:`warerover_phys.problems.errands`) an order is a
  list of cells, and its AGV runs IDLE -> ERRAND (one errand after the other, each done when
  it stands at rest on the errand's cell) -> IDLE; an IDLE AGV stays where it is (or drives
  home, ``orders.errands.idle``).
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .config import Scenario
from .errors import ScenarioError
from .faults.book import CorridorBook
from .fleet import (
    MOVING_STATES,
    STAGE_OF,
    WORK_STATES,
    Agv,
    AgvState,
    Cell,
    OrderStatus,
    Trip,
    _place_fleet,
    can_carry,
    check_layout,
    layout_cell,
)
from .layout import Layout, build_layout
from .orders import Order, OrderStream
from .planning.base import TimedPath
from .planning.graph import GraphSet
from .planning.reservation import ReservationTable

if TYPE_CHECKING:
    from .schedulers.costs import TripCosts

__all__ = ["AgvState", "OrderStatus", "Agv", "Trip", "World", "make_rngs", "WORK_STATES",
           "STAGE_OF", "MOVING_STATES", "can_carry", "check_layout", "layout_cell"]

RNG_STREAMS = ("orders", "scheduler", "planner", "faults", "delays")


def make_rngs(seed: int) -> dict[str, np.random.Generator]:
    """One child generator per consumer, all spawned from the episode's root seed."""
    children = np.random.SeedSequence(seed).spawn(len(RNG_STREAMS))
    return {name: np.random.default_rng(s) for name, s in zip(RNG_STREAMS, children, strict=True)}


@dataclass
class World:
    scenario: Scenario
    layout: Layout
    graphs: GraphSet
    agvs: list[Agv]
    stream: OrderStream
    rngs: dict[str, np.random.Generator]
    reservations: ReservationTable
    orders: dict[int, Order] = field(default_factory=dict)
    status: dict[int, OrderStatus] = field(default_factory=dict)
    completed_tick: dict[int, int] = field(default_factory=dict)
    shelf_busy: dict[int, int] = field(default_factory=dict)
    """Shelf id -> id of the trip that uses it."""
    trips: dict[int, Trip] = field(default_factory=dict)
    events: list[dict] = field(default_factory=list)
    tick: int = 0
    _next_trip: int = 0
    corridors: dict = field(default_factory=dict)
    """Open safety corridors, by id (``faults.corridors.Corridor``)."""
    corridor_book: CorridorBook = field(default_factory=CorridorBook)
    """Intrusion figures and the exit grants of AGVs caught inside corridors as they
    opened (``faults/intrusion_log.py``)."""
    fault_stats: dict[str, int] = field(default_factory=lambda: {
        "failures": 0, "down_ticks": 0, "corridor_intrusions": 0, "failure_replans": 0})
    corridor_log: list[dict] = field(default_factory=list)
    """Every corridor of the episode: id, AGV, open / close tick, polygon and protected zone
    (exterior rings in metres), rectangles and margin (m) and cells, for outputs and
    rendering."""
    delayed_orders: set[int] = field(default_factory=set)
    assigned_tick: dict[int, int] = field(default_factory=dict)
    """Order id -> tick of its latest assignment (``orders.requeue_after_ticks``)."""
    blind_trips: set[int] = field(default_factory=set)
    """Trips sent to a shelf another trip had out (``orders.requeue_after_ticks``): they
    lift nothing and hand over nothing."""
    requeued: int = 0
    """Orders sent back to pending by ``orders.requeue_after_ticks`` (counting repeats)."""
    _pending: set[int] = field(default_factory=set, repr=False)
    """Pending orders, by id (kept by ``_set_status``)."""
    _open: int = field(default=0, repr=False)
    """Orders not completed (kept by ``_set_status``): ``all_done`` without a scan."""

    # ------------------------------------------------------------------------- building

    @classmethod
    def build(cls, scenario: Scenario) -> World:
        src = scenario.source
        try:
            layout = build_layout(scenario.layout, fleet_size=scenario.fleet.size, file=src,
                                  name=scenario.name,
                                  errands=scenario.orders.pattern == "errands")
            graphs = GraphSet(layout)
            agvs = _place_fleet(scenario, layout, graphs)
            check_layout(scenario, layout, graphs, agvs)
            width = scenario.faults.corridor_width_m
            if width > min(layout.rows, layout.cols) * layout.cell_m:
                raise ScenarioError(f"safety corridors {width} m wide do not fit the "
                                    f"{layout.rows} x {layout.cols} cell map of "
                                    f"{layout.cell_m} m cells", field="faults.corridor_width_m",
                                    value=width)
        except ScenarioError as err:
            raise err.with_file(src) if src else err from None
        rngs = make_rngs(scenario.seed)
        if scenario.orders.pattern == "errands":
            from .problems.errands import ErrandStream

            stream = ErrandStream(scenario.orders.errands, layout.cols,
                                  graphs.get(1, False).valid.ravel(), len(agvs),
                                  rngs["orders"], scenario.base_dir, src)
        else:
            try:
                stream = OrderStream(scenario.orders, layout.sku_sizes, len(layout.stations),
                                     rngs["orders"])
            except ValueError as err:
                raise ScenarioError(str(err), file=src, field="orders.stations_by_size",
                                    value=scenario.orders.stations_by_size) from None
        res = ReservationTable(layout.cols)
        for agv in agvs:
            res.commit(TimedPath(agv.id, 0, (agv.pos,)), agv.k)
        return cls(scenario=scenario, layout=layout, graphs=graphs, agvs=agvs, stream=stream,
                   rngs=rngs, reservations=res)

    # ------------------------------------------------------------------------- queries

    def cell(self, node: int) -> Cell:
        return divmod(node, self.layout.cols)

    def node(self, cell: Cell) -> int:
        return cell[0] * self.layout.cols + cell[1]

    def pending_orders(self) -> list[Order]:
        """Pending orders, by id."""
        return [self.orders[i] for i in sorted(self._pending)]

    def idle_agvs(self) -> list[Agv]:
        return [a for a in self.agvs if a.state == AgvState.IDLE]

    def free_shelves_for(self, sku: int, agv: Agv) -> list[int]:
        """Shelves holding ``sku`` that ``agv`` can carry and nobody is using (with
        ``orders.requeue_after_ticks`` the shelves out on a trip follow, as WareRover never
        checks: a trip to one of them is blind)."""
        out, busy = [], []
        for sid in self.layout.sku_shelves.get(sku, ()):
            shelf = self.layout.shelves[sid]
            if can_carry(agv.spec, shelf.size):
                (busy if sid in self.shelf_busy else out).append(sid)
        if busy and self.scenario.orders.requeue_after_ticks is not None:
            out += busy
        return out

    def usable_shelves(self) -> np.ndarray:
        """Bool per shelf: :meth:`free_shelves_for` may list it (nobody is using it, or
        any shelf with ``orders.requeue_after_ticks``), whoever asks."""
        mask = np.ones(len(self.layout.shelves), dtype=bool)
        if self.scenario.orders.requeue_after_ticks is None and self.shelf_busy:
            mask[list(self.shelf_busy)] = False
        return mask

    def trip_costs(self) -> TripCosts:
        """Trip lengths as arrays (:class:`~warerover_phys.schedulers.costs.TripCosts`) on
        the current motion graphs: a new one whenever the graphs are replaced (corridors
        opening or closing), as :meth:`trip_distance` starts a new cache."""
        costs = self.__dict__.get("_trip_costs")
        if costs is None or costs.graphs is not self.graphs:
            from .schedulers.costs import TripCosts

            costs = self.__dict__["_trip_costs"] = TripCosts(self.layout, self.graphs,
                                                              self.station_anchor)
        return costs

    def keep_clear(self) -> np.ndarray:
        """Flat mask of the cells any AGV of the fleet covers while at a station, and the
        cells next to them: queues form away from the stations so they never block the
        way in or out."""
        mask = self.__dict__.get("_keep_clear")
        if mask is None:
            rows, cols = self.layout.rows, self.layout.cols
            grid = np.zeros((rows, cols), dtype=bool)
            for k in {a.k for a in self.agvs}:
                for st in range(len(self.layout.stations)):
                    r, c = self.cell(self.station_anchor(st, k))
                    grid[max(0, r - 1):r + k + 1, max(0, c - 1):c + k + 1] = True
            mask = grid.ravel()
            mask.setflags(write=False)
            self.__dict__["_keep_clear"] = mask
        return mask

    def station_anchor(self, station: int, k: int) -> int:
        """Anchor a loaded ``k x k`` AGV uses at ``station`` (depends on the layout only:
        closed corridor cells do not change which anchors are valid)."""
        cache = self.__dict__.setdefault("_station_anchor", {})
        node = cache.get((station, k))
        if node is None:
            anchor = self.graphs.get(k, True).goal_anchor(self.layout.stations[station])
            assert anchor is not None, "checked at load"
            node = cache[(station, k)] = self.node(anchor)
        return node

    @property
    def errands(self) -> bool:
        """Whether the work is errand tasks (``orders.pattern: errands``)."""
        return self.scenario.orders.pattern == "errands"

    def goal_of(self, agv: Agv) -> int | None:
        """Anchor node the AGV should drive to now (None while it works in place)."""
        if agv.state == AgvState.IDLE:
            if self.errands and self.scenario.orders.errands.idle == "stay":
                return agv.node
            return agv.home
        trip = agv.trip
        if agv.state == AgvState.ERRAND:
            assert trip is not None
            return trip.stops[trip.stop_idx]
        if agv.state in (AgvState.TO_SHELF, AgvState.RETURNING):
            assert trip is not None
            return self.node(self.layout.shelves[trip.shelf].anchor)
        if agv.state == AgvState.TO_STATION:
            assert trip is not None
            return self.station_anchor(trip.stops[trip.stop_idx], agv.k)
        return None

    def trip_distance(self, agv: Agv, shelf: int, stations: list[int]) -> int:
        """True path length of a trip: to the shelf unloaded, then loaded to each station
        (cached per motion-graph set: corridors opening or closing start a new cache)."""
        graphs, cache = self.__dict__.get("_trip_cache", (None, None))
        if graphs is not self.graphs or len(cache) > 200_000:
            cache = {}
            self.__dict__["_trip_cache"] = (self.graphs, cache)
        key = (agv.node, agv.k, shelf, tuple(stations))
        d = cache.get(key)
        if d is None:
            d = cache[key] = self._trip_distance(agv, shelf, stations)
        return d

    def _trip_distance(self, agv: Agv, shelf: int, stations: list[int]) -> int:
        anchor = self.layout.shelves[shelf].anchor
        d = self.graphs.get(agv.k, False).distance(self.cell(agv.node), anchor)
        loaded = self.graphs.get(agv.k, True, shelf)
        here = anchor
        for st in stations:
            target = self.cell(self.station_anchor(st, agv.k))
            d += loaded.distance(here, target)
            here = target
        return d

    def all_done(self) -> bool:
        # Arrivals of ticks < self.tick are in; none may come later.
        return self.tick > 0 and self.stream.exhausted(self.tick - 1) and self._open == 0

    # ------------------------------------------------------------------------- changes

    def _set_status(self, order_id: int, status: OrderStatus) -> None:
        """The one place order statuses change (keeps the pending set and the count of
        orders not completed in step)."""
        before = self.status.get(order_id)
        self._open += (status != OrderStatus.COMPLETED) - (
            before is not None and before != OrderStatus.COMPLETED)
        self.status[order_id] = status
        if status == OrderStatus.PENDING:
            self._pending.add(order_id)
        else:
            self._pending.discard(order_id)

    def log(self, event: str, **fields) -> None:
        self.events.append({"tick": self.tick, "event": event, **fields})

    def arrivals(self) -> list[Order]:
        """The orders (or errand tasks) that arrive at this tick."""
        if not self.errands:
            return self.stream.arrivals(self.tick)
        idle = [a.id for a in self.agvs if a.state == AgvState.IDLE]
        return self.stream.arrivals(self.tick, idle, len(self.status) - len(self.completed_tick))

    def add_orders(self, orders: list[Order]) -> None:
        for order in orders:
            if order.id in self.orders:
                raise ValueError(f"order {order.id} exists already")
            self.orders[order.id] = order
            self._set_status(order.id, OrderStatus.PENDING)
            if order.errands:
                self.log("order_created", order=order.id, errands=[
                    list(self.cell(e)) for e in order.errands])
            else:
                self.log("order_created", order=order.id, sku=order.sku,
                         station=order.station, size=order.size)

    def start_trip(self, agv_id: int, shelf: int, order_ids: list[int]) -> Trip:
        """Give an idle AGV a trip. The scheduler decides; this keeps the books straight.
        An errand task comes with ``shelf`` -1 and its one order (:meth:`_start_errands`)."""
        agv = self.agvs[agv_id]
        if agv.state != AgvState.IDLE:
            raise ValueError(f"AGV {agv_id} is not idle ({agv.state.name})")
        if shelf < 0 or self.errands:
            return self._start_errands(agv, shelf, order_ids)
        blind = shelf in self.shelf_busy
        if blind and self.scenario.orders.requeue_after_ticks is None:
            raise ValueError(f"shelf {shelf} is in use by trip {self.shelf_busy[shelf]}")
        shelf_skus = set(self.layout.shelves[shelf].skus)
        for oid in order_ids:
            if self.status.get(oid) != OrderStatus.PENDING:
                raise ValueError(f"order {oid} is not pending")
            if self.orders[oid].sku not in shelf_skus:
                raise ValueError(f"shelf {shelf} does not hold SKU of order {oid}")
        stations = _stop_order(self, agv, shelf, {self.orders[o].station for o in order_ids})
        if self.scenario.tasks.stops == "order_ids":
            stations = _stops_by_order_id(self, order_ids)
        trip = Trip(self._next_trip, agv_id, shelf, tuple(order_ids), tuple(stations))
        self._next_trip += 1
        self.trips[trip.id] = trip
        if blind:
            self.blind_trips.add(trip.id)
        else:
            self.shelf_busy[shelf] = trip.id
        for oid in order_ids:
            self._set_status(oid, OrderStatus.ASSIGNED)
            self.assigned_tick[oid] = self.tick
            self.log("order_assigned", order=oid, agv=agv_id, trip=trip.id, shelf=shelf)
        agv.trip = trip
        agv.state = AgvState.TO_SHELF
        self.log("trip_started", agv=agv_id, trip=trip.id, shelf=shelf,
                 orders=list(order_ids), stops=list(stations))
        return trip

    def _start_errands(self, agv: Agv, shelf: int, order_ids: list[int]) -> Trip:
        if shelf >= 0 or not self.errands or len(order_ids) != 1:
            raise ValueError("an errand task goes to one AGV alone, with shelf -1 (got shelf "
                             f"{shelf}, orders {list(order_ids)})")
        oid = order_ids[0]
        order = self.orders.get(oid)
        if order is None or self.status.get(oid) != OrderStatus.PENDING:
            raise ValueError(f"order {oid} is not pending")
        if order.for_agv is not None and order.for_agv != agv.id:
            raise ValueError(f"errand task {oid} was released for AGV {order.for_agv}, "
                             f"not {agv.id}")
        trip = Trip(self._next_trip, agv.id, -1, (oid,), order.errands)
        self._next_trip += 1
        self.trips[trip.id] = trip
        self._set_status(oid, OrderStatus.ASSIGNED)
        self.assigned_tick[oid] = self.tick
        self.log("order_assigned", order=oid, agv=agv.id, trip=trip.id)
        agv.trip = trip
        agv.state = AgvState.ERRAND
        return trip

    def _errand_done(self, agv: Agv) -> None:
        """The AGV stands at rest on its task's next errand cell: that errand is done (and
        the task with its last)."""
        trip = agv.trip
        assert trip is not None
        oid = trip.orders[0]
        trip.stop_idx += 1
        self.log("errand_done", agv=agv.id, order=oid, errands=trip.stop_idx,
                 cell=list(self.cell(agv.node)))
        if trip.stop_idx == 1:
            self._set_status(oid, OrderStatus.IN_PROGRESS)
        if trip.stop_idx < len(trip.stops):
            return
        self._set_status(oid, OrderStatus.COMPLETED)
        self.completed_tick[oid] = self.tick
        self.assigned_tick.pop(oid, None)
        self.log("order_completed", order=oid, agv=agv.id,
                 latency=self.tick - self.orders[oid].tick)
        agv.trip = None
        agv.state = AgvState.IDLE

    def advance_tasks(self, settled: Collection[int] | None = None) -> None:
        """Arrivals, work in place and hand-overs for the tick that just ended.

        A stage's work (pick, hand-over, place) starts only when the AGV stands on the
        stage's goal *and is at rest there*: its committed path has ended on the goal (a
        path that passes the goal and comes back later does not count) and, on physics, its
        body holds the goal pose within the executor's tolerance. ``settled`` is the set of
        AGVs the executor reports at rest (``StepReport.settled``); None: judged from the
        committed paths. The dwell counts down only while the AGV is at rest on its goal,
        and its events (``shelf_picked``, ``order_completed``, ``shelf_returned``,
        ``parked``) are logged at the tick the work completes there; ``work_started`` /
        ``work_done`` bracket every dwell for the validator
        (:func:`warerover_phys.validate.validate_dwells`)."""
        tasks = self.scenario.tasks
        stay = self.errands and self.scenario.orders.errands.idle == "stay"
        for agv in self.agvs:
            if agv.node != agv.home or not agv.standing:
                agv.parked = False
            if not agv.standing:
                continue
            if agv.state == AgvState.ERRAND:
                if agv.node == self.goal_of(agv) and self.at_rest(agv, settled):
                    self._errand_done(agv)
                continue
            if agv.state in WORK_STATES:
                if self.at_rest(agv, settled):
                    agv.dwell_left -= 1
                    if agv.dwell_left <= 0:
                        self._finish_work(agv)
                continue
            goal = self.goal_of(agv)
            if goal is None or agv.node != goal or not self.at_rest(agv, settled):
                continue
            if agv.state == AgvState.IDLE:
                if not agv.parked and agv.yield_goal is None and not stay:
                    agv.parked = True
                    self.log("parked", agv=agv.id, cell=list(self.cell(agv.node)))
                continue
            trip = agv.trip
            assert trip is not None
            if agv.state == AgvState.TO_SHELF:
                self._begin_work(agv, AgvState.PICKING, tasks.pick_ticks)
            elif agv.state == AgvState.TO_STATION:
                self._begin_work(agv, AgvState.HANDOVER, tasks.handover_ticks)
            elif agv.state == AgvState.RETURNING:
                self._begin_work(agv, AgvState.PLACING, tasks.place_ticks)
        if self.scenario.orders.requeue_after_ticks is not None:
            self._requeue_overdue(self.scenario.orders.requeue_after_ticks)

    def _requeue_overdue(self, after: int) -> None:
        """WareRover's order time-out: an order assigned more than ``after`` ticks ago and
        not handed over goes back to pending (it stays on its trip, which may still hand it
        over)."""
        for oid, since in list(self.assigned_tick.items()):
            if self.tick - since > after and self.status[oid] in (OrderStatus.ASSIGNED,
                                                                  OrderStatus.IN_PROGRESS):
                self._set_status(oid, OrderStatus.PENDING)
                del self.assigned_tick[oid]
                self.requeued += 1
                self.log("order_requeued", order=oid, assigned_tick=since)

    def at_rest(self, agv: Agv, settled: Collection[int] | None = None) -> bool:
        """Whether ``agv`` stands still at the end of its committed path: per the executor's
        report (``settled``) if it gives one, else from the path: every state from where the
        AGV is on it now (``tick - delay``) to its end is standing on the AGV's cell."""
        if not agv.standing:
            return False
        if settled is not None:
            return agv.id in settled
        path = self.reservations.paths.get(agv.id)
        if path is None:
            return True
        here = (agv.node, agv.node)
        i = max(0, min(self.tick - agv.delay - path.start_tick, len(path.states) - 1))
        return all(s == here for s in path.states[i:])

    # ------------------------------------------------------------------------- failures

    def fail(self, agv_id: int, repair_at: int | None) -> Agv:
        """Stop an AGV where it is; it keeps its cargo. Orders of a trip whose shelf it has
        not lifted yet go back to PENDING (``faults.orders_of_failed: reassign``) or wait
        with it (``wait``); orders on a shelf it carries always wait for the repair."""
        agv = self._agv(agv_id)
        if agv.state == AgvState.FAILED:
            raise ValueError(f"AGV {agv_id} has already failed (since its repair is due at "
                             f"tick {agv.repair_at})")
        agv.resume_state, agv.repair_at = agv.state, repair_at
        agv.state = AgvState.FAILED
        agv.yield_goal = None
        self.fault_stats["failures"] += 1
        trip = agv.trip
        released: list[int] = []
        if trip is not None:
            self.delayed_orders.update(trip.orders)
            if not agv.loaded and agv.resume_state == AgvState.TO_SHELF and \
                    self.scenario.faults.orders_of_failed == "reassign":
                for oid in trip.orders:
                    if self.status[oid] != OrderStatus.COMPLETED:
                        self._set_status(oid, OrderStatus.PENDING)
                        released.append(oid)
                if trip.id in self.blind_trips:
                    self.blind_trips.discard(trip.id)
                else:
                    del self.shelf_busy[trip.shelf]
                agv.trip = None
                agv.resume_state = AgvState.IDLE
        self.log("agv_failed", agv=agv_id, repair_at=repair_at, orders_released=released,
                 loaded=agv.loaded)
        return agv

    def repair(self, agv_id: int) -> Agv:
        """Put a failed AGV back to work where it left off."""
        agv = self._agv(agv_id)
        if agv.state != AgvState.FAILED:
            raise ValueError(f"AGV {agv_id} is working ({agv.state.name}), not failed: "
                             "nothing to repair")
        assert agv.resume_state is not None
        agv.state, agv.resume_state, agv.repair_at = agv.resume_state, None, None
        agv.delay = agv.blocked_ticks = agv.plan_failures = 0
        agv.retry_at = self.tick
        self.log("agv_repaired", agv=agv_id)
        return agv

    def _agv(self, agv_id: int) -> Agv:
        if not isinstance(agv_id, int | np.integer) or not 0 <= agv_id < len(self.agvs):
            raise ValueError(f"unknown AGV id {agv_id!r} (the fleet has {len(self.agvs)}: ids "
                             f"0..{len(self.agvs) - 1})")
        return self.agvs[int(agv_id)]

    def _begin_work(self, agv: Agv, state: AgvState, ticks: int) -> None:
        agv.state = state
        agv.dwell_left = ticks
        self.log("work_started", agv=agv.id, stage=STAGE_OF[state],
                 cell=list(self.cell(agv.node)))
        if ticks <= 0:
            self._finish_work(agv)

    def _finish_work(self, agv: Agv) -> None:
        trip = agv.trip
        assert trip is not None
        self.log("work_done", agv=agv.id, stage=STAGE_OF[agv.state],
                 cell=list(self.cell(agv.node)))
        if trip.id in self.blind_trips:
            self._finish_blind(agv, trip)
            return
        if agv.state == AgvState.PICKING:
            agv.loaded = True
            for oid in trip.orders:
                if self.status[oid] == OrderStatus.ASSIGNED:   # not re-queued, not done
                    self._set_status(oid, OrderStatus.IN_PROGRESS)
            self.log("shelf_picked", agv=agv.id, trip=trip.id, shelf=trip.shelf)
            agv.state = AgvState.TO_STATION
        elif agv.state == AgvState.HANDOVER:
            station = trip.stops[trip.stop_idx]
            for oid in trip.orders:
                if self.orders[oid].station == station and \
                        self.status[oid] != OrderStatus.COMPLETED:
                    self._set_status(oid, OrderStatus.COMPLETED)
                    self.completed_tick[oid] = self.tick
                    self.log("order_completed", order=oid, agv=agv.id, station=station,
                             latency=self.tick - self.orders[oid].tick)
            trip.stop_idx += 1
            agv.state = AgvState.TO_STATION if trip.stop_idx < len(trip.stops) \
                else AgvState.RETURNING
        elif agv.state == AgvState.PLACING:
            agv.loaded = False
            del self.shelf_busy[trip.shelf]
            self.log("shelf_returned", agv=agv.id, trip=trip.id, shelf=trip.shelf)
            agv.trip = None
            agv.state = AgvState.IDLE

    def _finish_blind(self, agv: Agv, trip: Trip) -> None:
        """A blind trip (its shelf was out): the same stops, nothing lifted or handed over."""
        if agv.state == AgvState.PICKING:
            agv.state = AgvState.TO_STATION
        elif agv.state == AgvState.HANDOVER:
            trip.stop_idx += 1
            agv.state = AgvState.TO_STATION if trip.stop_idx < len(trip.stops) \
                else AgvState.RETURNING
        elif agv.state == AgvState.PLACING:
            self.blind_trips.discard(trip.id)
            self.log("blind_trip_ended", agv=agv.id, trip=trip.id, shelf=trip.shelf)
            agv.trip = None
            agv.state = AgvState.IDLE


def _stop_order(world: World, agv: Agv, shelf: int, stations: set[int]) -> list[int]:
    """Visit the trip's stations nearest-first (loaded distances), starting at the shelf."""
    graph = world.graphs.get(agv.k, True, shelf)
    here = world.layout.shelves[shelf].anchor
    left = sorted(stations)
    out = []
    while left:
        nxt = min(left, key=lambda s: (graph.distance(
            here, world.cell(world.station_anchor(s, agv.k))), s))
        out.append(nxt)
        left.remove(nxt)
        here = world.cell(world.station_anchor(nxt, agv.k))
    return out


def _stops_by_order_id(world: World, order_ids: list[int]) -> list[int]:
    """One stop per order, by order id; the same station twice in a row is one stop."""
    out: list[int] = []
    for oid in sorted(order_ids):
        station = world.orders[oid].station
        if not out or out[-1] != station:
            out.append(station)
    return out


# ----------------------------------------------------------------------------- fleet set-up


