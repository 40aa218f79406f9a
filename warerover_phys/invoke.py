"""When the loop calls the planner, and how long its answer takes in simulated time.

``planner.invoke`` (:func:`~warerover_phys.config.parse_invoke`):

- ``every_tick``: at every tick (step planners move every AGV; the others plan the AGVs that
  need a path);
- ``periodic:S``: every ``S`` seconds of simulated time (``round(S / tick_s)`` ticks, at
  least one);
- ``event:K``: when some AGV whose committed path does not end on its goal has fewer than
  ``K`` ticks of it left (counted from where it really is: its path's end tick less the
  current tick less the ticks it runs behind).

With ``periodic`` and ``event`` a step planner plans ``window_ticks`` steps a call
(:func:`plan_window`: windowed PIBT, as LSMART runs it), the others whole paths as always.

``planner.latency`` (:func:`~warerover_phys.config.parse_latency`): ``none`` — the world
waits while the planner computes (its time is not simulated time). ``measured`` or
``fixed:S`` — the planner takes simulated time: ``L`` = its wall-clock seconds, or ``S``.
A call made at tick ``t`` then plans from where the AGVs' committed paths are at the
expected effect tick ``t_eff = t + D`` (``D`` = ``ceil(L / tick_s)`` of the previous call,
at least 1; for ``fixed`` exactly that), and the loop cuts their committed paths there: the
committed prefix stays, the AGVs stop at its end. The plan is ready at ``t + L / tick_s``
and takes effect at the first tick after that, ``t_r >= t_eff``: each AGV's new path is its
old path up to ``t_eff``, a wait until ``t_r``, then the new plan (:func:`splice`). While a
plan is pending the planner is busy and is not called again. Time the AGVs stand with
nothing planned while they have somewhere to go is counted as ``plan_wait_agv_s`` (the
cost of a slow or seldom planner).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .config import PlannerSpec, parse_invoke, parse_latency
from .planning.base import PlanRequest, PlanResult, State, TimedPath
from .planning.paths import occupancy

__all__ = ["PlanClock", "Pending", "hold_back", "plan_window", "splice"]

_DIRS = ((0, 1), (1, 0), (0, -1), (-1, 0))


@dataclass
class Pending:
    """A plan computed and not yet in effect."""

    request: PlanRequest
    result: PlanResult
    call_tick: int
    ready_tick: int


class PlanClock:
    """``planner.invoke`` and ``planner.latency`` of one episode (see the module docstring)."""

    def __init__(self, spec: PlannerSpec, tick_s: float) -> None:
        self.kind, value = parse_invoke(spec.invoke)
        self.latency, self.fixed_s = parse_latency(spec.latency)
        self.tick_s = tick_s
        self.period = max(1, round(value / tick_s)) if self.kind == "periodic" else 1
        self.k_left = int(value) if self.kind == "event" else 0
        auto = {"every_tick": 1, "periodic": 2 * self.period, "event": 2 * self.k_left}
        self.window = spec.window_ticks or max(1, auto[self.kind])
        self.pending: Pending | None = None
        self.last_call: int | None = None
        self._ahead = self._ticks(self.fixed_s) if self.latency == "fixed" else (
            1 if self.latency == "measured" else 0)
        self.calls_s: list[float] = []
        self.delay_ticks: list[int] = []
        """Per call that took effect: ticks from the call to its plan's effect."""
        self.wait_agv_ticks = 0

    def _ticks(self, seconds: float) -> int:
        return max(0, math.ceil(seconds / self.tick_s - 1e-9))

    @property
    def delayed(self) -> bool:
        """Whether the planner's time is simulated time."""
        return self.latency != "none"

    def due(self, tick: int, short_of_plan) -> bool:
        """Whether to call the planner at ``tick`` (``short_of_plan(k)``: whether some AGV
        has fewer than ``k`` ticks of its path left short of its goal)."""
        if self.pending is not None:
            return False
        if self.last_call is None or self.kind == "every_tick":
            return True
        if self.kind == "periodic":
            return tick - self.last_call >= self.period
        return short_of_plan(self.k_left)

    def effect_tick(self, tick: int) -> int:
        """The tick a plan asked for at ``tick`` is expected to take effect."""
        if not self.delayed:
            return tick
        return tick + max(self._ahead, 1 if self.latency == "measured" else 0)

    def called(self, tick: int, request: PlanRequest, result: PlanResult,
               wall_s: float) -> Pending:
        """The planner answered ``request`` (asked at ``tick``) after ``wall_s`` seconds: the
        plan that goes into effect at its ready tick."""
        self.last_call = tick
        self.calls_s.append(wall_s)
        if not self.delayed:
            ready = tick
        else:
            took = self.fixed_s if self.latency == "fixed" else wall_s
            ticks = self._ticks(took)
            if self.latency == "measured":
                ticks = max(1, ticks)
                self._ahead = ticks
            ready = max(request.tick, tick + ticks)
        self.pending = Pending(request, result, tick, ready)
        return self.pending

    def take_ready(self, tick: int) -> Pending | None:
        """The pending plan if its time has come at ``tick`` (and the planner is free)."""
        p = self.pending
        if p is None or p.ready_tick > tick:
            return None
        self.pending = None
        self.delay_ticks.append(tick - p.call_tick)
        return p

    def summary(self) -> dict:
        ms = np.asarray(self.calls_s) * 1e3
        return {
            "planner_invoke": f"{self.kind}" + (f":{self.period * self.tick_s:g}"
                                                if self.kind == "periodic" else
                                                f":{self.k_left}" if self.kind == "event"
                                                else ""),
            "planner_latency": self.latency + (f":{self.fixed_s:g}" if self.latency == "fixed"
                                               else ""),
            "planner_window_ticks": self.window,
            "planner_calls": len(self.calls_s),
            "ct_plan_call_mean_ms": float(ms.mean()) if ms.size else 0.0,
            "ct_plan_call_p99_ms": float(np.percentile(ms, 99)) if ms.size else 0.0,
            "plan_effect_ticks_mean": float(np.mean(self.delay_ticks))
            if self.delay_ticks else 0.0,
            "plan_wait_agv_s": self.wait_agv_ticks * self.tick_s,
        }


def cut(path: TimedPath, tick: int) -> TimedPath:
    """``path`` up to ``tick`` (the AGV stops where the path is then; a move in progress at
    ``tick`` is finished first)."""
    j = tick - path.start_tick
    if j < 0 or j >= len(path.states) - 1:
        return path
    while j < len(path.states) - 1 and path.states[j][0] != path.states[j][1]:
        j += 1
    heads = path.headings[:j + 1] if path.headings is not None else None
    return TimedPath(path.agv, path.start_tick, path.states[:j + 1], heads)


def splice(old: TimedPath | None, new: TimedPath, t_r: int, now: State) -> TimedPath | None:
    """The AGV's path once ``new`` (planned to start at ``new.start_tick`` = t_eff) takes
    effect at ``t_r``: ``old`` up to t_eff (to the end of a move under way then), a wait at
    ``new``'s first state until ``t_r``, then ``new``; ``old`` from the AGV's state ``now``
    (what it still has to drive; earlier states are history): the end of the first run of
    ``now`` in ``old``, since a path may come back to ``now`` (a side step and back) and
    the AGV behind its plan has not made that side step yet (the executor skips what it has
    already driven, :meth:`~warerover_phys.executors.follow_sync.PlanSync._cut`).
    None if ``old`` does not reach ``new``'s first state at t_eff (it was changed meanwhile:
    the AGV keeps ``old`` and is planned again)."""
    first = new.states[0]
    if old is None:
        return TimedPath(new.agv, t_r, new.states, new.headings)
    j = new.start_tick - old.start_tick  # t_eff in old's states
    while 0 <= j < len(old.states) - 1 and old.states[j][0] != old.states[j][1]:
        j += 1  # a move under way at t_eff is finished first
    if j < 0 or old.state_at(old.start_tick + j) != first:
        return None
    t_eff = old.start_tick + j
    t_r = max(t_r, t_eff)
    s0 = old.start_tick
    last = min(j, len(old.states) - 1)
    for k in range(last + 1):
        if old.states[k] == now:
            while k < last and old.states[k + 1] == now:
                k += 1
            s0 = old.start_tick + k
            break
    states = tuple(old.state_at(t) for t in range(s0, t_eff)) + (first,) * (t_r - t_eff) \
        + new.states
    heads = None
    if new.headings is not None:
        h0 = new.headings[0]
        before = tuple(old.heading_at(t) if old.headings is not None else h0
                       for t in range(s0, t_eff))
        heads = before + (h0,) * (t_r - t_eff) + new.headings
    return TimedPath(new.agv, s0, states, heads)


def hold_back(spliced: dict[int, TimedPath], old: dict[int, TimedPath], dropped: list[int],
              sizes: dict[int, int], cols: int, tick: int) -> list[int]:
    """The AGVs of a late joint plan that must keep their old paths too, because the AGVs
    ``dropped`` keep theirs (their splice failed: their paths changed while the plan was
    computed) and the joint plan assumed they would move. ``spliced``: the new paths of the
    others; ``old``: every AGV's path before the plan (each stops at the call's effect
    tick); ``sizes``: footprints; ``tick``: now. An AGV whose new path covers a cell that a
    kept path covers at the same tick (from ``tick`` on) keeps its old path as well, and
    so on until none does: the old paths stop on cells of one collision-free
    configuration, so the paths left are collision-free in plan time and the executor's
    dependency graph stays acyclic. Returns the AGVs to hold back, in the order found."""
    if not dropped:
        return []
    end = max((p.end_tick for p in spliced.values()), default=tick)
    held: dict[tuple[int, int], int] = {}

    def hold(aid: int) -> None:
        path = old.get(aid)
        if path is None:
            return
        for t in range(max(tick, path.start_tick), end + 1):
            for c in occupancy(path.state_at(t), sizes[aid], cols):
                held[(t, c)] = aid

    for aid in dropped:
        hold(aid)
    out: list[int] = []
    todo = dict(spliced)
    changed = True
    while changed:
        changed = False
        for aid, path in list(todo.items()):
            k = sizes[aid]
            if any(held.get((t, c), aid) != aid
                   for t in range(max(tick, path.start_tick), end + 1)
                   for c in occupancy(path.state_at(t), k, cols)):
                del todo[aid]
                out.append(aid)
                hold(aid)
                changed = True
    return out


def plan_window(planner, request: PlanRequest, window: int) -> PlanResult:
    """``window`` steps of a step planner (``replans_all``) from ``request``: each step's
    request starts the AGVs where the step before left them (facing its headings, goals
    one tick older) on the request's scratch reservations; the result holds one path per
    AGV over the window. A planner that plans whole paths, or ``window`` 1: one call."""
    if window <= 1 or not planner.replans_all:
        return planner.plan(request)
    agents = list(request.agents)
    res = request.reservations
    t0 = request.tick
    states: dict[int, list] = {a.agv: [] for a in agents}
    heads: dict[int, list] = {a.agv: [] for a in agents}
    out = PlanResult()
    for k in range(window):
        step = planner.plan(replace(request, tick=t0 + k, agents=agents))
        out.expansions += step.expansions
        out.budget_hits += step.budget_hits
        nxt = []
        for a in agents:
            p = step.paths.get(a.agv)
            if p is None:
                p = TimedPath(a.agv, t0 + k, ((a.start, a.start),))
            if res.paths.get(a.agv) is not p:
                res.commit(p, a.k, a.heading)
            if k == 0:
                states[a.agv].append(p.state_at(t0))
                heads[a.agv].append(p.heading_at(t0))
            s1 = p.state_at(t0 + k + 1)
            h1 = p.heading_at(t0 + k + 1)
            states[a.agv].append(s1)
            heads[a.agv].append(h1)
            prio = (a.priority[0] + 1,) + tuple(a.priority[1:]) if a.priority else ()
            nxt.append(replace(a, start=s1[1], priority=prio,
                               heading=_DIRS[h1] if h1 is not None and h1 < 4 else a.heading))
        agents = nxt
    for aid, sts in states.items():
        hs = heads[aid]
        out.paths[aid] = TimedPath(aid, t0, tuple(sts),
                                   None if any(h is None for h in hs) else tuple(hs))
    return out
