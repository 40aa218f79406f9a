"""MAPF planning: motion graphs, reservations, planners."""

from __future__ import annotations

from ..registry import is_plugin, lookup
from .astar import AStarPlanner
from .base import AgentRequest, Planner, PlanRequest, PlanResult, TimedPath
from .cbs import CBSPlanner
from .graph import GraphSet, MotionGraph
from .lacam_planner import LaCAMPlanner
from .learned import LearnedPlanner
from .pibt_planner import PIBTPlanner
from .reservation import ReservationTable

__all__ = ["AStarPlanner", "CBSPlanner", "PIBTPlanner", "LaCAMPlanner", "AgentRequest", "Planner", "PlanRequest", "PlanResult", "TimedPath",
           "GraphSet", "MotionGraph", "ReservationTable", "make_planner", "PLANNERS"]

PLANNERS = {"astar": AStarPlanner, "cbs": CBSPlanner, "pibt": PIBTPlanner,
            "lacam": LaCAMPlanner, "learned": LearnedPlanner}


def make_planner(spec) -> Planner:
    """Build the planner a :class:`~warerover_phys.config.PlannerSpec` names."""
    cls = lookup(PLANNERS, spec.name, "planner.name")
    if is_plugin(spec.name):
        return cls(spec)
    if cls is CBSPlanner:
        return CBSPlanner(max_expansions=spec.max_expansions, horizon=spec.horizon_ticks,
                          max_nodes=spec.max_nodes, time_budget_s=spec.time_budget_s)
    if cls is LaCAMPlanner:
        return LaCAMPlanner(time_budget_s=spec.time_budget_s)
    return cls(max_expansions=spec.max_expansions)
