"""One registry for the three pluggable boxes: schedulers, planners and executors.

A scenario names each box in its section (``scheduler.name``, ``planner.name``,
``executor.name``) in one of three ways, looked up in this order:

1. a **built-in** (``ta``, ``rd``, ``errands``; ``astar``, ``cbs``, ``pibt``, ``lacam``; ``grid``,
   ``physics``);
2. an **entry point** of an installed package, in the group ``warerover_phys.schedulers``,
   ``warerover_phys.planners`` or ``warerover_phys.executors`` (``pyproject.toml``:
   ``[project.entry-points."warerover_phys.planners"] myplanner = "mypkg.mod:MyPlanner"``);
3. a **dotted path** to a class: ``package.module:ClassName`` (or ``package.module.ClassName``).

A plug-in class is built as ``cls(spec)`` with the scenario's section (``SchedulerSpec``,
``PlannerSpec`` or ``ExecutorSpec``), or as ``cls(spec, params)`` if it declares a pydantic
model ``Params``: the section's ``params`` mapping is validated against it when the scenario
is loaded (closed: unknown keys are errors naming the file and ``planner.params.KEY``). A
plug-in must have the members of its box's Protocol (``assign``; ``plan``; ``bind``,
``step``, ``remaining``, ``stop_short``, ``summary``, ``trajectory``) — see
:mod:`warerover_phys.testing` for the checkers that run it through small cases.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable
from importlib.metadata import entry_points
from typing import Any

from pydantic import BaseModel, ValidationError

from .errors import ScenarioError

__all__ = ["check_plugins", "KINDS", "BUILTINS", "is_plugin", "load_plugin", "resolve", "build", "params_of",
           "validate_params", "builtin_names"]

KINDS = ("scheduler", "planner", "executor")

MEMBERS: dict[str, tuple[str, ...]] = {
    "scheduler": ("assign",),
    "planner": ("plan",),
    "executor": ("bind", "step", "remaining", "stop_short", "summary", "trajectory"),
}
"""The methods a class of each kind must have (its Protocol's)."""

GROUPS = {kind: f"warerover_phys.{kind}s" for kind in KINDS}
"""Entry-point group of each kind."""


def _astar(spec):
    from .planning.search.astar import AStarPlanner

    return AStarPlanner(max_expansions=spec.max_expansions)


def _pibt(spec):
    from .planning.pibt.planner import PIBTPlanner

    return PIBTPlanner(rotation=spec.rotation_rule, budget_mb=spec.dist_budget_mb,
                       max_expansions=spec.max_expansions)


def _cbs(spec):
    from .planning.search.cbs import CBSPlanner

    return CBSPlanner(max_expansions=spec.max_expansions, horizon=spec.horizon_ticks,
                      max_nodes=spec.max_nodes, time_budget_s=spec.time_budget_s,
                      max_call_expansions=spec.max_call_expansions)


def _lacam(spec):
    from .planning.lacam.planner import LaCAMPlanner

    return LaCAMPlanner(time_budget_s=spec.time_budget_s, max_iterations=spec.max_iterations)


def _learned(spec):  # numpy inference only: the shipped weights, no PyTorch
    from .planning.learned.planner import LearnedPlanner

    return LearnedPlanner(spec, weights=spec.weights)


def _ta(spec):
    from .schedulers.ta import TaskAssignment

    return TaskAssignment(spec)


def _rd(spec):
    from .schedulers.rd import RandomDispatch

    return RandomDispatch(spec)


def _errands(spec):
    from .schedulers.errands import ErrandScheduler

    return ErrandScheduler(spec)


def _grid(spec):
    from .executors.grid import GridExecutor

    return GridExecutor(spec)


def _physics(spec):  # pymunk is imported only when the physics executor is asked for
    from .executors.physics import PhysicsExecutor

    return PhysicsExecutor(spec)


BUILTINS: dict[str, dict[str, Callable[[Any], Any]]] = {
    "scheduler": {"ta": _ta, "rd": _rd, "errands": _errands},
    "planner": {"astar": _astar, "cbs": _cbs, "pibt": _pibt, "lacam": _lacam,
                "learned": _learned},
    "executor": {"grid": _grid, "physics": _physics},
}
"""Built-in factories: ``spec -> instance`` (their parameters are the spec's own fields)."""

_DOTTED = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*([:.][A-Za-z_]\w*)")


def builtin_names(kind: str) -> list[str]:
    return sorted(BUILTINS[kind])


def is_plugin(name: str) -> bool:
    """Whether ``name`` is an import path (``package.module:ClassName``), not a built-in."""
    return ":" in name


def _kind_of(field: str) -> str:
    kind = field.split(".")[0]
    if kind not in KINDS:
        raise ValueError(f"field {field!r} names no pluggable box")
    return kind


def load_plugin(path: str, field: str) -> type:
    """Import ``package.module:ClassName`` (or ``package.module.ClassName``) and return the
    class; a :class:`ScenarioError` naming ``field`` and ``path`` if it cannot be imported
    or lacks its Protocol's methods."""
    if ":" in path:
        module_name, _, attr = path.partition(":")
    else:
        module_name, _, attr = path.rpartition(".")
    try:
        module = importlib.import_module(module_name)
    except Exception as err:  # noqa: BLE001 - any import failure is the user's to fix
        raise ScenarioError(f"cannot import plugin module {module_name!r} "
                            f"({type(err).__name__}: {err})", field=field, value=path) from None
    cls = getattr(module, attr, None)
    if cls is None:
        raise ScenarioError(f"module {module_name!r} has no attribute {attr!r}", field=field,
                            value=path)
    return _checked_class(cls, field, path)


def _checked_class(cls: Any, field: str, name: str) -> type:
    kind = _kind_of(field)
    missing = [m for m in MEMBERS[kind] if not callable(getattr(cls, m, None))]
    if not isinstance(cls, type) or missing:
        what = "a class" if not isinstance(cls, type) else \
            f"a {kind} class (missing {', '.join(m + '()' for m in missing)})"
        raise ScenarioError(f"plugin is not {what}", field=field, value=name)
    if kind == "planner" and not isinstance(getattr(cls, "replans_all", None), bool):
        raise ScenarioError("plugin planner must declare replans_all = True (every AGV every "
                            "tick) or False (only AGVs that need a path) as a class attribute",
                            field=field, value=name)
    params = getattr(cls, "Params", None)
    if params is not None and not (isinstance(params, type) and issubclass(params, BaseModel)):
        raise ScenarioError("plugin's Params must be a pydantic BaseModel", field=field,
                            value=name)
    return cls


def _entry_point(kind: str, name: str) -> Any | None:
    try:
        found = entry_points(group=GROUPS[kind], name=name)
    except Exception:  # noqa: BLE001 - a broken installed distribution must not stop us
        return None
    return next(iter(found), None)


def resolve(kind: str, name: str, field: str | None = None) -> Callable[..., Any] | type:
    """The built-in factory or the plug-in class ``name`` stands for."""
    field = field or f"{kind}.name"
    if name in BUILTINS[kind]:
        return BUILTINS[kind][name]
    ep = _entry_point(kind, name)
    if ep is not None:
        try:
            cls = ep.load()
        except Exception as err:  # noqa: BLE001
            raise ScenarioError(f"cannot load entry point {ep.value!r} ({type(err).__name__}: "
                                f"{err})", field=field, value=name) from None
        return _checked_class(cls, field, name)
    if _DOTTED.fullmatch(name) and ("." in name or ":" in name):
        return load_plugin(name, field)
    raise ScenarioError(f"unknown {kind} (choose from {builtin_names(kind)}, an installed "
                        f"entry point of {GROUPS[kind]!r}, or a class as "
                        "'package.module:ClassName')", field=field, value=name)


def params_of(target: Any) -> type[BaseModel] | None:
    """The pydantic parameter model a plug-in class declares (None for built-ins)."""
    params = getattr(target, "Params", None) if isinstance(target, type) else None
    return params


def validate_params(kind: str, name: str, params: dict[str, Any]) -> BaseModel | None:
    """Validate a section's ``params`` against its plug-in's ``Params`` model; a
    :class:`ScenarioError` naming ``KIND.params.KEY`` and the value otherwise."""
    target = resolve(kind, name)
    model = params_of(target)
    if model is None:
        if params:
            key = next(iter(params))
            raise ScenarioError(f"{kind} {name!r} takes no params (it declares no Params "
                                "model)", field=f"{kind}.params.{key}", value=params[key])
        return None
    try:
        return model.model_validate(params)
    except ValidationError as err:
        e = err.errors()[0]
        loc = ".".join(str(p) for p in e["loc"])
        where = f"{kind}.params" + (f".{loc}" if loc else "")
        value = e.get("input")
        msg = e["msg"] if e["type"] != "extra_forbidden" else "unknown parameter"
        raise ScenarioError(msg, field=where, value=value) from None


def build(kind: str, spec: Any) -> Any:
    """An instance of the box ``spec.name`` names, built with ``spec`` (and its validated
    ``params`` for plug-ins that declare a ``Params`` model)."""
    target = resolve(kind, spec.name)
    params = validate_params(kind, spec.name, dict(getattr(spec, "params", {}) or {}))
    try:
        obj = target(spec, params) if params is not None else target(spec)
    except ScenarioError:
        raise
    except Exception as err:  # noqa: BLE001 - a plug-in's constructor is user code
        first = str(err).strip().splitlines()[0] if str(err).strip() else ""
        raise ScenarioError(f"plugin constructor raised {type(err).__name__}"
                            + (f": {first}" if first else ""), field=f"{kind}.name",
                            value=spec.name) from None
    if spec.name in BUILTINS[kind] or kind == "executor":
        return obj
    from .plugins import Guarded  # run-time guard: a plug-in's errors become clean lines

    return Guarded(obj, f"{kind}.name", spec.name)


def check_plugins(scenario: Any) -> None:
    """Resolve the scenario's scheduler, planner and executor names (built-in, entry point
    or plug-in class) and validate each section's ``params`` against its plug-in's
    ``Params`` model; errors name the scenario's file."""
    for kind in KINDS:
        section = getattr(scenario, kind)
        try:
            validate_params(kind, section.name, section.params)
        except ScenarioError as err:
            raise err.with_file(scenario.source) if scenario.source else err from None
