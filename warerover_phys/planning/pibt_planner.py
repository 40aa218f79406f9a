"""Lifelong PIBT in the warehouse loop: every tick, every AGV takes one step.

Each tick the loop hands over *all* AGVs (``replans_all``); PIBT (with swap) picks one move
each, and every AGV gets a two-state path (now, next) that it then stays at until the next
tick. Priorities age: an AGV's priority is the number of ticks since it got its current goal,
so an AGV that keeps being pushed aside eventually wins. AGVs working in place (picking,
handing over, placing) are held where they are. Loaded AGVs keep to the aisles (their own
motion graph) and never step where their goal is unreachable from.

PIBT moves 1x1 AGVs one cell per tick; :func:`check_fleet` refuses other fleets.
"""

from __future__ import annotations

import numpy as np

from ..errors import ScenarioError
from .base import AgentRequest, PlanRequest, PlanResult, TimedPath
from .pibt import pibt_step

__all__ = ["PIBTPlanner", "check_fleet"]


def check_fleet(name: str, agvs) -> None:
    """PIBT-style planners move 1x1 AGVs one cell per tick; say so for any other fleet."""
    for agv in agvs:
        if agv.k != 1 or agv.ticks_per_move != 1:
            raise ScenarioError(
                f"{name} moves 1x1 AGVs one cell per tick, but AGV type {agv.type_name!r} has "
                f"footprint {agv.k} and {agv.ticks_per_move} ticks per move; use astar or cbs "
                "for this fleet", field="planner.name", value=name)


class PIBTPlanner:
    name = "pibt"
    replans_all = True
    """The loop must send every AGV every tick."""

    def __init__(self, swap: bool = True, **_: object) -> None:
        self.swap = swap

    def plan(self, request: PlanRequest) -> PlanResult:
        agents: list[AgentRequest] = sorted(request.agents, key=lambda a: a.agv)
        result = PlanResult()
        if not agents:
            return result
        graphs = request.graphs
        unloaded, loaded = graphs.get(1, False), graphs.get(1, True)
        config = [a.start for a in agents]
        goals = [a.goal for a in agents]
        tables = [(loaded if a.loaded else unloaded).neighbors for a in agents]
        dists = [(loaded if a.loaded else unloaded).dist_to(unloaded.cell(a.goal))
                 for a in agents]
        prio = [float(a.priority[0]) if a.priority else 0.0 for a in agents]
        held = [(i, a.start) for i, a in enumerate(agents) if a.hold]
        rng = request.rng if request.rng is not None else np.random.default_rng(0)
        tie = rng.random(unloaded.num_nodes) * 0.5
        nxt = pibt_step(unloaded, config, dists, prio, tie, forced=held, goals=goals,
                        swap=self.swap, tables=tables)
        if nxt is None:  # cannot happen with holds only (they never contradict); be safe
            nxt = list(config)
        res = request.reservations
        for a, here, there in zip(agents, config, nxt, strict=True):
            states = ((here, here),) if here == there else ((here, here), (there, there))
            path = TimedPath(a.agv, request.tick, states)
            res.commit(path, 1)
            result.paths[a.agv] = path
        return result
