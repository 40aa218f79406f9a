"""Order schedulers: which idle AGV fetches which shelf for which orders."""

from __future__ import annotations

from ..errors import ScenarioError
from .base import Assignment, Scheduler
from .rd import RandomDispatch
from .ta import TaskAssignment

__all__ = ["Assignment", "Scheduler", "RandomDispatch", "TaskAssignment", "make_scheduler",
           "SCHEDULERS"]

SCHEDULERS = {"rd": RandomDispatch, "ta": TaskAssignment}


def make_scheduler(spec) -> Scheduler:
    """Build the scheduler a :class:`~warerover_phys.config.SchedulerSpec` names."""
    try:
        cls = SCHEDULERS[spec.name]
    except KeyError:
        raise ScenarioError(f"unknown scheduler (choose from {sorted(SCHEDULERS)})",
                            field="scheduler.name", value=spec.name) from None
    return cls(spec)
