"""Executors: move the AGVs one tick along their committed paths."""

from __future__ import annotations

from ..errors import ScenarioError
from .base import Executor, StepReport
from .grid import GridExecutor

__all__ = ["Executor", "StepReport", "GridExecutor", "make_executor", "EXECUTORS"]

EXECUTORS = {"grid": GridExecutor}


def make_executor(spec) -> Executor:
    try:
        cls = EXECUTORS[spec.name]
    except KeyError:
        raise ScenarioError(f"unknown executor (choose from {sorted(EXECUTORS)})",
                            field="executor.name", value=spec.name) from None
    return cls()
