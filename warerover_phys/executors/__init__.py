"""Executors: carry out the committed plans, one tick at a time, and report what happened."""

from __future__ import annotations

from ..registry import build
from .base import AgvBody, Executor, ExecutorSetup, StepReport, TickView
from .grid import GridExecutor

__all__ = ["AgvBody", "Executor", "ExecutorSetup", "StepReport", "TickView", "GridExecutor",
           "make_executor"]


def make_executor(spec) -> Executor:
    """Build the executor an :class:`~warerover_phys.config.ExecutorSpec` names (a built-in,
    an entry point or a plug-in class; see :mod:`warerover_phys.registry`)."""
    return build("executor", spec)
