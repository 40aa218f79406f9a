"""MAPF planning: motion graphs, reservations, planners."""

from __future__ import annotations

from ..registry import lookup
from .astar import AStarPlanner
from .base import AgentRequest, Planner, PlanRequest, PlanResult, TimedPath
from .graph import GraphSet, MotionGraph
from .lacam_planner import LaCAMPlanner
from .pibt_planner import PIBTPlanner
from .reservation import ReservationTable

__all__ = ["AStarPlanner", "PIBTPlanner", "LaCAMPlanner", "AgentRequest", "Planner", "PlanRequest", "PlanResult", "TimedPath",
           "GraphSet", "MotionGraph", "ReservationTable", "make_planner", "PLANNERS"]

PLANNERS = {"astar": AStarPlanner, "pibt": PIBTPlanner, "lacam": LaCAMPlanner}


def make_planner(spec) -> Planner:
    """Build the planner a :class:`~warerover_phys.config.PlannerSpec` names."""
    cls = lookup(PLANNERS, spec.name, "planner.name")
    return cls(max_expansions=spec.max_expansions)
