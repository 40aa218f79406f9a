"""MAPF planning: motion graphs, reservations, planners."""

from __future__ import annotations

from ..registry import build
from .astar import AStarPlanner
from .base import AgentRequest, Planner, PlanRequest, PlanResult, TimedPath
from .cbs import CBSPlanner
from .graph import GraphSet, MotionGraph
from .lacam_planner import LaCAMPlanner
from .pibt_planner import PIBTPlanner
from .reservation import ReservationTable

__all__ = ["AStarPlanner", "CBSPlanner", "PIBTPlanner", "LaCAMPlanner", "AgentRequest", "Planner", "PlanRequest", "PlanResult", "TimedPath",
           "GraphSet", "MotionGraph", "ReservationTable", "make_planner"]



def make_planner(spec) -> Planner:
    """Build the planner a :class:`~warerover_phys.config.PlannerSpec` names (a built-in, an
    entry point or a plug-in class; see :mod:`warerover_phys.registry`)."""
    return build("planner", spec)
