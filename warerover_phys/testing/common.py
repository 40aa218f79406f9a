"""What every conformance checker shares: the report, the error, building the plug-in under
test, the small test worlds."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pydantic import ValidationError

from ..errors import ScenarioError, WareroverError

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


def _spec_class(kind: str) -> type:
    from ..config import ExecutorSpec, PlannerSpec, SchedulerSpec

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
    from .. import registry

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
    from ..registry import params_of

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
    from ..config import scenario_from_dict
    from ..world import World

    return World.build(scenario_from_dict({
        "seed": seed, "layout": {"grid": MIXED_GRID},
        "fleet": {"types": {"small": {},
                            "big": {"footprint": 2, "body_m": [1.4, 1.4], "max_speed_mps": 0.75}},
                  "agvs": [{"type": "small", "count": 2},
                           {"type": "big", "count": 1, "starts": [[2, 1]]}]}}))


def _sched_world(seed: int):
    from ..config import scenario_from_dict
    from ..world import World

    return World.build(scenario_from_dict({
        "seed": seed,
        "layout": {"grid": SCHED_GRID, "inventory": {"num_skus": 3, "skus_per_shelf": 1}},
        "fleet": {"agvs": [{"count": 3}]}}))


def _timed(world, agv: int, cells: list[tuple[int, int]], tick: int = 0):
    """A timed path through ``cells`` (repeat a cell to wait), slow moves spread over
    ``ticks_per_move`` ticks."""
    from ..planning.paths import TimedPath

    m = world.agvs[agv].ticks_per_move
    nodes = [world.node(c) for c in cells]
    states = [(nodes[0], nodes[0])]
    for a, b in zip(nodes, nodes[1:], strict=False):
        if a != b:
            states += [(a, b)] * (m - 1)
        states.append((b, b))
    return TimedPath(agv, tick, tuple(states))


STEP_TICKS = 60
"""Ticks a ``replans_all`` planner gets, one call per tick, to bring the easy cases home."""


def _short(value: Any, limit: int = 200) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."
