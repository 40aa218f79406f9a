"""The closed loop: orders arrive, the scheduler assigns, the planner plans, the executor
moves, tasks advance, metrics record — once per tick, until every order is done or
``max_ticks``.

Data flows one way: the loop owns the :class:`~warerover_phys.world.World` and is its only
writer. The scheduler reads a :class:`~warerover_phys.schedulers.base.SchedulerView` and
returns assignments; the planner gets a request with a private copy of the reservations and
returns timed paths, which the loop commits; the executor gets a read-only
:class:`~warerover_phys.executors.base.TickView` and returns a
:class:`~warerover_phys.executors.base.StepReport`, which the loop applies; failures are
events the fault model draws and the loop applies.

>>> from warerover_phys import load_scenario, run_episode
>>> result = run_episode(load_scenario("layouts/paper_homogeneous.yaml"), seed=1)
>>> result.metrics["success_rate"]
1.0
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from .config import Scenario
from .errors import ScenarioError
from .executors import make_executor
from .executors.base import StepReport, TickView
from .executors.binding import _goal_now, apply_report, executor_setup, step_executor, tick_view
from .faults.exits import exit_spots, inside_open_corridor
from .faults.model import FaultModel, close_failure, open_failure
from .invoke import PlanClock, cut, hold_back, plan_window, splice
from .loop_requests import YIELD_TICKS, PlanRequests
from .metrics import MetricsRecorder
from .planning import make_planner
from .planning.base import AgentRequest, Planner, PlanRequest, PlanResult
from .planning.paths import TimedPath, occupancy
from .planning.rotation import agent_turn_ticks
from .planning.sweep import DIR_OF, EAST, BodyShape, TurnMasks, turn_fields
from .registry import check_plugins
from .schedulers import make_scheduler
from .schedulers.base import SchedulerView
from .world import MOVING_STATES, Agv, AgvState, OrderStatus, World

__all__ = ["EpisodeResult", "run_episode", "Simulation", "executor_setup", "tick_view", "step_executor",
           "apply_report", "failure_cause"]

STUCK_FAILURES = 3
"""Failed plans in a row after which AGVs waiting on the AGV's route are asked to make way."""


@dataclass
class EpisodeResult:
    metrics: dict
    events: list[dict]
    planned: list[dict]
    """Every path the planner committed: ``{"agv", "tick", "states"}``."""
    actual: dict[int, list[tuple[int, int]]]
    """Executed state per tick per AGV, from tick 0."""
    world: World = field(repr=False)
    trajectory: dict | None = field(default=None, repr=False)
    """Executed poses at a fixed rate (physics executor; see ``PhysicsExecutor.trajectory``)."""
    headings: dict[int, list[int]] | None = None
    """``planner.rotations``: the heading (direction index) of each rotation-aware AGV per
    tick, from tick 0, as the loop tracked it; None otherwise."""
    plan_s: list[float] = field(default_factory=list)
    """Wall seconds the planner took at every tick (0 where it was not called)."""


class Simulation(PlanRequests):
    """One episode, stepped one tick at a time (``run_episode`` runs it to the end)."""

    def __init__(self, scenario: Scenario, seed: int | None = None, *,
                 planner: Planner | None = None) -> None:
        """``planner``: a planner object to use instead of the scenario's (the closed-loop
        environment, :mod:`warerover_phys.envs.loop`, plans with the agents' actions)."""
        if seed is not None:
            scenario = scenario.with_seed(seed)
        self.scenario = scenario
        self.world = World.build(scenario)
        try:
            check_plugins(scenario)
            self.scheduler = make_scheduler(scenario.scheduler)
            self.planner = make_planner(scenario.planner) if planner is None else planner
            self.executor = make_executor(scenario.executor)
        except ScenarioError as err:
            raise err.with_file(scenario.source) if scenario.source else err from None
        self.executor.bind(executor_setup(self.world))
        self.metrics = MetricsRecorder(scenario)
        self.faults = FaultModel(scenario.faults, self.world.rngs["faults"])
        self._pending: tuple | None = None
        self._cut_at: dict[int, int] = {}
        """With a planning latency: AGVs committed beyond the effect tick of the call being
        made, and the tick of their paths they keep to (see ``_step_requests``)."""
        """Between begin_tick and finish_tick: (request, t0, t1, asked at)."""
        self.clock = PlanClock(scenario.planner, scenario.tick_s)
        self._committed: dict[int, int] = {}
        """AGVs the executor committed beyond their state: the node a new plan must start
        from (``StepReport.committed``)."""
        """When the planner is called and when its plans take effect (:mod:`.invoke`)."""
        self.last_report: StepReport | None = None
        """What the executor reported for the last tick (read-only for observers such as
        the live view: ``poses`` holds continuous poses on physics)."""
        self.planned: list[dict] = []
        self.actual: dict[int, list[tuple[int, int]]] = {a.id: [a.pos] for a in self.world.agvs}
        self.freezes: list[dict] = []
        """Every freeze the executor reported: tick, AGVs, tick of their last progress."""
        self._freeze_hits: dict[int, int] = {}
        self._freeze_yields: set[int] = set()
        """AGVs sent to a yield spot by a freeze recovery (step planners honour these)."""
        self._exit_sent: dict[int, int] = {}
        """AGVs caught inside a corridor that were sent out -> the spot they go to."""
        w = self.world
        self._turns = turn_fields(w.layout, [a.spec for a in w.agvs])
        """AGVs whose turns in place planners must reserve: agv -> (sweep, no-turn anchors)."""
        shapes: dict = {}
        self._masks = {aid: shapes.setdefault(BodyShape.of(w.agvs[aid].spec), TurnMasks(
            w.layout, BodyShape.of(w.agvs[aid].spec))) for aid in self._turns}
        self._heading = {aid: EAST for aid in self._turns}
        """The direction each of those AGVs faces (its last move's; east when placed)."""
        self._rot: dict[int, tuple[int, int]] = {}
        """``planner.rotations``: per differential-drive AGV its (quarter, half) turn ticks
        (:func:`~warerover_phys.planning.rotation.agent_turn_ticks`); its heading is then
        tracked in ``_heading`` too (a planned turn changes it without a move)."""
        if scenario.planner.rotations:
            for a in w.agvs:
                tt = agent_turn_ticks(a.spec, scenario.tick_s)
                if tt is not None:
                    self._rot[a.id] = tt
                    self._heading.setdefault(a.id, EAST)
        self.headings: dict[int, list[int]] = {
            aid: [DIR_OF[self._heading[aid]]] for aid in sorted(self._rot)}
        """Executed heading per tick of every rotation-aware AGV (direction indices)."""
        if self._turns:
            w.reservations.configure_turns({a: sw for a, (sw, _) in self._turns.items()
                                            if sw is not None}, w.layout.rows)

    @property
    def done(self) -> bool:
        w = self.world
        return w.all_done() or w.tick >= self.scenario.max_ticks

    # ------------------------------------------------------------------------- failures

    def fail(self, agv_id: int, repair_ticks: int | None = None) -> None:
        """Fail an AGV now (on demand): it stops, a safety corridor opens around it, and it
        stays down for ``repair_ticks`` ticks, or until :meth:`repair` if None."""
        if repair_ticks is not None and repair_ticks < 1:
            raise ValueError(f"repair_ticks must be >= 1 (got {repair_ticks})")
        open_failure(self.world, agv_id, repair_ticks, self.executor, self._view())

    def add_orders(self, orders: list) -> None:
        """Add orders now (on demand, e.g. from the live view); they are pending from this
        tick on, like the stream's own arrivals."""
        self.world.add_orders(list(orders))

    def repair(self, agv_id: int) -> None:
        """Repair a failed AGV now; its corridor closes."""
        close_failure(self.world, agv_id)

    def step(self) -> None:
        """Run one tick of the loop."""
        request = self.begin_tick()
        self.finish_tick(None if request is None else
                         plan_window(self.planner, request, self.clock.window))

    def begin_tick(self) -> PlanRequest | None:
        """The first half of a tick: faults, order arrivals, the scheduler, and the
        planning request (None: no AGV needs planning). :meth:`finish_tick` takes what was
        planned for it; :meth:`step` is the two with the planner between them."""
        if self._pending is not None:
            raise RuntimeError("begin_tick called twice without finish_tick")
        w = self.world
        self._apply_faults()
        self._send_out()
        w.add_orders(w.arrivals())
        t0 = time.perf_counter()
        for a in self.scheduler.assign(SchedulerView(w), w.rngs["scheduler"]):
            w.start_trip(a.agv, a.shelf, list(a.orders))
        t1 = time.perf_counter()
        self._take_ready()
        self._count_plan_waits()
        request = None
        if self.clock.due(w.tick, self._short_of_plan):
            t_eff = self.clock.effect_tick(w.tick)
            self._cut_at = {}
            agents = self._step_requests(t_eff) if self._lifelong else \
                self._replan_requests(t_eff)
            if agents and t_eff > w.tick:  # the world moves on while the planner works
                for a in agents:
                    path = w.reservations.paths.get(a.agv)
                    if path is not None:
                        w.reservations.commit(cut(path, self._cut_at.get(a.agv, t_eff)), a.k)
            request = None if not agents else PlanRequest(
                tick=t_eff, agents=agents, graphs=w.graphs,
                reservations=w.reservations.snapshot(), rng=w.rngs["planner"],
                keep_clear=w.keep_clear(),
                acyclic=bool(getattr(self.executor, "acyclic_plans", False)))
        self._pending = (request, t0, t1, time.perf_counter())
        return request

    def finish_tick(self, result: PlanResult | None) -> None:
        """The second half of the tick :meth:`begin_tick` started: commit ``result`` (the
        plan for its request; None when there was none), step the executor and apply its
        report."""
        if self._pending is None:
            raise RuntimeError("finish_tick called without begin_tick")
        (request, t0, t1, asked), self._pending = self._pending, None
        w = self.world
        if request is None:
            self.metrics.replans_this_tick(0, 0, 0)
        else:
            if result is None:
                raise TypeError("finish_tick: a plan request was made, the result is None")
            self.clock.called(w.tick, request, result, time.perf_counter() - asked)
            self._take_ready()
        t2 = time.perf_counter()
        report = self.executor.step(self._view())
        self._apply_report(report)
        self.last_report = report
        self._committed = report.committed
        w.tick += 1
        self._follow_up(report.blocked)
        self._replan_now(report.replan)
        self._recover(report.freezes)
        if w.corridors and report.intrusion_unit == "cells":
            self._grid_intrusions()
        w.advance_tasks(report.settled)
        self.metrics.record_tick(sched_s=t1 - t0, plan_s=t2 - t1, blocked=len(report.blocked),
                                 collisions=report.collisions)

    def run(self, progress: Callable[[int, int, int], None] | None = None) -> EpisodeResult:
        from .util.gc_tuning import long_loop

        with long_loop():  # (see gc_tuning)
            while not self.done:
                self.step()
                if progress is not None:
                    progress(self.world.tick, len(self.world.completed_tick),
                             len(self.world.status))
        metrics = self.metrics.summary(self.world)
        metrics.update(self.clock.summary())
        metrics.update(self.executor.summary())
        metrics["freezes"] = len(self.freezes)
        metrics["deadlocks"] = metrics.get("deadlocks", 0) + len(self.freezes)
        metrics.update(failure_cause(self.world, self.freezes))
        trajectory = self.executor.trajectory()
        if trajectory is not None:
            import json

            import numpy as np

            from .faults.records import corridor_arrays

            trajectory["corridors_json"] = np.array(json.dumps(self.world.corridor_log))
            trajectory.update(corridor_arrays(self.world))
        return EpisodeResult(metrics=metrics, events=self.world.events, planned=self.planned,
                             actual=self.actual, world=self.world, trajectory=trajectory,
                             headings=self.headings if self._rot else None,
                             plan_s=list(self.metrics.plan_s))

    # ------------------------------------------------------------------------- helpers

    def _view(self) -> TickView:
        return tick_view(self.world)

    def _apply_report(self, report: StepReport) -> None:
        apply_report(self.world, report)

    def _apply_faults(self) -> None:
        """Repairs due, then scheduled failures, then random ones: each stage drawn by the
        fault model from the world as the stage before left it, and applied here."""
        w, model = self.world, self.faults
        w.fault_stats["down_ticks"] += sum(1 for a in w.agvs if a.state == AgvState.FAILED)
        for ev in model.repairs(w.tick, w.agvs):
            close_failure(w, ev.agv)
        for stage in (model.scheduled, lambda tick, agvs: model.random(agvs)):
            for ev in stage(w.tick, w.agvs):
                open_failure(w, ev.agv, ev.repair_ticks, self.executor, self._view())

    def _send_out(self) -> None:
        """AGVs caught inside an open corridor go to the nearest free spot outside it
        (:func:`~warerover_phys.faults.exits.exit_spots`), as a yield goal the planner
        plans like any other; sent again if the spot is lost or the yield runs out."""
        w, sent = self.world, self._exit_sent
        for aid in [a for a in sent if inside_open_corridor(w, a) is None]:
            del sent[aid]
        if not w.corridors:
            return
        live = {a: s for a, s in sent.items()
                if w.agvs[a].yield_goal == s and w.tick < w.agvs[a].yield_until}
        for aid, spot in exit_spots(w, live).items():
            agv = w.agvs[aid]
            agv.yield_goal, agv.yield_until, agv.retry_at = spot, w.tick + YIELD_TICKS, w.tick
            sent[aid] = spot
            w.log("corridor_exit_sent", agv=aid, corridor=inside_open_corridor(w, aid),
                  spot=list(w.cell(spot)))

    def _take_ready(self) -> None:
        """Commit the pending plan whose time has come (at once without a latency)."""
        pending = self.clock.take_ready(self.world.tick)
        if pending is None:
            return
        request, result = pending.request, pending.result
        if request.tick == self.world.tick == pending.call_tick:
            self._take(result, request.agents)
            return
        # a late plan: splice each AGV's new path behind the prefix it kept
        w = self.world
        paths, dropped = {}, []
        for aid, path in result.paths.items():
            agv = w.agvs[aid]
            new = splice(w.reservations.paths.get(aid), path, w.tick, agv.pos)
            if new is None or agv.state == AgvState.FAILED:
                dropped.append(aid)
            else:
                paths[aid] = new
        if dropped:
            for aid in hold_back(paths, w.reservations.paths, dropped,
                                 {a.id: a.k for a in w.agvs}, w.layout.cols, w.tick):
                del paths[aid]
                dropped.append(aid)
        self.metrics.plans_dropped += len(dropped)
        self._take(replace(result, paths=paths), request.agents, keep_delay=True)

    def _short_of_plan(self, k: int) -> bool:
        """Whether some AGV whose committed path does not end on its goal has fewer than
        ``k`` ticks of it left (``planner.invoke: event:K``)."""
        w = self.world
        for agv in w.agvs:
            if agv.state not in MOVING_STATES:
                continue
            path = w.reservations.paths.get(agv.id)
            goal = _goal_now(w, agv)
            if goal is None or path is None or path.goal == goal:
                continue
            if path.end_tick - (w.tick - agv.delay) < k:
                return True
        return False

    def _count_plan_waits(self) -> None:
        """AGVs standing at the end of their committed paths short of their goals, with
        the planner called seldom or slow (``plan_wait_agv_s``)."""
        clock = self.clock
        if clock.kind == "every_tick" and not clock.delayed:
            return
        w = self.world
        for agv in w.agvs:
            if agv.state not in MOVING_STATES or not agv.standing:
                continue
            goal = _goal_now(w, agv)
            path = w.reservations.paths.get(agv.id)
            if goal is not None and goal != agv.node and (
                    path is None or path.end_tick <= w.tick - agv.delay):
                clock.wait_agv_ticks += 1

    def _take(self, result: PlanResult, agents: list[AgentRequest],
              keep_delay: bool = False) -> None:
        """Take what the planner returned for the AGVs that needed planning (a new goal, a
        path that ran out short of its goal, blocked for ``replan_blocked_ticks``; every
        AGV for step planners): the planner worked on a copy of the reservations; the paths
        it returns are committed here. ``keep_delay``: the paths keep the ticks of the
        paths they replace (a spliced late plan), so the AGVs stay as late as they were."""
        w = self.world
        self._commit(result, agents)
        for aid, path in result.paths.items():
            agv = w.agvs[aid]
            if not keep_delay:
                agv.delay = 0
            agv.blocked_ticks = agv.plan_failures = 0
            if len(path.states) > 1 or not self._lifelong:
                entry = {"agv": aid, "tick": path.start_tick,
                         "states": [list(s) for s in path.states]}
                if path.headings is not None:
                    entry["headings"] = list(path.headings)
                self.planned.append(entry)
        for aid in result.failed:
            agv = w.agvs[aid]
            agv.plan_failures += 1
            agv.retry_at = w.tick + min(agv.plan_failures, 4)
            spot = self._exit_sent.get(aid)
            if spot is not None:  # leaving a corridor: no time to lose
                agv.retry_at = w.tick + 1
                self._make_way_for(agv, spot)
            elif agv.plan_failures % STUCK_FAILURES == 0:
                self._make_way_for(agv)
        self.metrics.replans_this_tick(len(result.paths), len(result.failed),
                                       len(result.detours), result.budget_hits)

    def _commit(self, result: PlanResult, agents: list[AgentRequest]) -> None:
        """Commit the returned paths (the loop is the only writer of the reservations), in
        the request's order. An AGV the planner could not plan keeps its path, committed
        again in its turn so that it holds its cells as a fresh commit would."""
        if not isinstance(result, PlanResult):
            raise TypeError(f"planner {self.planner.name!r} returned "
                            f"{type(result).__name__}, not PlanResult")
        res, asked = self.world.reservations, {a.agv for a in agents}
        stray = set(result.paths) - asked
        if stray:
            raise ValueError(f"planner {self.planner.name!r} returned paths for AGVs "
                             f"{sorted(stray)}, which it was not asked to plan")
        if self._rot:
            flat = sorted(aid for aid, p in result.paths.items() if aid in self._rot and (
                p.headings is None or len(p.headings) != len(p.states)))
            if flat:
                raise ValueError(f"planner {self.planner.name!r} returned paths without one "
                                 f"heading per state for the rotation-aware AGVs {flat} "
                                 "(planner.rotations: true): it does not plan rotations")
        failed = set(result.failed)
        for a in agents:
            path = result.paths.get(a.agv)
            if path is not None:
                old = res.paths.get(a.agv)
                if old is not None and _stays_put(old, path):
                    continue  # the same from here on: the executor sees no new plan
                res.commit(path, a.k, a.heading)
            elif a.agv in failed and a.agv in res.paths:
                res.commit(res.paths[a.agv], a.k)

    @property
    def _lifelong(self) -> bool:
        return self.planner.replans_all

    def _grid_intrusions(self) -> None:
        """On the grid, an AGV is inside a corridor when one of its cells is a corridor cell
        (checked once per tick, after the move: the check covers the tick just run)."""
        from .faults.intrusion_log import record_check

        w = self.world
        cols = w.layout.cols
        hits = []
        for cid, corridor in w.corridors.items():
            for agv in w.agvs:
                if agv.id == corridor.agv:
                    continue
                inside = len(corridor.cells.intersection(occupancy(agv.pos, agv.k, cols)))
                if inside:
                    hits.append((agv.id, cid, float(inside)))
        tick_s = self.scenario.tick_s
        record_check(w, hits, (w.tick - 1) * tick_s, tick_s, unit="cells")

    def _recover(self, freezes: list) -> None:
        """The executor found AGVs frozen (``freeze.Freeze``): count and log the freeze,
        re-anchor each standing AGV's reservation where it really stands and replan them
        all now, from their actual poses. A group frozen again is broken up: AGVs that
        wait on the route of a frozen AGV are sent to a nearby spot for a while
        (:meth:`_make_way_for`)."""
        w = self.world
        for fz in freezes:
            agvs = [int(a) for a in fz.agvs]
            self.freezes.append({"tick": w.tick, "agvs": agvs, "since": int(fz.since_tick)})
            w.log("freeze", agvs=agvs, since=int(fz.since_tick),
                  waits={str(a): [int(b) for b in fz.waits.get(a, ())] for a in agvs})
            again = False
            for aid in agvs:
                agv = w.agvs[aid]
                self._freeze_hits[aid] = self._freeze_hits.get(aid, 0) + 1
                again |= self._freeze_hits[aid] > 1
                if agv.standing and agv.state in MOVING_STATES and not self.clock.delayed:
                    # (With a planning latency the loop plans ahead from the paths'
                    # positions; an AGV put back where it stands would contradict the
                    # paths the others were given around it.)
                    w.reservations.commit(TimedPath(aid, w.tick, (agv.pos,)), agv.k)
            self._replan_now([a for a in agvs if w.agvs[a].state in MOVING_STATES])
            if again:
                before = {a.id: a.yield_goal for a in w.agvs}
                for aid in agvs:
                    if w.agvs[aid].state in MOVING_STATES and w.agvs[aid].yield_goal is None:
                        self._make_way_for(w.agvs[aid])
                self._freeze_yields |= {a.id for a in w.agvs
                                        if a.yield_goal is not None and before[a.id] is None}

    def _replan_now(self, agvs: list[int]) -> None:
        """The executor saw a deadlock or a deviation: replan these AGVs at once (once they
        stand), as if they had been blocked for ``replan_blocked_ticks``."""
        for aid in agvs:
            agv = self.world.agvs[aid]
            agv.delay = max(agv.delay, 1)
            agv.blocked_ticks = max(agv.blocked_ticks, self.scenario.planner.replan_blocked_ticks)
            agv.retry_at = min(agv.retry_at, self.world.tick)

    def _follow_up(self, blocked: list[int]) -> None:
        w = self.world
        blocked_set = set(blocked)
        cols = w.layout.cols
        for agv in w.agvs:
            if agv.id in self._rot:
                self._track_heading(agv)
            elif agv.id in self._heading:
                (pa, pb), (a, b) = self.actual[agv.id][-1], agv.pos
                src, dst = (a, b) if a != b else (pa, a) if pa == pb else (a, a)
                if src != dst:
                    r0, c0 = divmod(src, cols)
                    r1, c1 = divmod(dst, cols)
                    if abs(r1 - r0) + abs(c1 - c0) == 1:
                        self._heading[agv.id] = (r1 - r0, c1 - c0)
            self.actual[agv.id].append(agv.pos)
            agv.blocked_ticks = agv.blocked_ticks + 1 if agv.id in blocked_set else 0


    def _track_heading(self, agv: Agv) -> None:
        """The heading of a rotation-aware AGV after the tick: its plan's at the state it
        has reached (a planned turn changes it in place), else its last move's direction.
        The same on every executor: the physics executor turns a body itself before each
        move (towards the move), so a planned turn counts as done once its ticks are
        over, wherever the body points meanwhile."""
        w = self.world
        aid = agv.id
        path = w.reservations.paths.get(aid)
        idx = w.tick - agv.delay
        h = None
        if path is not None and path.headings is not None and path.state_at(idx) == agv.pos:
            h = path.heading_at(idx)
        if h is None:
            (pa, pb), (a, b) = self.actual[aid][-1], agv.pos
            src, dst = (a, b) if a != b else (pa, a) if pa == pb else (a, a)
            h = DIR_OF[self._heading[aid]]
            if src != dst:
                r0, c0 = divmod(src, w.layout.cols)
                r1, c1 = divmod(dst, w.layout.cols)
                if abs(r1 - r0) + abs(c1 - c0) == 1:
                    h = DIR_OF[(r1 - r0, c1 - c0)]
        self._heading[aid] = _DIRS[h]
        self.headings[aid].append(h)


_DIRS = ((0, 1), (1, 0), (0, -1), (-1, 0))


def _stays_put(old: TimedPath, new: TimedPath) -> bool:
    """Whether ``new`` only stands, facing one way, where ``old`` has ended by ``new``'s
    start: the same path from then on (a step planner's wait)."""
    s = new.states[0]
    if s[0] != s[1] or old.end_tick > new.start_tick or old.states[-1] != s \
            or any(x != s for x in new.states):
        return False
    if new.headings is None:
        return old.headings is None
    return old.headings is not None and all(h == old.headings[-1] for h in new.headings)


def failure_cause(world: World, freezes: list[dict]) -> dict:
    """Why an episode failed (``failure_cause``, ``failure_detail``; both None on success).

    - ``fault``: an AGV holding unfinished orders is down at the end;
    - ``deadlock``: an AGV holding unfinished orders was found frozen and has not
      finished a task stage since (the freeze detector's last word on it);
    - ``timeout``: ``max_ticks`` came first while work still went on (pending orders no
      AGV took, or AGVs still on their way).
    """
    unfinished = [o for o, s in world.status.items() if s != OrderStatus.COMPLETED]
    if not unfinished:
        return {"failure_cause": None, "failure_detail": None}
    holders = {}
    for agv in world.agvs:
        trip = agv.trip if agv.trip is not None else None
        if trip is not None and any(o in unfinished for o in trip.orders):
            holders[agv.id] = agv
    pending = sum(1 for o in unfinished if world.status[o] == OrderStatus.PENDING)
    counts = (f"{len(unfinished)} of {len(world.status)} orders unfinished ({pending} "
              f"pending, {len(unfinished) - pending} on AGVs {sorted(holders)})")
    down = sorted(a for a, agv in holders.items() if agv.state == AgvState.FAILED)
    if down:
        return {"failure_cause": "fault",
                "failure_detail": f"AGVs {down} down at the end; {counts}"}
    last_work: dict[int, int] = {}
    for e in world.events:
        if e["event"] in ("work_done", "trip_started"):
            last_work[e["agv"]] = e["tick"]
    frozen = set()
    for fz in freezes:
        for a in fz["agvs"]:
            if a in holders and last_work.get(a, -1) <= fz["tick"]:
                frozen.add(a)
    if frozen:
        last = max(fz["tick"] for fz in freezes if frozen & set(fz["agvs"]))
        return {"failure_cause": "deadlock",
                "failure_detail": f"AGVs {sorted(frozen)} frozen (last found at tick {last}) "
                                  f"and never recovered; {counts}"}
    return {"failure_cause": "timeout",
            "failure_detail": f"max_ticks {world.scenario.max_ticks} reached; {counts}"}


def run_episode(scenario: Scenario, seed: int | None = None,
                progress: Callable[[int, int, int], None] | None = None) -> EpisodeResult:
    """Run one episode of ``scenario`` (with ``seed`` if given) to the end."""
    return Simulation(scenario, seed).run(progress)


