"""The scheduler checker, :func:`check_scheduler`."""

from __future__ import annotations

from typing import Any

import numpy as np

from .common import (
    ConformanceReport,
    _check_members,
    _check_name,
    _Checker,
    _factory,
    _label,
    _new,
    _sched_world,
    _short,
)


def check_scheduler(target: Any, spec: Any = None, *, seed: int = 0) -> ConformanceReport:
    """Run a scheduler through fixed cases; raise :class:`ConformanceError` on the first
    problem, else return the passed checks.

    >>> check_scheduler("ta").passed[-1]
    'determinism'
    """
    ck = _Checker("scheduler", _label(target))
    factory = _factory("scheduler", target, spec, ck)
    sched = _new(factory, ck)
    _check_members("scheduler", sched, ck)
    _check_name(sched, ck)
    for case in SCHED_CASES:
        ck.case = case.__name__.removeprefix("_case_")
        _assign_checked(sched, case, seed, ck)
    ck.case = "busy"
    fresh = _new(factory, ck)
    runs = [_assign_checked(s, _case_busy, seed, ck) for s in (fresh, fresh, sched)]
    if runs.count(runs[0]) != len(runs):
        first, again = runs[0], next(r for r in runs if r != runs[0])
        ck.fail("determinism", f"the same world and seed {seed} gave {first} and then {again} "
                "(a fresh scheduler, called twice, and the one that ran the other cases)",
                "draw randomness only from the rng argument (never the random module, "
                "time or hash(set)), keep no state between calls on self, and iterate in a "
                "fixed order (sorted ids)")
    ck.ok("determinism")
    return ck.report


def _order(world, sku: int, station: int) -> None:
    from ..orders import Order

    oid = len(world.orders)
    world.add_orders([Order(oid, world.tick, sku, station, 1)])


def _case_fresh(seed: int):
    """Every AGV idle, four pending orders over the three SKUs."""
    w = _sched_world(seed)
    for sku, st in ((0, 0), (1, 1), (2, 0), (0, 1)):
        _order(w, sku, st)
    return w, True


def _case_busy(seed: int):
    """AGV 0 is on a trip with the only shelf of SKU 2; orders wait for SKUs 0, 1 and 2."""
    w = _sched_world(seed)
    for sku, st in ((2, 0), (2, 1), (0, 0), (1, 1), (0, 1)):
        _order(w, sku, st)
    shelf = w.layout.sku_shelves[2][0]
    w.start_trip(0, shelf, [0])
    return w, True


def _case_no_orders(seed: int):
    """Nothing pending: the scheduler must return []."""
    return _sched_world(seed), False


def _case_all_busy(seed: int):
    """Every AGV is on a trip: nothing to assign."""
    w = _sched_world(seed)
    for sku in (0, 1, 2, 0, 1):
        _order(w, sku, 0)
    for agv, sku in ((0, 0), (1, 1), (2, 2)):
        w.start_trip(agv, w.layout.sku_shelves[sku][0], [sku])
    return w, False


SCHED_CASES = (_case_fresh, _case_busy, _case_no_orders, _case_all_busy)


def _world_snapshot(w) -> tuple:
    """Everything a scheduler must not change, as comparable values."""
    return (repr(w.agvs), repr(w.orders), dict(w.status), sorted(w._pending),
            dict(w.shelf_busy), repr(w.trips), len(w.events), w.tick, w._next_trip,
            {k: repr(g.bit_generator.state) for k, g in w.rngs.items()})


SNAPSHOT_PARTS = ("AGVs", "orders", "order statuses", "pending orders", "busy shelves",
                  "trips", "event log", "tick", "trip counter", "random generators")


def _assign_checked(sched, case, seed: int, ck: _Checker) -> list:
    from ..schedulers.base import Assignment, SchedulerView

    world, can_assign = case(seed)
    before = _world_snapshot(world)
    try:
        out = sched.assign(SchedulerView(world), np.random.default_rng(seed))
    except Exception as err:  # noqa: BLE001 - a plug-in's assign is user code
        ck.fail("assign runs", f"assign() raised {type(err).__name__}: {err}",
                "return [] when there is nothing to do; read the world only through the "
                "SchedulerView's methods")
    ck.ok("assign runs")
    after = _world_snapshot(world)
    changed = [p for p, a, b in zip(SNAPSHOT_PARTS, before, after, strict=True) if a != b]
    if changed:
        ck.fail("read-only world", f"assign() changed the world's {', '.join(changed)}",
                "never write the AGVs, orders or world the view hands out (they are the "
                "world's own objects); return Assignments and let the loop apply them")
    ck.ok("read-only world")
    fix = "return a list of warerover_phys.schedulers.Assignment(agv, shelf, orders)"
    if not isinstance(out, list):
        ck.fail("return type", f"assign() returned {type(out).__name__} {_short(out)}", fix)
    bad = next((a for a in out if not isinstance(a, Assignment)), None)
    if bad is not None:
        ck.fail("return type", f"assign() returned a list holding {type(bad).__name__} "
                f"{_short(bad)}", fix)
    ck.ok("return type")
    _check_assignments(world, out, ck)
    if can_assign and not out:
        ck.fail("progress", "it assigned nothing although idle AGVs, free shelves and pending "
                "orders they can serve were there", "assign at least one trip when one is "
                "possible (an AGV idles until the scheduler gives it a trip)")
    if not can_assign and out:
        ck.fail("assignments", f"it assigned {out} with nothing assignable",
                "assign only idle AGVs (view.idle_agvs()) to pending orders")
    ck.ok("progress")
    return out


def _check_assignments(world, out: list, ck: _Checker) -> None:
    from ..world import AgvState, OrderStatus, can_carry

    agvs, shelves, orders = set(), set(), set()
    for a in out:
        where = f"Assignment{(a.agv, a.shelf, a.orders)}"
        if not all(isinstance(x, int | np.integer) for x in (a.agv, a.shelf)) or \
                not isinstance(a.orders, tuple) or not a.orders or \
                not all(isinstance(o, int | np.integer) for o in a.orders):
            ck.fail("assignments", f"{where} is malformed", "use int AGV and shelf ids and a "
                    "non-empty tuple of int order ids")
        if not 0 <= a.agv < len(world.agvs) or world.agvs[a.agv].state != AgvState.IDLE:
            state = world.agvs[a.agv].state.name if 0 <= a.agv < len(world.agvs) else "unknown"
            ck.fail("assignments", f"{where} gives a trip to AGV {a.agv}, which is {state}, "
                    "not IDLE", "take AGVs from view.idle_agvs() only")
        if not 0 <= a.shelf < len(world.layout.shelves) or a.shelf in world.shelf_busy:
            ck.fail("assignments", f"{where} uses shelf {a.shelf}, which is "
                    + ("in use by another trip" if a.shelf in world.shelf_busy else "unknown"),
                    "take shelves from view.free_shelves_for(order.sku, agv)")
        shelf = world.layout.shelves[a.shelf]
        if not can_carry(world.agvs[a.agv].spec, shelf.size):
            ck.fail("assignments", f"{where}: AGV {a.agv} cannot carry shelf {a.shelf} "
                    f"(size {shelf.size})", "take shelves from view.free_shelves_for(sku, agv)")
        for oid in a.orders:
            if world.status.get(oid) != OrderStatus.PENDING:
                status = world.status.get(oid)
                ck.fail("assignments", f"{where} serves order {oid}, which is "
                        f"{status.name if status is not None else 'unknown'}, not PENDING",
                        "take orders from view.pending_orders()")
            if world.orders[oid].sku not in shelf.skus:
                ck.fail("assignments", f"{where}: shelf {a.shelf} holds SKUs {shelf.skus}, not "
                        f"order {oid}'s SKU {world.orders[oid].sku}",
                        "pick the shelf with view.free_shelves_for(order.sku, agv)")
        for what, seen, ids in (("AGV", agvs, [a.agv]), ("shelf", shelves, [a.shelf]),
                                ("order", orders, list(a.orders))):
            for i in ids:
                if i in seen:
                    ck.fail("assignments", f"{what} {i} appears in two assignments (or twice "
                            f"in {where})", f"keep a set of taken {what} ids while assigning")
                seen.add(i)
    ck.ok("assignments")
