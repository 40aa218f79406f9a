"""Conformance checkers for plug-ins, in the spirit of Gymnasium's ``check_env``.

Each checker builds a plug-in, runs it through small *fixed* cases on tiny worlds built in
code, and either returns a :class:`ConformanceReport` (the checks it passed) or raises a
:class:`ConformanceError` whose message says what is wrong and how to fix it:

- :func:`check_scheduler`: the Protocol's ``assign(world, rng)``; a list of
  :class:`~warerover_phys.schedulers.base.Assignment` for idle AGVs, free shelves holding
  the orders' SKUs and pending orders, none twice; the world left as it was; the same
  assignments for the same seed.
- :func:`check_planner`: ``plan(request)``, ``name``, ``replans_all``; a
  :class:`~warerover_phys.planning.base.PlanResult` with paths only for the asked AGVs that
  start at the request's tick where each AGV stands, use edges of its motion graph (its
  footprint and speed), and conflict neither with the committed reservations nor with each
  other (:func:`warerover_phys.validate.validate_states`); goals reached in easy cases; the
  request's agents and graphs untouched; the same result for the same seed. With
  ``rotations=True`` the same cases are planned rotation-aware (``planner.rotations``:
  every AGV has ``turn_ticks`` and a heading), and every returned path must also carry one
  heading per state, start facing the AGV's heading, and move only straight ahead with turns
  that take their ticks (:func:`warerover_phys.validate.validate_headings`).
- :func:`check_executor`: ``bind``, ``step``, ``remaining``, ``stop_short``, ``summary``,
  ``trajectory``; a :class:`~warerover_phys.executors.base.StepReport` every tick with a
  valid state for every AGV; fixed conflict-free plans followed to their ends in bounded
  time, with no collisions reported; the same states for the same seed; a JSON-serialisable
  ``summary()`` and a ``trajectory()`` that is None or a dict of numpy arrays.

A target is a registry name (``"astar"``, an entry point, ``"pkg.mod:Class"``), a plug-in
class (built as ``cls(spec)``, or ``cls(spec, params)`` with its ``Params`` model and the
spec's ``params``), a factory (called with the spec if it takes an argument, else with
none) or, for schedulers and planners, an instance.

>>> from warerover_phys.testing import check_planner
>>> report = check_planner("astar")
>>> report.kind, report.name, "determinism" in report.passed
('planner', 'astar', True)
"""

from __future__ import annotations

import inspect
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydantic import ValidationError

from .errors import ScenarioError, WareroverError

__all__ = ["ConformanceError", "ConformanceReport", "check_scheduler", "check_planner",
           "check_executor"]

# The members of each Protocol: name -> the arguments it is called with (besides self).
SIGNATURES: dict[str, dict[str, tuple[str, ...]]] = {
    "scheduler": {"assign": ("world", "rng")},
    "planner": {"plan": ("request",)},
    "executor": {"bind": ("setup",), "step": ("view",), "remaining": ("agv",),
                 "stop_short": ("agv", "cells", "view"), "summary": (), "trajectory": ()},
}


class ConformanceError(WareroverError):
    """A plug-in does not follow its Protocol. ``str(err)``: what is wrong, where, and how
    to fix it; ``check`` names the failed check (see :attr:`ConformanceReport.passed`)."""

    def __init__(self, kind: str, name: str, check: str, problem: str, fix: str,
                 case: str | None = None) -> None:
        self.kind, self.name, self.check, self.problem, self.fix, self.case = \
            kind, name, check, problem, fix, case
        where = f" in case {case!r}" if case else ""
        super().__init__(f"{kind} {name!r} fails check {check!r}{where}: {problem}. "
                         f"Fix: {fix}")


@dataclass
class ConformanceReport:
    """What a checker ran: the checks the plug-in passed, in order."""

    kind: str
    name: str
    passed: list[str] = field(default_factory=list)

    def __str__(self) -> str:
        return f"{self.kind} {self.name!r} passed {len(self.passed)} checks: " + \
            ", ".join(self.passed)


class _Checker:
    """Collects passed checks; ``fail`` raises the :class:`ConformanceError`."""

    def __init__(self, kind: str, name: str) -> None:
        self.report = ConformanceReport(kind, name)
        self.case: str | None = None

    def ok(self, check: str) -> None:
        if check not in self.report.passed:
            self.report.passed.append(check)

    def fail(self, check: str, problem: str, fix: str) -> None:
        raise ConformanceError(self.report.kind, self.report.name, check, problem, fix,
                               self.case)


# ================================================================================ building


def _spec_class(kind: str) -> type:
    from .config import ExecutorSpec, PlannerSpec, SchedulerSpec

    return {"scheduler": SchedulerSpec, "planner": PlannerSpec, "executor": ExecutorSpec}[kind]


def _label(target: Any) -> str:
    if isinstance(target, str):
        return target
    obj = target if isinstance(target, type) or inspect.isfunction(target) else type(target)
    return f"{obj.__module__}:{obj.__qualname__}"


def _is_instance(kind: str, target: Any) -> bool:
    return not isinstance(target, type) and not isinstance(target, str) and all(
        callable(getattr(target, m, None)) for m in SIGNATURES[kind])


def _factory(kind: str, target: Any, spec: Any, ck: _Checker) -> Callable[[], Any]:
    """A callable that builds a fresh plug-in instance for every call."""
    from . import registry

    spec_cls = _spec_class(kind)
    if isinstance(target, str):
        spec = spec_cls(name=target) if spec is None else spec.model_copy(update={"name": target})
        try:
            _check_params_model(registry.resolve(kind, target), ck)
        except ScenarioError as err:
            ck.fail("build", f"the name does not resolve ({err})",
                    f"give a built-in ({registry.builtin_names(kind)}), an installed entry point "
                    f"of {registry.GROUPS[kind]!r}, or 'package.module:ClassName' on sys.path")
        return lambda: registry.build(kind, spec)
    spec = spec if spec is not None else spec_cls()
    if isinstance(target, type):
        _check_params_model(target, ck)
        model = registry.params_of(target)
        if model is not None:
            try:
                params = model.model_validate(dict(spec.params))
            except ValidationError as err:
                e = err.errors()[0]
                where = ".".join([kind, "params", *(str(p) for p in e["loc"])])
                ck.fail("build", f"its Params model rejects the spec's params ({where}: "
                        f"{e['msg']}, got {e.get('input')!r})",
                        f"pass spec={spec_cls.__name__}(params={{...}}) with valid values, or "
                        "give every Params field a default")
            return lambda: target(spec, params)
        return lambda: target(spec)
    if _is_instance(kind, target):
        return lambda: target
    if callable(target):
        try:
            wants_spec = any(p.default is p.empty and p.kind in (p.POSITIONAL_ONLY,
                                                                 p.POSITIONAL_OR_KEYWORD)
                             for p in inspect.signature(target).parameters.values())
        except (TypeError, ValueError):
            wants_spec = True
        return (lambda: target(spec)) if wants_spec else target
    ck.fail("build", f"got {type(target).__name__} {target!r}, which is neither a name, a "
            "class, a factory nor an instance",
            f"pass the {kind}'s registry name, its class, or a callable returning an instance")
    raise AssertionError  # unreachable: fail raises


def _check_params_model(target: Any, ck: _Checker) -> None:
    """A ``Params`` model must be closed: a misspelt key in a scenario is an error."""
    from .registry import params_of

    model = params_of(target)
    if model is None:
        return
    if model.model_config.get("extra") != "forbid":
        ck.fail("params", f"its Params model {model.__name__} accepts unknown keys, so a "
                "misspelt key in a scenario's params would be silently ignored",
                "add model_config = pydantic.ConfigDict(extra='forbid', frozen=True) to it")
    ck.ok("params")


def _new(factory: Callable[[], Any], ck: _Checker) -> Any:
    try:
        return factory()
    except WareroverError as err:
        ck.fail("build", f"it could not be built: {err}", "fix the constructor or its params")
    except Exception as err:  # noqa: BLE001 - a plug-in's constructor is user code
        ck.fail("build", f"its constructor raised {type(err).__name__}: {err}",
                "build it as cls(spec) or, with a pydantic Params model, cls(spec, params)")


# ================================================================================ protocol


def _check_members(kind: str, obj: Any, ck: _Checker) -> None:
    """Every member of the Protocol is there and can be called with its arguments."""
    for member, args in SIGNATURES[kind].items():
        fn = getattr(obj, member, None)
        want = f"{member}(self{''.join(', ' + a for a in args)})"
        if fn is None:
            ck.fail("members", f"it has no {member}()", f"add a method {want}")
        if not callable(fn):
            ck.fail("members", f"{member} is a {type(fn).__name__}, not a method",
                    f"make it a method {want}")
        try:
            sig = inspect.signature(fn)
        except (TypeError, ValueError):
            continue  # a builtin or C callable: nothing to inspect
        params = list(sig.parameters.values())
        positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
        required = [p for p in positional if p.default is p.empty]
        required_kw = [p for p in params if p.kind == p.KEYWORD_ONLY and p.default is p.empty]
        takes_more = any(p.kind == p.VAR_POSITIONAL for p in params)
        if len(required) > len(args) or required_kw or (
                len(positional) < len(args) and not takes_more):
            ck.fail("members", f"{member}{sig} cannot be called as {want}",
                    f"give it exactly the arguments {want} (extra ones need defaults)")
    ck.ok("members")


def _check_name(obj: Any, ck: _Checker) -> None:
    name = getattr(obj, "name", None)
    if not isinstance(name, str) or not name:
        ck.fail("name", f"its name is {name!r}, not a non-empty str",
                f'add a class attribute such as name = "my-{ck.report.kind}" (metrics and '
                "logs show it)")
    ck.ok("name")


# ================================================================================ worlds

# Planner and executor cases: a 4 x 9 floor, two 1x1 AGVs and a slow 2x2 one (2 ticks/cell).
MIXED_GRID = ["P.......R",
              "P..S.....",
              "P........",
              "P........"]

# Scheduler cases: three 1x1 AGVs, three shelves with one SKU each, two stations.
SCHED_GRID = ["R.......R",
              ".........",
              "P.S.S.S.P",
              "P.......P"]


def _mixed_world(seed: int):
    from .config import scenario_from_dict
    from .world import World

    return World.build(scenario_from_dict({
        "seed": seed, "layout": {"grid": MIXED_GRID},
        "fleet": {"types": {"small": {},
                            "big": {"footprint": 2, "body_m": [1.4, 1.4], "max_speed_mps": 0.75}},
                  "agvs": [{"type": "small", "count": 2},
                           {"type": "big", "count": 1, "starts": [[2, 1]]}]}}))


def _sched_world(seed: int):
    from .config import scenario_from_dict
    from .world import World

    return World.build(scenario_from_dict({
        "seed": seed,
        "layout": {"grid": SCHED_GRID, "inventory": {"num_skus": 3, "skus_per_shelf": 1}},
        "fleet": {"agvs": [{"count": 3}]}}))


def _timed(world, agv: int, cells: list[tuple[int, int]], tick: int = 0):
    """A timed path through ``cells`` (repeat a cell to wait), slow moves spread over
    ``ticks_per_move`` ticks."""
    from .planning.paths import TimedPath

    m = world.agvs[agv].ticks_per_move
    nodes = [world.node(c) for c in cells]
    states = [(nodes[0], nodes[0])]
    for a, b in zip(nodes, nodes[1:], strict=False):
        if a != b:
            states += [(a, b)] * (m - 1)
        states.append((b, b))
    return TimedPath(agv, tick, tuple(states))


# ================================================================================ scheduler


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
    from .orders import Order

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
    from .schedulers.base import Assignment, SchedulerView

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
    from .world import AgvState, OrderStatus, can_carry

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


# ================================================================================ planner


@dataclass(frozen=True)
class _PlanCase:
    """Agents to plan from tick 0 (``goals``); other AGVs hold ``committed`` cell paths."""

    name: str
    goals: dict[int, tuple[int, int]]
    committed: dict[int, list[tuple[int, int]]] = field(default_factory=dict)
    easy: bool = True
    """Every asked AGV can reach its goal: it must."""
    all_agents: bool = True
    """Every AGV is asked (the only kind of request a ``replans_all`` planner gets)."""


PLAN_CASES = (
    _PlanCase("crossing", {0: (3, 7), 1: (0, 7), 2: (0, 5)}),
    _PlanCase("around a committed path", {1: (0, 7)},
              committed={0: [(0, 0), (0, 1), (0, 2), (0, 3), (0, 3), (0, 3), (0, 3), (0, 3),
                             (1, 3), (2, 3)],
                         2: [(2, 1)]}, all_agents=False),
    _PlanCase("goal held for good", {0: (0, 6)},
              committed={1: [(1, 0), (1, 1), (1, 2), (1, 3), (1, 4), (1, 5), (1, 6), (0, 6)],
                         2: [(2, 1)]}, easy=False, all_agents=False),
)
STEP_TICKS = 60
"""Ticks a ``replans_all`` planner gets, one call per tick, to bring the easy cases home."""


def check_planner(target: Any, spec: Any = None, *, seed: int = 0,
                  rotations: bool = False) -> ConformanceReport:
    """Run a planner through fixed cases; raise :class:`ConformanceError` on the first
    problem, else return the passed checks. ``rotations``: plan the cases rotation-aware
    (see the module doc).

    >>> check_planner("pibt").passed[:3]
    ['members', 'name', 'replans_all']
    """
    ck = _Checker("planner", _label(target))
    factory = _factory("planner", target, spec, ck)
    planner = _new(factory, ck)
    _check_members("planner", planner, ck)
    _check_name(planner, ck)
    if not isinstance(getattr(planner, "replans_all", None), bool):
        ck.fail("replans_all", f"replans_all is {getattr(planner, 'replans_all', None)!r}, "
                "not a bool", "add a class attribute replans_all = False (planned only for "
                "AGVs that need a new path) or True (every AGV, every tick)")
    ck.ok("replans_all")
    for case in PLAN_CASES:
        if planner.replans_all and not case.all_agents:
            continue
        ck.case = case.name
        _run_plan_case(planner, case, seed, ck, rotations)
    ck.case = PLAN_CASES[0].name
    fresh = _new(factory, ck)
    runs = [_run_plan_case(p, PLAN_CASES[0], seed, ck, rotations)
            for p in (fresh, fresh, planner)]
    if runs.count(runs[0]) != len(runs):
        first, again = runs[0], next(r for r in runs if r != runs[0])
        ck.fail("determinism", f"the same requests (seed {seed}) got different answers from "
                "a fresh planner, called twice, and the one that ran the other cases: "
                f"{_plan_difference(first, again)}",
                "draw randomness only from request.rng, keep no state between calls on self, "
                "and break ties by AGV id, not by set or dict order of unsorted keys")
    ck.ok("determinism")
    return ck.report


def _plan_difference(first: list, again: list) -> str:
    """Where two planner traces (tick, {agv: (start tick, states)}, failed) first differ."""
    for (t, paths_a, failed_a), (_, paths_b, failed_b) in zip(first, again, strict=False):
        for agv in sorted(paths_a.keys() | paths_b.keys()):
            a, b = paths_a.get(agv), paths_b.get(agv)
            if a != b:
                return (f"at tick {t}, AGV {agv}'s path is {_short(a and a[1], 120)} in one "
                        f"run and {_short(b and b[1], 120)} in the other")
        if failed_a != failed_b:
            return f"at tick {t}, failed is {failed_a} in one run and {failed_b} in the other"
    return f"one run made {len(first)} planning calls, the other {len(again)}"


def _short(value: Any, limit: int = 200) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _run_plan_case(planner, case: _PlanCase, seed: int, ck: _Checker,
                   rotations: bool = False) -> list:
    """Plan ``case`` (tick by tick for ``replans_all`` planners, committing the returned
    paths as the loop does) and check every call; return a trace of the results."""
    from .planning.base import AgentRequest
    from .planning.rotation import agent_turn_ticks
    from .planning.sweep import EAST, turn_fields
    from .planning.sweep_checks import heading_after

    world = _mixed_world(seed)
    res = world.reservations
    fields = turn_fields(world.layout, [a.spec for a in world.agvs])
    if fields:
        res.configure_turns({a: sw for a, (sw, _) in fields.items() if sw is not None},
                            world.layout.rows)
    for agv, cells in case.committed.items():
        res.commit(_timed(world, agv, cells), world.agvs[agv].k)
    goals = {agv: world.node(cell) for agv, cell in case.goals.items()}
    rng = np.random.default_rng(seed)
    n = len(world.agvs)
    trace = []
    for t in range(STEP_TICKS if planner.replans_all else 1):
        agents = []
        for agv in world.agvs:
            if agv.id not in goals:
                continue
            pos = res.paths[agv.id].state_at(t)
            turn = fields.get(agv.id)
            extra = {} if turn is None else {
                "heading": heading_after(res.paths[agv.id].states[:t - res.paths[agv.id]
                                                                   .start_tick + 1],
                                         world.layout.cols,
                                         res.heading_at_start(agv.id)),
                "sweep": turn[0], "no_turn": turn[1]}
            if rotations and turn is None:
                tt = agent_turn_ticks(agv.spec, world.scenario.tick_s)
                if tt is not None:
                    h = res.paths[agv.id].heading_at(t)
                    extra = {"heading": _DIRS[h] if h is not None else EAST, "turn_ticks": tt}
            agents.append(AgentRequest(agv=agv.id, start=pos[1], goal=goals[agv.id], k=agv.k,
                                       ticks_per_move=agv.ticks_per_move,
                                       priority=(t + (n - agv.id) / (n + 1),), **extra))
        if planner.replans_all and all(res.paths[a.agv].state_at(t) == (a.goal, a.goal)
                                       and res.paths[a.agv].end_tick <= t for a in agents):
            break
        result = _plan_once(planner, world, agents, t, rng, ck)
        trace.append((t, {a: (p.start_tick, p.states) for a, p in sorted(result.paths.items())},
                      sorted(result.failed)))
        for a in agents:  # commit as the loop does: returned paths, in request order
            if a.agv in result.paths:
                res.commit(result.paths[a.agv], a.k, a.heading)
    if case.easy:
        _check_goals(world, goals, planner.replans_all, ck)
    return trace


_DIRS = ((0, 1), (1, 0), (0, -1), (-1, 0))


def _plan_once(planner, world, agents: list, tick: int, rng, ck: _Checker):
    from .planning.base import PlanRequest, PlanResult

    graphs = world.graphs
    committed = world.reservations
    asked = list(agents)
    request = PlanRequest(tick=tick, agents=agents, graphs=graphs,
                          reservations=committed.copy(), rng=rng,
                          keep_clear=world.keep_clear())
    try:
        result = planner.plan(request)
    except Exception as err:  # noqa: BLE001 - a plug-in's plan is user code
        ck.fail("plan runs", f"plan() raised {type(err).__name__}: {err} at tick {tick}",
                "return PlanResult(failed=[agv, ...]) for AGVs you cannot plan instead of "
                "raising")
    ck.ok("plan runs")
    if not isinstance(result, PlanResult):
        ck.fail("return type", f"plan() returned {type(result).__name__} {_short(result)}",
                "return warerover_phys.planning.PlanResult(paths={agv: TimedPath(agv, "
                "request.tick, states)}, failed=[...])")
    if not isinstance(result.paths, dict) or not isinstance(result.failed, list):
        ck.fail("return type", f"PlanResult.paths is {type(result.paths).__name__} and .failed "
                f"is {type(result.failed).__name__}", "use a dict {agv id: TimedPath} and a "
                "list of AGV ids")
    ck.ok("return type")
    if agents != asked:
        ck.fail("request untouched", "plan() reordered or changed request.agents (the loop "
                "commits the returned paths in the request's order)",
                "sort a copy: for agent in sorted(request.agents, key=...)")
    _check_graphs(world, ck)
    ck.ok("request untouched")
    _check_paths(world, agents, result, tick, ck)
    return result


def _check_graphs(world, ck: _Checker) -> None:
    """The motion graphs match fresh ones built from the same layout."""
    from .planning.graph import MotionGraph

    graphs = world.graphs
    built = [((k, loaded, None), g) for (k, loaded), g in graphs._graphs.items()] + \
        [((k, True, shelf), g) for (k, shelf), g in graphs._per_shelf.items()]
    for (k, loaded, shelf), g in built:
        fresh = MotionGraph(world.layout, k, loaded, shelf, closed=graphs.closed)
        same = (np.array_equal(g.valid, fresh.valid) and np.array_equal(g.enterable,
                                                                        fresh.enterable)
                and g.neighbors == fresh.neighbors and g.expandable_flat == fresh.expandable_flat)
        if not same:
            ck.fail("request untouched", f"plan() changed the motion graph of {k}x{k} "
                    f"{'loaded' if loaded else 'unloaded'} AGVs (valid anchors or neighbours)",
                    "treat request.graphs as read-only (it is the world's own); copy what you "
                    "need to change")


def _check_paths(world, agents: list, result, tick: int, ck: _Checker) -> None:
    from .planning.paths import TimedPath
    from .validate import validate_states

    by_id = {a.agv: a for a in agents}
    committed = world.reservations
    stray = sorted(set(result.paths) - set(by_id))
    if stray:
        ck.fail("asked AGVs only", f"it returned paths for AGVs {stray}, which were not in "
                "request.agents", "return paths only for the AGVs of request.agents (the "
                "reservations hold the others' paths: read them, do not replan them)")
    ck.ok("asked AGVs only")
    for aid, path in result.paths.items():
        a = by_id[aid]
        if not isinstance(path, TimedPath) or path.agv != aid or not path.states:
            ck.fail("path format", f"paths[{aid}] is {_short(path)}",
                    f"map each AGV id to TimedPath(agv={aid}, start_tick=request.tick, "
                    "states=((node, node), ...)) with at least one state")
        bad = next((s for s in path.states if not (isinstance(s, tuple) and len(s) == 2 and all(
            type(x) is int for x in s))), None)
        if bad is not None:
            ck.fail("path format", f"AGV {aid}'s path has the state {bad!r} "
                    f"({type(bad).__name__} of {', '.join(type(x).__name__ for x in bad)})"
                    if isinstance(bad, tuple) else f"AGV {aid}'s path has the state {bad!r}",
                    "make every state a tuple of two Python ints (int(node)): numpy integers "
                    "do not serialise to paths.json")
        now = committed.paths[aid].state_at(tick)
        here = now if now[0] != now[1] and now[1] == a.start else (a.start, a.start)
        if path.start_tick != tick or path.states[0] != here:
            ck.fail("path start", f"AGV {aid}'s path starts at tick {path.start_tick} in state "
                    f"{path.states[0]}, but the request is for tick {tick} and the AGV is in "
                    f"state {here}", "start every path at request.tick with the state the AGV "
                    "is in: (agent.start, agent.start) when it stands")
        _check_edges(world, a, path, ck)
    ck.ok("path format")
    ck.ok("path start")
    ck.ok("motion graph")
    paths = {agv: committed.paths[agv] for agv in committed.paths}
    paths.update(result.paths)
    horizon = max(p.end_tick for p in paths.values()) + 2
    states = {agv: [p.state_at(t) for t in range(tick, horizon)] for agv, p in paths.items()}
    conflicts = validate_states(states, world.layout.obstacles,
                                sizes={a.id: a.k for a in world.agvs},
                                ticks_per_move={a.id: a.ticks_per_move for a in world.agvs},
                                start_tick=tick)
    if conflicts:
        c = conflicts[0]
        mine = [x for x in c.agvs if x in result.paths]
        others = [x for x in c.agvs if x not in result.paths]
        if c.kind in ("vertex", "swap") and others:
            what = (f"AGV {mine[0]}'s new path runs into AGV {others[0]}'s committed path "
                    f"({c})", "check request.reservations.free(cell, t, agv) for every cell "
                    "of the footprint (both footprints while moving) before using it, and "
                    "stay off cells another AGV rests on for good (reservations.last_use)")
        elif c.kind in ("vertex", "swap"):
            what = (f"two returned paths conflict ({c})", "commit each new path into "
                    "request.reservations (reservations.commit(path, agent.k)) before "
                    "planning the next AGV, or resolve conflicts jointly")
        elif c.kind == "move":
            what = (f"a returned path breaks the motion rules ({c}: not a wait, or a move to "
                    "a 4-neighbour that does not take exactly ticks_per_move ticks)",
                    "move one cell at a time along graph edges; a slow AGV holds (a, b) for "
                    "ticks_per_move - 1 ticks, then stands at (b, b)")
        else:
            what = (f"a returned path leaves the floor ({c})", "use only nodes of "
                    "request.graphs.get(agent.k, agent.loaded, agent.shelf)")
        ck.fail("conflict-free", *what)
    ck.ok("conflict-free")
    _check_headings(world, agents, result, ck)
    turns = plan_turn_conflicts(world, paths, tick, {a.agv: a.heading for a in agents})
    if turns:
        c = turns[0]
        mine = [x for x in c.agvs if x in result.paths]
        fixes = {
            "sweep": "keep the cells agent.sweep.cells (offsets from the anchor) of every "
                     "turn in place free of other AGVs at the turn's tick and the next "
                     "(reservations.free), and off cells other AGVs' turns sweep",
            "turn_lock": "never turn at the same tick as another AGV whose turn shares one "
                         "of agent.sweep.locks (reservations.locks_free)",
            "turn_wall": "never turn in place at an anchor in agent.no_turn (drive straight "
                         "through it)"}
        ck.fail("turn sweeps", f"a returned path {'of AGV ' + str(mine[0]) + ' ' if mine else ''}"
                f"turns in place where it may not ({c})",
                fixes[c.kind] + "; a turn is a move whose direction differs from the AGV's "
                "heading (agent.heading, then its last move's); see "
                "warerover_phys.planning.search.turning_astar")
    ck.ok("turn sweeps")


def _check_headings(world, agents: list, result, ck: _Checker) -> None:
    """Rotation-aware agents (``turn_ticks`` set): their paths carry one heading per
    state, start facing the agent's heading, move only straight ahead and turn no faster
    than ``turn_ticks`` allow."""
    from .planning.sweep import DIR_OF
    from .validate import validate_headings

    rot = [a for a in agents if getattr(a, "turn_ticks", None) is not None
           and a.agv in result.paths]
    if not rot:
        return
    for a in rot:
        path = result.paths[a.agv]
        heads = path.headings
        if heads is None or len(heads) != len(path.states):
            ck.fail("headings", f"AGV {a.agv} is rotation-aware (agent.turn_ticks = "
                    f"{a.turn_ticks}) but its path has headings {_short(heads)} for "
                    f"{len(path.states)} states", "give TimedPath(..., headings=(h0, h1, "
                    "...)) one direction index (0 east, 1 south, 2 west, 3 north) per state")
        if a.heading is not None and heads[0] != DIR_OF[a.heading]:
            ck.fail("headings", f"AGV {a.agv}'s path starts facing {heads[0]}, but the "
                    f"agent faces {DIR_OF[a.heading]} (agent.heading = {a.heading})",
                    "start every path with the heading the agent has now")
        found = validate_headings({a.agv: path.states}, {a.agv: heads}, world.layout.cols,
                                  turn_ticks={a.agv: a.turn_ticks},
                                  start_tick=path.start_tick)
        if found:
            ck.fail("headings", f"AGV {a.agv}'s path breaks the rotation rules ({found[0]}: "
                    f"{found[0].kind})", "move only along the heading (the direction of "
                    "headings[i] before the move); turn in place a quarter at a time, "
                    "standing turn_ticks[0] ticks per quarter (turn_ticks[1] for a half "
                    "turn), the new heading on the turn's last state; see "
                    "warerover_phys.planning.rotation")
    ck.ok("headings")


def plan_turn_conflicts(world, paths: dict, tick: int,
                        headings: dict | None = None, max_conflicts: int = 100,
                        loaded: dict | None = None) -> list:
    """Turn-in-place conflicts (:func:`~warerover_phys.planning.sweep_checks.sweep_conflicts`:
    ``sweep``, ``turn_lock``, ``turn_wall``) of the timed ``paths`` (``agv -> TimedPath``)
    from ``tick`` on, for ``world``'s fleet and layout (empty when no AGV's turn holds
    anything). ``headings``: the heading of AGVs at ``tick`` (for paths that start then);
    the others' headings are worked out from their paths and the reservation table.
    ``loaded`` (``agv -> bool``, or one bool per tick from ``tick``): also the turns beside
    AGVs that carry a shelf (``shelf_sweep``; planners do not reserve these yet, the
    physics executor's dependency graph makes such a turn wait)."""
    from .planning.sweep import turn_fields
    from .planning.sweep_checks import heading_after, sweep_conflicts

    fields = turn_fields(world.layout, [a.spec for a in world.agvs])
    if not fields:
        return []
    cols = world.layout.cols
    res = world.reservations
    horizon = max(p.end_tick for p in paths.values()) + 2
    states = {agv: [p.state_at(t) for t in range(tick, horizon)] for agv, p in paths.items()}
    heads = {}
    for agv, p in paths.items():
        if headings is not None and agv in headings and p.start_tick == tick:
            heads[agv] = headings[agv]
        else:
            heads[agv] = heading_after(p.states[:max(0, tick - p.start_tick) + 1], cols,
                                       res.heading_at_start(agv))
    return sweep_conflicts(
        states, world.layout.rows, cols, {a.id: a.k for a in world.agvs},
        {a: sw.cells for a, (sw, _) in fields.items() if sw is not None},
        start_tick=tick, headings=heads, max_conflicts=max_conflicts,
        locks={a: sw.locks for a, (sw, _) in fields.items() if sw is not None},
        no_turn={a: nt for a, (_, nt) in fields.items()},
        shelf_offsets=None if loaded is None else {
            a: sw.shelf_cells for a, (sw, _) in fields.items() if sw is not None},
        loaded=loaded)


def _check_edges(world, agent, path, ck: _Checker) -> None:
    """Every state is an enterable anchor or a move along an edge of the AGV's graph."""
    graph = world.graphs.get(agent.k, agent.loaded, agent.shelf)
    cols = graph.cols
    prev = None
    for i, (a, b) in enumerate(path.states):
        t = path.start_tick + i
        for node in (a, b):
            if not 0 <= node < graph.num_nodes or not graph.enterable.ravel()[node]:
                ck.fail("motion graph", f"AGV {agent.agv} ({agent.k}x{agent.k}) is at node "
                        f"{node} = cell {divmod(node, cols)} at tick {t}, which its footprint "
                        "cannot occupy (off the grid, on an obstacle, or on a shelf when "
                        "loaded)", "search request.graphs.get(agent.k, agent.loaded, "
                        "agent.shelf) and use only its nodes")
        moves = [(a, b)] if a != b else []
        if prev is not None and prev[0] == prev[1] and a == b and a != prev[0]:
            moves.append((prev[0], a))
        for u, v in moves:
            if v not in graph.neighbors[u]:
                ck.fail("motion graph", f"AGV {agent.agv} moves from {divmod(u, cols)} to "
                        f"{divmod(v, cols)} at tick {t}, which is not an edge of its motion "
                        "graph (a jump, a diagonal or a move into a blocked footprint)",
                        "take each step from graph.neighbors[node] (or wait in place)")
        prev = (a, b)


def _check_goals(world, goals: dict[int, int], replans_all: bool, ck: _Checker) -> None:
    res = world.reservations
    for agv, goal in goals.items():
        path = res.paths[agv]
        if path.states[-1] != (goal, goal):
            end = divmod(path.states[-1][1], world.layout.cols)
            within = f"within {STEP_TICKS} ticks" if replans_all else "in one call"
            ck.fail("reaches goals", f"AGV {agv} ends at {end}, not at its goal "
                    f"{divmod(goal, world.layout.cols)} ({within}, on an open floor where it "
                    "can)", "plan each path to the agent's goal (the last state must be "
                    "(goal, goal)); put AGVs you cannot plan in PlanResult.failed")
    ck.ok("reaches goals")


# ================================================================================ executor

# The fixed plans (cells per standing state; repeat a cell to wait): AGV 1 follows AGV 0 one
# tick behind along row 0, the slow 2x2 AGV 2 comes up behind them.
EXEC_PLANS: dict[int, list[tuple[int, int]]] = {
    0: [(0, 0), (0, 1), (0, 2), (0, 3), (0, 4), (0, 5), (0, 6), (0, 7), (1, 7), (2, 7), (3, 7)],
    1: [(1, 0), (0, 0), (0, 1), (0, 2), (0, 3), (0, 4), (0, 5), (0, 6), (0, 7)],
    2: [(2, 1), (1, 1), (1, 2), (0, 2), (0, 3), (0, 4), (0, 5)],
}
STANDSTILL_TICKS = 4


def check_executor(target: Any, spec: Any = None, *, seed: int = 0,
                   max_ticks: int = 120) -> ConformanceReport:
    """Run an executor through fixed plans; raise :class:`ConformanceError` on the first
    problem, else return the passed checks. ``max_ticks``: ticks allowed to finish the
    plans (the ideal grid executor needs 12).

    >>> check_executor("grid").passed[-1]
    'determinism'
    """
    ck = _Checker("executor", _label(target))
    factory = _factory("executor", target, spec, ck)
    if _is_instance("executor", target):
        ck.fail("build", "got an instance; the determinism check needs two fresh executors",
                "pass the class, a factory or the registry name")
    executor = _new(factory, ck)
    _check_members("executor", executor, ck)
    _check_name(executor, ck)
    ck.case = "standstill"
    _run_executor(executor, seed, ck, plans=False, ticks=STANDSTILL_TICKS)
    ck.case = "follow the plans"
    first = _run_executor(_new(factory, ck), seed, ck, plans=True, ticks=max_ticks)
    again = _run_executor(_new(factory, ck), seed, ck, plans=True, ticks=max_ticks)
    if first != again:
        ck.fail("determinism", f"two fresh executors bound with the same seed ({seed}) "
                f"differ: {_trace_difference(first, again)}", "draw randomness only from "
                "setup.rng, keep nothing in module or class globals, and iterate AGVs in id "
                "order")
    ck.ok("determinism")
    return ck.report


def _run_executor(ex, seed: int, ck: _Checker, *, plans: bool, ticks: int) -> list:
    """Bind ``ex`` to a fresh world, step it as the loop does, check every report; return
    the trace of (states, behind, blocked, collisions, replan)."""
    from .sim import apply_report, executor_setup, tick_view

    world = _mixed_world(seed)
    cols = world.layout.cols
    if plans:
        for agv, cells in EXEC_PLANS.items():
            world.reservations.commit(_timed(world, agv, cells), world.agvs[agv].k)
    goal = {a.id: world.reservations.paths[a.id].states[-1] for a in world.agvs}
    try:
        ex.bind(executor_setup(world))
    except Exception as err:  # noqa: BLE001 - a plug-in's bind is user code
        ck.fail("bind", f"bind() raised {type(err).__name__}: {err}", "build the per-episode "
                "state from the ExecutorSetup (layout, tick_s, agvs, rng) in bind()")
    ck.ok("bind")
    executed = {a.id: [a.pos] for a in world.agvs}
    trace = []
    done_at = None
    for _ in range(ticks):
        view = tick_view(world)
        try:
            report = ex.step(view)
        except Exception as err:  # noqa: BLE001 - a plug-in's step is user code
            ck.fail("step", f"step() raised {type(err).__name__}: {err} at tick {world.tick}",
                    "advance every AGV by one tick of its committed plan (view.plans)")
        _check_report(world, report, view, ck)
        _check_remaining(world, ex, ck)
        apply_report(world, report)
        world.tick += 1
        for a in world.agvs:
            executed[a.id].append(a.pos)
        trace.append((dict(report.states), dict(report.behind), sorted(report.blocked),
                      report.collisions, sorted(report.replan)))
        if plans:
            _check_progress(world, executed, ck)
        if all(a.pos == goal[a.id] for a in world.agvs) and not any(
                ex.remaining(a.id) for a in world.agvs):
            done_at = world.tick
            if plans:
                break
    if plans and done_at is None:
        late = [f"AGV {a.id} at {divmod(a.pos[1], cols)} (goal {divmod(goal[a.id][1], cols)})"
                for a in world.agvs if a.pos != goal[a.id]]
        ck.fail("follows plans", f"after {ticks} ticks the valid plans are not done: "
                f"{', '.join(late) or 'remaining() is not empty'}",
                "move each AGV along view.plans[agv] (path.state_at(view.tick + 1 - "
                "view.behind[agv]) on the grid), or pass a larger max_ticks if it is merely "
                "slow")
    if plans:
        ck.ok("follows plans")
    if not plans and any(executed[a.id][-1] != executed[a.id][0] for a in world.agvs):
        moved = [a.id for a in world.agvs if executed[a.id][-1] != executed[a.id][0]]
        ck.fail("follows plans", f"AGVs {moved} moved although their plans say stand still",
                "move AGVs only along their committed paths")
    _check_executed(world, executed, ck)
    _check_results(world, ex, view, ck)
    return trace


TRACE_FIELDS = ("states", "behind", "blocked", "collisions", "replan")


def _trace_difference(first: list, again: list) -> str:
    """Where two executor traces first differ, in words."""
    for t, (a, b) in enumerate(zip(first, again, strict=False)):
        for what, x, y in zip(TRACE_FIELDS, a, b, strict=True):
            if x == y:
                continue
            if isinstance(x, dict) and isinstance(y, dict):
                agv = min(i for i in x.keys() | y.keys() if x.get(i) != y.get(i))
                return (f"at tick {t}, report.{what}[{agv}] is {x.get(agv)!r} in one run and "
                        f"{y.get(agv)!r} in the other")
            return f"at tick {t}, report.{what} is {x!r} in one run and {y!r} in the other"
    return f"one run took {len(first)} ticks to finish the plans, the other {len(again)}"


def _check_report(world, report, view, ck: _Checker) -> None:
    from .executors.base import StepReport

    t, n = view.tick, len(world.agvs)
    if not isinstance(report, StepReport):
        ck.fail("report", f"step() returned {type(report).__name__} at tick {t}",
                "return warerover_phys.executors.StepReport(states={agv: (a, b), ...})")
    missing = sorted(set(range(n)) - set(report.states))
    extra = sorted(set(report.states) - set(range(n)))
    if missing or extra:
        ck.fail("report", f"report.states at tick {t} " + (f"lacks AGVs {missing}" if missing
                else f"has unknown AGVs {extra}"), "report every AGV's state every tick, "
                "standing ones included: {agv: (node, node)}")
    for agv, state in report.states.items():
        _check_state(world, agv, state, t, ck)
    ints = {"behind": list(report.behind.values()), "blocked": report.blocked,
            "replan": report.replan}
    ids_ok = all(isinstance(i, int | np.integer) and 0 <= i < n
                 for i in [*report.behind, *report.blocked, *report.replan])
    if not ids_ok or not all(isinstance(v, int | np.integer) and v >= 0 for v in ints["behind"]):
        ck.fail("report", f"report.behind / blocked / replan at tick {t} hold something other "
                f"than AGV ids and tick counts: {report.behind}, {report.blocked}, "
                f"{report.replan}", "behind: {agv: ticks >= 0}; blocked, replan: lists of "
                "AGV ids")
    if not isinstance(report.collisions, int | np.integer) or report.collisions < 0:
        ck.fail("report", f"report.collisions is {report.collisions!r} at tick {t}",
                "count collisions as an int >= 0")
    if report.collisions:
        ck.fail("no false collisions", f"it reported {report.collisions} collision(s) at tick "
                f"{t} while executing valid, conflict-free plans", "count only overlaps or "
                "contacts that really happened (a blocked move is not a collision); "
                "report.collisions must be 0 here")
    if not all(isinstance(e, tuple) and len(e) == 2 and isinstance(e[0], str)
               and isinstance(e[1], dict) for e in report.events):
        ck.fail("report", f"report.events at tick {t} is {_short(report.events)}",
                "log events as (name, {field: value}) tuples")
    if report.intrusion_unit not in ("m", "cells"):
        ck.fail("report", f"report.intrusion_unit is {report.intrusion_unit!r}",
                "use 'm' (physical executors) or 'cells' (grid executors)")
    ck.ok("report")
    ck.ok("no false collisions")


def _check_state(world, agv: int, state, t: int, ck: _Checker) -> None:
    cols = world.layout.cols
    graph = world.graphs.get(world.agvs[agv].k, False)
    if not (isinstance(state, tuple) and len(state) == 2 and all(type(x) is int for x in state)):
        ck.fail("report", f"AGV {agv}'s state at tick {t} is {state!r}", "report a state as "
                "a tuple of two Python ints (a, b): standing at a if a == b, else moving a -> b")
    a, b = state
    if not all(0 <= x < graph.num_nodes and graph.enterable.ravel()[x] for x in (a, b)) or (
            a != b and b not in graph.neighbors[a]):
        ck.fail("report", f"AGV {agv}'s state at tick {t} is {state} = "
                f"{divmod(a, cols)} -> {divmod(b, cols)}, not a place its footprint fits nor a "
                "move to a neighbouring one", "report (a, a) or (a, b) with b a 4-neighbour of "
                "a, both valid anchors for the AGV's footprint")


def _check_progress(world, executed: dict, ck: _Checker) -> None:
    """Every executed state lies on the AGV's plan, never behind where it was before."""
    cols = world.layout.cols
    for agv, cells in EXEC_PLANS.items():
        nodes = [world.node(c) for i, c in enumerate(cells) if i == 0 or c != cells[i - 1]]
        where = 0
        for t, (a, b) in enumerate(executed[agv]):
            if a == b:
                ok = a in nodes[where:]
                nxt = nodes.index(a, where) if ok else where
            else:
                idx = [i for i in range(where, len(nodes) - 1) if nodes[i:i + 2] == [a, b]]
                ok = bool(idx)
                nxt = idx[0] if ok else where
            if not ok:
                ck.fail("follows plans", f"AGV {agv} is in state {divmod(a, cols)} -> "
                        f"{divmod(b, cols)} at tick {t}, which is off its plan or behind where "
                        "it already was", "move each AGV only forward along its committed "
                        "path (view.plans[agv]); wait instead of leaving it")
            where = nxt


def _check_executed(world, executed: dict, ck: _Checker) -> None:
    from .validate import validate_states

    conflicts = [c for c in validate_states(executed, world.layout.obstacles,
                                            sizes={a.id: a.k for a in world.agvs})
                 if c.kind != "move"]  # executors may lag, so moves may take longer
    if conflicts:
        ck.fail("conflict-free execution", f"the executed states conflict although the plans "
                f"do not ({conflicts[0]})", "when an AGV falls behind, hold the AGVs whose next "
                "cells it still holds (report them in blocked) instead of moving them in")
    ck.ok("conflict-free execution")


def _check_remaining(world, ex, ck: _Checker) -> None:
    for a in world.agvs:
        try:
            rest = ex.remaining(a.id)
        except Exception as err:  # noqa: BLE001 - user code
            ck.fail("remaining", f"remaining({a.id}) raised {type(err).__name__}: {err}",
                    "return [] for an AGV with nothing beyond its committed path")
        if not isinstance(rest, list) or not all(
                isinstance(s, tuple) and len(s) == 2 and all(type(x) is int for x in s)
                for s in rest):
            ck.fail("remaining", f"remaining({a.id}) returned {_short(rest)}",
                    "return a list of states (a, b) of Python ints ([] if none)")
    ck.ok("remaining")


def _check_results(world, ex, view, ck: _Checker) -> None:
    try:
        summary = ex.summary()
    except Exception as err:  # noqa: BLE001 - user code
        ck.fail("summary", f"summary() raised {type(err).__name__}: {err}",
                "return a dict of figures for metrics.json ({} if none)")
    if not isinstance(summary, dict) or not all(isinstance(k, str) for k in summary):
        ck.fail("summary", f"summary() returned {_short(summary)}",
                "return a dict with str keys ({} if none)")
    try:
        json.dumps(summary, allow_nan=True)
    except (TypeError, ValueError) as err:
        ck.fail("summary", f"summary() is not JSON-serialisable ({err})",
                "convert numpy values with float(x) / int(x) / x.tolist()")
    ck.ok("summary")
    traj = ex.trajectory()
    if traj is not None and (not isinstance(traj, dict) or not all(
            isinstance(k, str) and isinstance(v, np.ndarray) for k, v in traj.items())):
        ck.fail("trajectory", f"trajectory() returned {_short(traj)}",
                "return None, or a dict of str -> numpy array (it is written with np.savez)")
    ck.ok("trajectory")
    far = frozenset({world.node((3, 8))})
    out = ex.stop_short(0, far, view)
    if not (isinstance(out, tuple) and len(out) == 2
            and all(isinstance(x, bool | np.bool_) for x in out)):
        ck.fail("stop_short", f"stop_short(0, cells, view) returned {_short(out)}",
                "return (handled, enters): two bools, (False, False) to let the loop cut the "
                "path")
    ck.ok("stop_short")
