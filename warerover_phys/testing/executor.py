"""The executor checker, :func:`check_executor`."""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from .common import (
    ConformanceReport,
    _check_members,
    _check_name,
    _Checker,
    _factory,
    _is_instance,
    _label,
    _mixed_world,
    _new,
    _short,
    _timed,
)

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
    from ..sim import apply_report, executor_setup, tick_view

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
    from ..executors.base import StepReport

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
    from ..validate import validate_states

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
