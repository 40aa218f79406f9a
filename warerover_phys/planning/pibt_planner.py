"""Lifelong PIBT in the warehouse loop: every tick, every AGV takes one step.

Each tick the loop hands over *all* AGVs (``replans_all``); PIBT (with swap) picks one move
each, and every AGV gets a two-state path (now, next) that it then stays at until the next
tick. Priorities age: an AGV's priority is the number of ticks since it got its current goal,
so an AGV that keeps being pushed aside eventually wins. AGVs working in place (picking,
handing over, placing) are held where they are. Loaded AGVs keep to the aisles (their own
motion graph) and never step where their goal is unreachable from.

A fleet of 1x1 AGVs that move one cell per tick takes the fast path (:func:`pibt_step`,
with swap). Any other fleet (``k x k`` AGVs, slow AGVs) is stepped by the footprint-aware
PIBT of :mod:`footprint_pibt`: an AGV in the middle of a multi-tick move keeps going, one
that starts a move gets the whole move as its path (the next tick reads its progress back
from that path in the reservation table). So are fleets with turn-aware AGVs (bodies whose
turns in place must be reserved, :func:`~warerover_phys.planning.sweep.turn_aware`): the
footprint-aware step then tracks headings, turn locks, swept cells and no-turn anchors, and
ranks moves by heading-aware distances (:meth:`~warerover_phys.planning.graph.MotionGraph.
turn_dist`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .base import AgentRequest, PlanRequest, PlanResult, TimedPath
from .footprint_pibt import Mover, Pose, footprint_step, pose_states, successor
from .pibt import pibt_step
from .reservation import ReservationTable
from .sweep import turn_aware
from .turns import heading_index

__all__ = ["PIBTPlanner", "uniform_fleet", "movers_for", "current_pose", "headings_for"]


def uniform_fleet(agents: Sequence[AgentRequest]) -> bool:
    """Only 1x1 AGVs that move one cell per tick, none turn-aware (the fast path)?"""
    return all(a.k == 1 and a.ticks_per_move == 1 and not turn_aware(a) for a in agents)


def movers_for(request: PlanRequest, agents: Sequence[AgentRequest],
               goals: Sequence[int]) -> list[Mover]:
    """Each AGV on its own motion graph (footprint, loaded, carried shelf), heading for
    ``goals``."""
    out = []
    for a, goal in zip(agents, goals, strict=True):
        graph = request.graphs.get(a.k, a.loaded, a.shelf)
        if turn_aware(a):
            sw = a.sweep
            out.append(Mover(a.k, a.ticks_per_move, graph.neighbors,
                             graph.dist_to(graph.cell(goal)), goal,
                             sweep=sw.cells if sw is not None else (),
                             locks=sw.locks if sw is not None else (), no_turn=a.no_turn,
                             dead=graph.dead_ends(a.no_turn), rows=graph.rows,
                             goal_dead=a.goal_dead if goal == a.goal else None,
                             tdist=graph.turn_dist(a.no_turn, goal, a.goal_dead
                                                   if goal == a.goal else None)
                             if a.no_turn else None))
        else:
            out.append(Mover(a.k, a.ticks_per_move, graph.neighbors,
                             graph.dist_to(graph.cell(goal)), goal))
    return out


def headings_for(agents: Sequence[AgentRequest]) -> tuple[int, ...] | None:
    """Direction indices the agents face, if any is turn-aware (else None)."""
    if not any(turn_aware(a) for a in agents):
        return None
    return tuple(heading_index(a.heading) for a in agents)


def current_pose(res: ReservationTable, agent: AgentRequest, tick: int) -> Pose:
    """Where the AGV is at ``tick``: at rest on ``agent.start``, or in the middle of the
    move its committed path makes into ``agent.start`` (with the ticks it still needs)."""
    here = agent.start
    path = res.paths.get(agent.agv)
    if path is None:
        return (here, here, 0)
    a, b = path.state_at(tick)
    if a == b or b != here:
        return (here, here, 0)
    left = 1
    while left < agent.ticks_per_move - 1 and path.state_at(tick + left) == (a, b):
        left += 1
    return (a, b, left)


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
        if not uniform_fleet(agents):
            return self._plan_footprints(request, agents)
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

    def _plan_footprints(self, request: PlanRequest, agents: list[AgentRequest]) -> PlanResult:
        """One footprint-aware PIBT step for a fleet of mixed sizes and speeds."""
        res, tick = request.reservations, request.tick
        movers = movers_for(request, agents, [a.goal for a in agents])
        poses = [current_pose(res, a, tick) for a in agents]
        prio = [float(a.priority[0]) if a.priority else 0.0 for a in agents]
        held = {i: a.start for i, a in enumerate(agents) if a.hold and poses[i][2] == 0}
        rng = request.rng if request.rng is not None else np.random.default_rng(0)
        tie = rng.random(len(movers[0].dist)) * 0.5
        nxt = footprint_step(movers, poses, prio, tie, res.cols, forced=held,
                             headings=headings_for(agents))
        if nxt is None:  # holds never contradict each other; be safe and keep still
            nxt = [successor(p, p[1], mv.m) for p, mv in zip(poses, movers, strict=True)]
        result = PlanResult()
        for a, here, there in zip(agents, poses, nxt, strict=True):
            path = TimedPath(a.agv, tick, pose_states([here, there]))
            res.commit(path, a.k, a.heading)
            result.paths[a.agv] = path
        return result
