"""Name -> class lookups for the pluggable parts (schedulers, planners, executors)."""

from __future__ import annotations

from typing import TypeVar

from .errors import ScenarioError

__all__ = ["lookup"]

T = TypeVar("T")


def lookup(registry: dict[str, T], name: str, field: str) -> T:
    """``registry[name]``, or a :class:`ScenarioError` naming ``field`` and the choices."""
    try:
        return registry[name]
    except KeyError:
        kind = field.split(".")[0]
        raise ScenarioError(f"unknown {kind} (choose from {sorted(registry)})", field=field,
                            value=name) from None
