"""MAPF planning: motion graphs, reservations, planners.

The names below are imported on first use, so that importing one planning module (as
``warerover solve`` does with :mod:`~warerover_phys.planning.oneshot.core`) does not load every
planner and the plug-in registry (pydantic).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .base import AgentRequest, Planner, PlanRequest, PlanResult, TimedPath
    from .graph import GraphSet, MotionGraph
    from .lacam.planner import LaCAMPlanner
    from .pibt.planner import PIBTPlanner
    from .reservation import ReservationTable
    from .search.astar import AStarPlanner
    from .search.cbs import CBSPlanner

__all__ = ["AStarPlanner", "CBSPlanner", "PIBTPlanner", "LaCAMPlanner", "AgentRequest", "Planner", "PlanRequest", "PlanResult", "TimedPath",
           "GraphSet", "MotionGraph", "ReservationTable", "make_planner"]

_LAZY = {"AStarPlanner": "search.astar", "CBSPlanner": "search.cbs",
         "PIBTPlanner": "pibt.planner", "LaCAMPlanner": "lacam.planner", "AgentRequest": "base", "Planner": "base",
         "PlanRequest": "base", "PlanResult": "base", "TimedPath": "base",
         "GraphSet": "graph", "MotionGraph": "graph", "ReservationTable": "reservation"}


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def make_planner(spec) -> Planner:
    """Build the planner a :class:`~warerover_phys.config.PlannerSpec` names (a built-in, an
    entry point or a plug-in class; see :mod:`warerover_phys.registry`)."""
    from ..registry import build

    return build("planner", spec)
