"""Executors: move the AGVs one tick along their committed paths."""

from __future__ import annotations

from ..registry import lookup
from .base import Executor, StepReport
from .grid import GridExecutor

__all__ = ["Executor", "StepReport", "GridExecutor", "make_executor", "EXECUTORS"]

EXECUTORS = {"grid": GridExecutor, "physics": "physics"}


def make_executor(spec) -> Executor:
    cls = lookup(EXECUTORS, spec.name, "executor.name")
    if cls == "physics":  # imported only when asked for: pymunk is not needed on the grid
        from .physics import PhysicsExecutor

        return PhysicsExecutor(spec)
    return cls()
