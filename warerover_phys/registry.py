"""Name -> class lookups for the pluggable parts (schedulers, planners, executors).

A name is either a built-in (a key of the registry) or a *plugin*: a user class given by
import path, ``package.module:ClassName``. A plugin class is built with the scenario's spec
(``SchedulerSpec`` / ``PlannerSpec``) as its only argument and must have the method of its
Protocol (``assign`` for a scheduler, ``plan`` for a planner).
"""

from __future__ import annotations

import importlib
from typing import Any, TypeVar

from .errors import ScenarioError

__all__ = ["lookup", "is_plugin", "load_plugin"]

T = TypeVar("T")

_METHOD = {"scheduler": "assign", "planner": "plan"}
"""The method a plugin of each kind must have."""


def is_plugin(name: str) -> bool:
    """Whether ``name`` is an import path (``package.module:ClassName``), not a built-in."""
    return ":" in name


def load_plugin(path: str, field: str) -> Any:
    """Import ``package.module:ClassName`` and return the class; a :class:`ScenarioError`
    naming ``field`` and ``path`` if it cannot be imported or is not a usable class."""
    module_name, _, attr = path.partition(":")
    try:
        module = importlib.import_module(module_name)
    except Exception as err:  # noqa: BLE001 - any import failure is the user's to fix
        raise ScenarioError(f"cannot import plugin module {module_name!r} "
                            f"({type(err).__name__}: {err})", field=field, value=path) from None
    cls = getattr(module, attr, None)
    if cls is None:
        raise ScenarioError(f"module {module_name!r} has no attribute {attr!r}", field=field,
                            value=path)
    method = _METHOD.get(field.split(".")[0])
    if not isinstance(cls, type) or (method and not callable(getattr(cls, method, None))):
        what = f"a class with a {method}() method" if method else "a class"
        raise ScenarioError(f"plugin is not {what}", field=field, value=path)
    return cls


def lookup(registry: dict[str, T], name: str, field: str) -> T:
    """``registry[name]``, the plugin class ``name`` imports, or a :class:`ScenarioError`
    naming ``field`` and the choices."""
    if is_plugin(name):
        return load_plugin(name, field)
    try:
        return registry[name]
    except KeyError:
        kind = field.split(".")[0]
        raise ScenarioError(f"unknown {kind} (choose from {sorted(registry)} or a plugin "
                            "'package.module:ClassName')", field=field, value=name) from None
