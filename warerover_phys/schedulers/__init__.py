"""Order schedulers: which idle AGV fetches which shelf for which orders."""

from __future__ import annotations

from ..plugins import build_plugin
from ..registry import is_plugin, lookup
from .base import Assignment, Scheduler
from .rd import RandomDispatch
from .ta import TaskAssignment

__all__ = ["Assignment", "Scheduler", "RandomDispatch", "TaskAssignment", "make_scheduler",
           "SCHEDULERS"]

SCHEDULERS = {"rd": RandomDispatch, "ta": TaskAssignment}


def make_scheduler(spec) -> Scheduler:
    """Build the scheduler a :class:`~warerover_phys.config.SchedulerSpec` names."""
    cls = lookup(SCHEDULERS, spec.name, "scheduler.name")
    if is_plugin(spec.name):
        return build_plugin(cls, spec, "scheduler.name", spec.name)
    return cls(spec)
