"""The planner's requests of the closed loop: which AGVs ask for a path this tick, from where,
to which goal, with what priority and turn constraints; and the AGVs sent aside so that a
stuck one can pass. A mixin of :class:`~warerover_phys.sim.Simulation` (its state is the
simulation's)."""

from __future__ import annotations

from .planning.base import AgentRequest
from .planning.paths import TimedPath, footprint_nodes
from .planning.search.astar import nearest_free_anchor
from .planning.search.turning_astar import request_turn_fields
from .world import MOVING_STATES, Agv, AgvState

__all__ = ["LAG_SLACK_TICKS", "PlanRequests", "YIELD_TICKS", "claimed_to", "driven_to"]

YIELD_TICKS = 8
"""How long an AGV that makes way stays away."""
LAG_SLACK_TICKS = 2
"""With a planning latency: how many ticks an AGV may run behind its path (plus half the
planner's window) before the planner stops extending it (it is held where its path is at
the plan's effect tick)."""
_TRAVEL_STATES = (AgvState.TO_SHELF, AgvState.TO_STATION, AgvState.RETURNING)
"""States whose goal holds a step planner's AGV once it stands there (its work starts when
it is at rest); an errand needs no work, so an AGV on an errand is never held."""


class PlanRequests:
    """The request-building half of :class:`~warerover_phys.sim.Simulation`."""

    def _step_requests(self, t_eff: int) -> list[AgentRequest]:
        """Every AGV, for planners that move all of them each tick; from where each will
        be at ``t_eff`` (later than now with a latency: where its committed path is then)."""
        w = self.world
        out = []
        n = len(w.agvs)
        high = self.scenario.planner.ties == "high_id"
        ahead = t_eff > w.tick
        for agv in w.agvs:
            goal = w.goal_of(agv)
            # Standing on a task stage's goal: hold there, so that the path ends on the
            # goal and the stage's work can start (World.advance_tasks).
            hold = goal is None or (agv.standing and agv.node == goal
                                    and agv.state in _TRAVEL_STATES)
            goal = agv.node if goal is None else goal
            if agv.id in self._freeze_yields or agv.id in self._exit_sent:
                if agv.yield_goal is not None and w.tick < agv.yield_until and (
                        not hold or agv.id in self._exit_sent):
                    goal, hold = agv.yield_goal, False
                else:
                    agv.yield_goal = None
                    self._freeze_yields.discard(agv.id)
            if goal != agv.last_goal:
                agv.last_goal, agv.goal_since = goal, w.tick
            age = w.tick - agv.goal_since + ((agv.id if high else n - agv.id) / (n + 1))
            start = self._committed.get(agv.id, agv.node)
            if ahead and agv.id in w.reservations.paths:
                path = w.reservations.paths[agv.id]
                start = path.state_at(t_eff)[1]
                tc = claimed_to(path, self._committed.get(agv.id, agv.node), t_eff,
                                driven_to(path, agv.pos, first=True))
                if tc is not None:
                    # Ahead of its path (the dependency graph let it go early): it stands,
                    # or is committed by the executor to stand, where its path is only
                    # after t_eff. It keeps its path to there and is planned to stand there.
                    start, hold = path.state_at(tc)[1], True
                    self._cut_at[agv.id] = tc
                # Far behind its path already: stand where the path is at t_eff (the
                # plan's time waits for it), so that the paths do not run ahead of the AGVs
                # without bound.
                hold = hold or min(w.tick, path.end_tick) - driven_to(path, agv.pos) \
                    > LAG_SLACK_TICKS + self.clock.window // 2
            out.append(AgentRequest(
                agv=agv.id, start=start, goal=goal, k=agv.k, loaded=agv.loaded,
                ticks_per_move=agv.ticks_per_move,
                shelf=agv.trip.shelf if agv.loaded and agv.trip is not None else None,
                priority=(0.0 if hold else age,), hold=hold,
                **self._turn_request(agv, goal)))
        return out

    def _turn_request(self, agv: Agv, goal: int) -> dict:
        """The AgentRequest fields of a turn-aware AGV (none for the others): its heading,
        what its turns hold, where it may not turn, and how it leaves its goal."""
        turn = self._turns.get(agv.id)
        rot = self._rot.get(agv.id)
        if turn is None:
            return {} if rot is None else {"heading": self._heading[agv.id], "turn_ticks": rot}
        w = self.world
        shelf = agv.trip.shelf if agv.trip is not None else None
        after = None
        if goal == w.goal_of(agv):
            after = {AgvState.TO_SHELF: (True, shelf), AgvState.TO_STATION: (True, shelf),
                     AgvState.RETURNING: (False, None)}.get(agv.state)
        out = request_turn_fields(w.graphs, self._masks[agv.id], turn[0],
                                  self._heading[agv.id], agv.k, agv.loaded,
                                  shelf if agv.loaded else None, goal, after)
        if rot is not None:
            out["turn_ticks"] = rot
        return out

    def _replan_requests(self, t_eff: int) -> list[AgentRequest]:
        """The AGVs that need a new path (see :meth:`_plan`), from where each will be at
        ``t_eff`` (later than now with a latency)."""
        w = self.world
        res = w.reservations
        ahead = t_eff > w.tick
        agents = []
        for agv in w.agvs:
            if not agv.standing or agv.state not in MOVING_STATES or w.tick < agv.retry_at:
                continue
            goal = w.goal_of(agv)
            if agv.yield_goal is not None:
                if w.tick < agv.yield_until:
                    goal = agv.yield_goal
                else:
                    agv.yield_goal = None
            path = res.paths.get(agv.id)
            if goal is None or path is None:
                continue
            on_track = path.goal == goal and agv.delay == 0 and path.state_at(w.tick) == agv.pos
            if on_track and (path.end_tick > w.tick or agv.node == goal):
                continue
            if agv.delay and agv.blocked_ticks < self.scenario.planner.replan_blocked_ticks \
                    and path.goal == goal:
                continue
            if agv.node == goal and agv.state == AgvState.IDLE and path.end_tick <= w.tick:
                continue
            agents.append(AgentRequest(
                agv=agv.id, start=path.state_at(t_eff)[1] if ahead else agv.node, goal=goal,
                k=agv.k, loaded=agv.loaded, ticks_per_move=agv.ticks_per_move,
                shelf=agv.trip.shelf if agv.loaded and agv.trip is not None else None,
                priority=(-agv.plan_failures, not agv.loaded, agv.state == AgvState.IDLE),
                **self._turn_request(agv, goal)))
            # Re-anchor a delayed AGV's committed path at where it really stands.
            if not ahead and (agv.delay or path.state_at(w.tick) != agv.pos):
                res.commit(TimedPath(agv.id, w.tick, (agv.pos,)), agv.k)
        return agents

    def _make_way_for(self, stuck: Agv, goal: int | None = None) -> None:
        """Send AGVs that stand idle or queue on ``stuck``'s shortest path (to ``goal``,
        default its task's) somewhere else for a while: prioritized planning alone can wall
        an AGV in with AGVs that wait for it."""
        w = self.world
        goal = w.goal_of(stuck) if goal is None else goal
        if goal is None:
            return
        shelf = stuck.trip.shelf if stuck.loaded and stuck.trip is not None else None
        graph = w.graphs.get(stuck.k, stuck.loaded, shelf)
        route = graph.static_path(w.cell(stuck.node), w.cell(goal))
        cells = frozenset(c for node in route
                          for c in footprint_nodes(node, stuck.k, w.layout.cols))
        for other in w.agvs:
            if other.id == stuck.id or not other.standing or other.yield_goal is not None:
                continue
            waiting = other.state == AgvState.IDLE or (
                other.state in MOVING_STATES and other.node != w.goal_of(other))
            mine = set(footprint_nodes(other.node, other.k, w.layout.cols))
            if not waiting or not mine & cells:
                continue
            g = w.graphs.get(other.k, other.loaded,
                             other.trip.shelf if other.loaded and other.trip else None)
            probe = AgentRequest(other.id, other.node, other.node, k=other.k)
            spot = nearest_free_anchor(g, w.reservations, probe, keep_clear=w.keep_clear(),
                                       avoid=cells)
            if spot is not None:
                other.yield_goal = spot
                other.yield_until = w.tick + YIELD_TICKS
                other.retry_at = w.tick
                w.log("make_way", agv=other.id, for_agv=stuck.id, spot=list(w.cell(spot)))


def driven_to(path: TimedPath, here, first: bool = False) -> int:
    """The tick of ``path`` the AGV at state ``here`` has reached: the end of the first run
    of ``here`` in it (see :func:`~warerover_phys.invoke.splice`); an AGV between two cells
    (a move the path plans in one tick) is just before its first standing on the next
    one; the path's start if ``here`` is not on it. ``first``: the start of that run (the
    earliest tick the AGV may be at), not its end."""
    states = path.states
    a, b = here
    if a != b and here not in states:  # between two cells: on its way to the next one
        for k, s in enumerate(states):
            if s[0] == s[1] == b:
                return path.start_tick + max(k - 1, 0)
        return path.start_tick
    for k, s in enumerate(states):
        if s == here:
            while not first and k + 1 < len(states) and states[k + 1] == here:
                k += 1
            return path.start_tick + k
    return path.start_tick


def claimed_to(path: TimedPath, committed: int, t_eff: int, here: int) -> int | None:
    """The tick of ``path`` after ``t_eff`` at which the AGV, at tick ``here`` of it
    (:func:`driven_to`), will stand on ``committed`` (its node, or the node the executor
    has committed it to beyond its state): its first standing there from ``here`` on.
    None if that is not after ``t_eff`` (or the path does not stand there): the AGV is not
    ahead of where its path is at ``t_eff``."""
    states = path.states
    for k in range(max(here - path.start_tick, 0), len(states)):
        a, b = states[k]
        if a == b == committed:
            return path.start_tick + k if path.start_tick + k > t_eff else None
    return None
