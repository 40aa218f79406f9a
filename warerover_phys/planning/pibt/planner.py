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

Rotation-aware AGVs (``planner.rotations``, :mod:`~warerover_phys.planning.rotation`) take the
footprint-aware step too: each moves only straight ahead or turns a quarter in place (see
:mod:`footprint_pibt`), and its path carries headings. A turn of several ticks is committed
whole and read back from the path like a slow move.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ..base import AgentRequest, PlanRequest, PlanResult, TimedPath
from ..reservation import ReservationTable
from ..rotation import graph_rotation_dist
from ..search.turning_astar import heading_index
from ..sweep import turn_aware
from .footprint import Mover, Pose, footprint_step, pose_path, pose_states, successor
from .reference import pibt_step

__all__ = ["PIBTPlanner", "uniform_fleet", "movers_for", "current_pose", "headings_for",
           "last_turns", "commit_poses", "footprint_plan"]


def uniform_fleet(agents: Sequence[AgentRequest]) -> bool:
    """Only 1x1 AGVs that move one cell per tick, none turn-aware (the fast path)?"""
    return all(a.k == 1 and a.ticks_per_move == 1 and not turn_aware(a)
               and a.turn_ticks is None for a in agents)


def movers_for(request: PlanRequest, agents: Sequence[AgentRequest],
               goals: Sequence[int]) -> list[Mover]:
    """Each AGV on its own motion graph (footprint, loaded, carried shelf), heading for
    ``goals``."""
    out = []
    for a, goal in zip(agents, goals, strict=True):
        graph = request.graphs.get(a.k, a.loaded, a.shelf)
        if a.turn_ticks is not None:
            out.append(Mover(a.k, a.ticks_per_move, graph.neighbors,
                             graph.dist_to(graph.cell(goal)), goal, rot=a.turn_ticks,
                             rdist=graph_rotation_dist(graph, goal, a.ticks_per_move,
                                                       *a.turn_ticks)))
        elif turn_aware(a):
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


def headings_for(agents: Sequence[AgentRequest], res: ReservationTable | None = None,
                 tick: int = 0) -> tuple[int, ...] | None:
    """Direction indices the agents face, if any is turn-aware or rotation-aware (else
    None). With ``res``, a rotation-aware AGV in the middle of a turn (its committed path
    turns it later without moving: :func:`current_pose`) counts with the heading the turn
    ends in."""
    if not any(turn_aware(a) or a.turn_ticks is not None for a in agents):
        return None
    out = []
    for a in agents:
        h = heading_index(a.heading)
        if res is not None and a.turn_ticks is not None:
            end = _turn_end(res, a, tick)
            if end is not None:
                h = end[1]
        out.append(h)
    return tuple(out)


def last_turns(res: ReservationTable, agents: Sequence[AgentRequest],
                tick: int) -> dict[int, int]:
    """Per rotation-aware agent (index) that turned in the tick before ``tick``, the
    heading it turned away from (read from its committed path)."""
    out = {}
    for i, a in enumerate(agents):
        path = res.paths.get(a.agv)
        if a.turn_ticks is None or path is None or path.headings is None:
            continue
        before, now = path.heading_at(tick - 1), path.heading_at(tick)
        if path.start_tick <= tick - 1 and before != now and \
                path.state_at(tick - 1) == path.state_at(tick):
            out[i] = before
    return out


def _turn_end(res: ReservationTable, agent: AgentRequest, tick: int) -> tuple[int, int] | None:
    """A rotation-aware AGV in the middle of a committed turn of more than one tick:
    (ticks left, heading after it), else None."""
    path = res.paths.get(agent.agv)
    if path is None or path.headings is None or agent.turn_ticks is None \
            or max(agent.turn_ticks) <= 1:
        return None
    i = tick - path.start_tick
    if not 0 <= i < len(path.states) - 1:
        return None
    here = (agent.start, agent.start)
    h = path.headings[i]
    if path.states[i] != here or path.heading_at(tick) != heading_index(agent.heading):
        return None
    for j in range(i + 1, min(len(path.states), i + max(agent.turn_ticks) + 1)):
        if path.states[j] != here:
            return None
        if path.headings[j] != h:
            # the turn started before this tick if it needs more ticks than are left
            need = agent.turn_ticks[0 if (path.headings[j] - h) % 2 else 1]
            return (j - i, path.headings[j]) if j - i < need else None
    return None


def current_pose(res: ReservationTable, agent: AgentRequest, tick: int) -> Pose:
    """Where the AGV is at ``tick``: at rest on ``agent.start``, or in the middle of the
    move its committed path makes into ``agent.start`` (with the ticks it still needs)."""
    here = agent.start
    path = res.paths.get(agent.agv)
    if path is None:
        return (here, here, 0)
    turn = _turn_end(res, agent, tick)
    if turn is not None:
        return (here, here, turn[0])
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

    def __init__(self, swap: bool = True, rotation: str = "cascade", engine: str = "numba",
                 budget_mb: float = 1024.0, **_: object) -> None:
        from .compiled import CompiledStep

        self.swap = swap
        self.rotation = rotation
        """How rotation-aware AGVs take part in a step: ``cascade`` (``footprint_step``'s),
        or a Robot Runners rule, ``actions`` or ``turn-first`` (:mod:`.pibt_compiled`)."""
        self._compiled = CompiledStep(budget_mb=budget_mb, engine=engine)
        """1x1 fleets (:func:`.pibt_compiled.eligible`): the compiled step (``engine``
        ``numba``) or its Python references (``python``, for tests)."""

    def plan(self, request: PlanRequest) -> PlanResult:
        from .compiled import RULES, eligible

        agents: list[AgentRequest] = sorted(request.agents, key=lambda a: a.agv)
        result = PlanResult()
        if not agents:
            return result
        if self.swap and eligible(agents, self.rotation) and (
                self._compiled.engine == "numba" or agents[0].turn_ticks is not None):
            return self._compiled.plan(request, agents, self.rotation)
        if self.rotation in RULES and any(a.turn_ticks is not None for a in agents):
            raise ValueError(f"planner.rotation_rule {self.rotation!r} plans 1x1 AGVs that "
                             "move a cell and turn a quarter in one tick each, unloaded; this "
                             "request has others (use rotation_rule 'cascade')")
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
                        swap=self.swap, tables=tables, acyclic=request.acyclic)
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
        return footprint_plan(request, agents, self.rotation)


def footprint_plan(request: PlanRequest, agents: list[AgentRequest], rotation: str = "cascade",
                   rank: Callable[[list[Mover], list[Pose], list[float], dict[int, int]],
                                  list[Mover]] | None = None) -> PlanResult:
    """One footprint-aware PIBT step (:func:`footprint_step`) for ``agents`` (sorted by
    id), committed into the request's scratch reservations and returned. ``rank`` may
    replace movers before the step (given movers, poses, priorities and held AGVs), e.g.
    with a ``Mover.prefer`` ranking (the ``learned`` planner)."""
    res, tick = request.reservations, request.tick
    movers = movers_for(request, agents, [a.goal for a in agents])
    poses = [current_pose(res, a, tick) for a in agents]
    prio = [float(a.priority[0]) if a.priority else 0.0 for a in agents]
    held = {i: a.start for i, a in enumerate(agents) if a.hold and poses[i][2] == 0}
    rng = request.rng if request.rng is not None else np.random.default_rng(0)
    tie = rng.random(len(movers[0].dist)) * 0.5
    if rank is not None:
        movers = rank(movers, poses, prio, held)
    heads = headings_for(agents, res, tick)
    out_heads: list[int] = []
    nxt = footprint_step(movers, poses, prio, tie, res.cols, forced=held,
                         headings=heads, out_headings=out_heads,
                         rotation=rotation, undo=last_turns(res, agents, tick))
    if nxt is None:  # holds never contradict each other; be safe and keep still
        nxt = [successor(p, p[1], mv.m) for p, mv in zip(poses, movers, strict=True)]
        out_heads = list(heads) if heads is not None else []
    result = PlanResult()
    configs = [tuple(poses), tuple(nxt)]
    commit_poses(result, res, agents, configs,
                 [heads, tuple(out_heads)] if heads is not None else None, tick)
    return result


def commit_poses(result: PlanResult, res: ReservationTable, agents: Sequence[AgentRequest],
                 configs: Sequence[Sequence[Pose]], heads: Sequence[Sequence[int]] | None,
                 tick: int) -> None:
    """Each AGV's path through the pose ``configs`` (from ``tick``), with headings for the
    rotation-aware ones (``heads``: per config each agent's heading once its pose is
    done), committed into ``res`` and added to ``result``."""
    for i, a in enumerate(agents):
        poses = [c[i] for c in configs]
        if a.turn_ticks is not None and heads is not None:
            states, hs = pose_path(poses, [h[i] for h in heads], heading_index(a.heading))
            path = TimedPath(a.agv, tick, states, hs)
        else:
            path = TimedPath(a.agv, tick, pose_states(poses))
        res.commit(path, a.k, a.heading)
        result.paths[a.agv] = path
