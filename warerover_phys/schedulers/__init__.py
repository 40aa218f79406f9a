"""Order schedulers: which idle AGV fetches which shelf for which orders."""

from __future__ import annotations

from ..registry import build
from .base import Assignment, Scheduler, SchedulerView
from .rd import RandomDispatch
from .ta import TaskAssignment

__all__ = ["Assignment", "Scheduler", "SchedulerView", "RandomDispatch", "TaskAssignment",
           "make_scheduler"]


def make_scheduler(spec) -> Scheduler:
    """Build the scheduler a :class:`~warerover_phys.config.SchedulerSpec` names (a built-in,
    an entry point or a plug-in class; see :mod:`warerover_phys.registry`)."""
    return build("scheduler", spec)
