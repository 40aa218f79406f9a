"""Following the dependency graph: which action each AGV drives, and when it may start.

:class:`PlanFollower` hands every new or changed committed plan to the
:class:`~.adg.ActionGraph` (commit cut: the AGV keeps the action it is driving, the rest is
replaced), draws the tick's random delays, and per physics step

- runs the references through the step and finishes turns and actions at the exact times
  their references end them (the rest of the step goes to the next action);
- looks ahead of driving AGVs and pushes their stop point to the end of the released
  collinear run (claiming those actions in the ADG); with ``executor.reorder`` only as far
  as braking before the next look needs, plus a cell, and a delayed AGV gives back the
  claims beyond its braking (the cells further on stay switchable);
- turns standing differential-drive AGVs towards their next move, and starts it once the
  ADG says its cells are free (or, with ``adg: false``, at its planned tick: naive
  time-indexed following, for comparison);
- with ``executor.turn_in_place``: turns in place an AGV whose committed plan only stands
  and turns (all its states on one cell,
  :attr:`~warerover_phys.planning.paths.TimedPath.headings` changing) to the plan's last
  heading, if its turn sweeps no cell beyond its own (the environments' turn actions,
  :mod:`warerover_phys.envs`). Otherwise plan headings are not followed: the AGV turns
  when its next move comes.

At the end of a tick it reports each AGV's discrete state, how far behind it is, blocked
AGVs and AGVs to replan (dependency deadlock, deviation from the path, a plan that did not
fit the commit cut).
"""

from __future__ import annotations

import heapq
import math
from typing import TYPE_CHECKING

import numpy as np

from ..freeze import FreezeDetector
from ..planning.base import TimedPath
from ..planning.paths import footprint_nodes, occupancy
from ..validate import DWELL_HEADING_TOL_RAD, DWELL_POS_TOL_M
from . import control
from .bodies import cell_centre
from .control import ARRIVE_EPS_M, TURN_EPS_RAD, run_references, wrap
from .control_nb import advance_rows
from .delays import delay_draws, held
from .fleet_state import DRIVE, HOLD, TURN, FleetState
from .follow_sync import PlanSync

if TYPE_CHECKING:
    from ..config import ExecutorSpec
    from .accounting import Accounting
    from .adg import Action, ActionGraph
    from .base import StepReport, TickView

__all__ = ["LOOKAHEAD", "DECIDE_S", "PlanFollower"]

_DIRS = ((0, 1), (1, 0), (0, -1), (-1, 0))
"""(d_row, d_col) of each direction index: east, south, west, north."""

LOOKAHEAD = 8
"""Actions looked at (and claimed) ahead of a driving AGV."""
MAX_EVENTS = 6
"""Most events (turn done, action done) one AGV's reference passes in one physics step."""
DECIDE_S = 0.1
"""Simulated seconds between checks of standing AGVs (may they start their next action?):
every ``FleetState.decide_every = round(DECIDE_S / dt)`` physics steps, so that decisions
fall at the same simulated times whatever ``dt_s`` (a fixed number of steps made the
look-ahead and the waits five times longer at dt 0.05 s than at 0.01 s)."""
_NO_ROWS = np.zeros(0, dtype=np.int64)
WORK_TASK_STATES = (2, 4, 6)
"""``TickView.task_state`` values of AGVs working in place (``world.AgvState`` PICKING,
HANDOVER, PLACING)."""


class PlanFollower(PlanSync):
    """Drives the fleet's references through the ADG's actions (see the module docstring)."""

    def __init__(self, st: FleetState, adg: ActionGraph, spec: ExecutorSpec,
                 rng: np.random.Generator, acc: Accounting) -> None:
        self.st, self.adg, self.spec, self.rng, self.acc = st, adg, spec, rng, acc
        self._synced: dict[int, TimedPath | None] = {i: None for i in range(st.n)}
        self._resync: set[int] = set()
        """AGVs whose new plan did not fit their commit cut: replanned once they stand."""
        self._cycles_seen: set[frozenset[int]] = set()
        self._asleep = np.zeros(st.n, dtype=bool)
        """AGVs waiting on the dependency graph that need no decision until woken."""
        self._ext_for: list[Action | None] = [None] * st.n
        """Per AGV the running action at its last :meth:`_extend`, while that answer
        holds."""
        self._given_back: set[int] = set()
        """Delayed driving AGVs that gave back claims (:meth:`_give_back_delayed`)."""
        self._left, self._used = np.empty(st.n), np.empty(st.n)
        self._events = np.empty(st.n, dtype=np.int64)
        """Buffers of one physics step (:meth:`advance`)."""
        self._turn_in_place_on = bool(getattr(spec, "turn_in_place", False))
        self._face: dict[int, int] = {}
        """Standing AGVs to turn in place: AGV -> heading (direction index) of its plan."""
        self._holds: dict[int, dict[int, int]] = {}
        """Planned dwells (``TickView.dwells``): AGV -> action seq -> ticks it must stand
        before that action (from its arrival at the action's start cell)."""
        freeze_s = getattr(spec, "freeze_s", 0.0)
        self.freezes: FreezeDetector | None = FreezeDetector(
            st.n, st.cols, max(1, math.ceil(freeze_s / st.tick_s - 1e-9))) if freeze_s > 0 else None
        """Finds AGVs without progress while nothing they wait on can move
        (``executor.freeze_s``; None: off)."""
        self.reorder = None
        """Switches edges of the graph under delays (``executor.reorder``,
        :mod:`.reorder`; None: off)."""
        if getattr(spec, "reorder", "none") != "none" and spec.adg:
            from .reorder import Reorderer

            self.reorder = Reorderer(st, adg, spec, self._holds, acc)

    # ------------------------------------------------------------------------- per tick

    def draw_delays(self) -> list[tuple[str, dict]]:
        """Start this tick's random delays (``executor.delays``); returns their events."""
        d = self.spec.delays
        if d.model == "none" or d.prob <= 0:
            return []
        st = self.st
        if self.reorder is not None:
            self.reorder.see_delays(self.rng)
        events, ticks = delay_draws(self.rng, d, st.n)
        start = events & ~held(st.delayed_until, st.sim_s, st.dt)
        st.delayed_until[start] = st.sim_s + ticks[start] * st.tick_s
        return [("delay", {"agv": int(i), "ticks": int(ticks[i])}) for i in np.flatnonzero(start)]

    def sync_failed(self, failed: frozenset[int]) -> None:
        """Failed AGVs brake and start nothing."""
        self.st.failed = np.zeros(self.st.n, dtype=bool)
        self.st.failed[list(failed)] = True

    # ------------------------------------------------------------------------- per step

    def advance(self, pos: np.ndarray, ang: np.ndarray, delayed: np.ndarray,
                decide: bool) -> None:
        """One physics step from ``st.sim_s`` for bodies at ``pos`` / ``ang`` (their poses
        now): extend runs and decide for standing AGVs (on every ``st.decide_every`` th
        step, every :data:`DECIDE_S` seconds, when ``decide``), then run the references
        through the step (:func:`~.control.run_references`), finishing turns and actions at
        the exact times their references get there and giving the rest of the step to what
        follows (a move after its turn, the next cell of a run)."""
        st = self.st
        t = st.sim_s
        self.adg.now = t
        if decide:
            if self.reorder is not None:
                self._give_back_delayed(delayed)
                self.reorder.decide(t, delayed)
            # Look further ahead for AGVs that would otherwise start braking before the
            # next look (the margin covers two decision intervals).
            driving = st.mode == DRIVE
            brake = st.speed ** 2 / (2 * st.amax) + 2 * st.vmax * st.dt * st.decide_every
            for i in np.flatnonzero(driving & ~delayed
                                    & (st.stop_s - st.s_ref < brake + 0.05)).tolist():
                self._extend(i, again=True)
            st.waiting[:] = False
            st.listening[:] = False
            # An AGV found waiting on the dependency graph sleeps until the queue head it
            # waits for changes (adg.woken), it is delayed, or its plan changes: deciding
            # for it again before then would find it waiting again.
            self._decide_standing(t, delayed, ang)
            for i in list(self._face):
                if st.mode[i] == HOLD and not st.has_next[i] and not delayed[i] \
                        and not st.failed[i]:
                    self._turn_in_place(i, float(ang[i]))
        left = self._left
        left.fill(st.dt)
        if control.COMPILED:
            self._run_compiled(t, left, delayed)
        else:
            busy = st.mode != HOLD
            for _ in range(MAX_EVENTS):
                idx = np.flatnonzero(busy)
                if len(idx) == 0:
                    break
                used, event = run_references(st, idx, left[idx], delayed[idx])
                left[idx] -= used
                busy[:] = False
                for i in idx[event]:
                    busy[i] = self._event(int(i), t, left, delayed)
        self.adg.now = t

    def _give_back_delayed(self, delayed: np.ndarray) -> None:
        """With reordering: a delayed driving AGV gives back its claims beyond where its
        braking stops it, so the AGVs waiting at those cells may be switched ahead of it
        (its stop point moves back only if one is, or plans change:
        :meth:`.reorder.Reorderer.stop_at_claims`).
        Once its delay is over it claims again what is released to it."""
        st, adg = self.st, self.adg
        for i in sorted(self._given_back):
            if not delayed[i]:
                self._given_back.discard(i)
                if st.mode[i] == DRIVE:
                    self._extend(i)
        for i in np.flatnonzero((st.mode == DRIVE) & delayed).tolist():
            claimed = adg.claimed(i)
            if not claimed:
                continue
            over = st.s_ref[i] + st.speed[i] ** 2 / (2 * st.amax[i]) - st.cur_end[i]
            keep = max(0, math.ceil(over / st.cell_m - 1e-9))
            if keep >= len(claimed):
                continue
            adg.unclaim(i, keep)
            self._given_back.add(i)
            self._ext_for[i] = None

    def _decide_standing(self, t: float, delayed: np.ndarray, ang: np.ndarray) -> None:
        """Decide, in id order, for the standing AGVs with a next action, except those
        asleep: found waiting on the dependency graph before, they sleep until the queue
        head they wait for changes (``adg.woken``), they are delayed, or their plan
        changes; deciding for them again before then would find them waiting again, so
        they are marked waiting all at once. (Whether each sleeps is read up front:
        :meth:`_decide` changes only its own AGV's ``asleep``. ``woken`` may grow while
        deciding: an AGV woken then, after the one decided, is decided in its turn.)"""
        st = self.st
        asleep, woken = self._asleep, self.adg.woken
        cand = np.flatnonzero((st.mode != DRIVE) & st.has_next)
        sleeps = asleep[cand] & ~delayed[cand]
        sleepers = cand[sleeps]
        st.waiting[sleepers] = True
        sleeping = set(sleepers.tolist())
        todo = cand[~sleeps].tolist()
        if woken:
            todo += [i for i in woken if i in sleeping]
            todo.sort()
        known = len(woken)
        decided: set[int] = set()
        while todo:
            i = heapq.heappop(todo)
            if i in decided:
                continue
            decided.add(i)
            if i in sleeping:
                st.waiting[i] = False
            asleep[i] = False
            self._decide(i, t, bool(delayed[i]), float(ang[i]))
            if len(woken) != known:  # (rare) woken grew: those after i decide in turn
                known = len(woken)
                for j in woken:
                    if j > i and j in sleeping and j not in decided:
                        heapq.heappush(todo, j)
        woken.clear()

    def _run_compiled(self, t: float, left: np.ndarray, delayed: np.ndarray) -> None:
        """:meth:`advance`'s event loop with the compiled references
        (:func:`.control_nb.advance_rows`): one kernel call for the whole fleet, then one
        per round of events (the AGVs that go on after an event, in ascending order, as the
        numpy loop takes them)."""
        st = self.st
        used, events = self._used, self._events
        idx, all_rows = _NO_ROWS, True
        delayed = np.ascontiguousarray(delayed, dtype=np.bool_)
        for _ in range(MAX_EVENTS):
            k = advance_rows(all_rows, idx, left, delayed, st.mode, st.heading, st.ang_ref,
                             st.wmax, st.amax, st.vmax, st.s_ref, st.stop_s, st.cur_end,
                             st.speed, used, events)
            all_rows = False
            nxt = [i for i in events[:k].tolist() if self._event(i, t, left, delayed)]
            if not nxt:
                break
            idx = np.array(nxt, dtype=np.int64)

    def _event(self, i: int, t: float, left: np.ndarray, delayed: np.ndarray) -> bool:
        """AGV ``i``'s reference stopped at an event (``left[i]`` seconds before the step's
        end): finish its turn or action there. Returns whether it goes on in this step."""
        st = self.st
        t_ev = t + st.dt - left[i]
        self.adg.now = t_ev
        if st.mode[i] == TURN:
            st.mode[i] = HOLD
            self._decide(i, t_ev, bool(delayed[i]), float(st.heading[i]))
        else:
            self._arrive(i, t_ev)
        return bool(st.mode[i] != HOLD and left[i] > 0)

    def _decide(self, i: int, t: float, delayed: bool, angle: float) -> None:
        """A standing (or turning) AGV: turn towards its next move, then start it once the
        ADG allows it (or its planned tick has come, without the ADG)."""
        st = self.st
        nxt = self.adg.next_action(i)
        if nxt is None:
            return
        if not st.omni[i]:
            want = math.atan2(nxt.direction[0], nxt.direction[1])
            if abs(wrap(want - angle)) >= TURN_EPS_RAD:
                if not delayed:
                    if nxt.sweeps and self.spec.adg and not self.adg.ready(i):
                        # Its turn sweeps beyond its cells: only once those are its own.
                        st.mode[i] = HOLD
                        if self.adg.listening(i):
                            st.listening[i] = True
                            return
                        st.waiting[i] = True
                        self._asleep[i] = self.adg.wait_on(i)
                        return
                    if nxt.sweeps and self.spec.adg:
                        self.adg.claim(i, 1)  # no AGV may go ahead of it mid-turn
                    # The heading is kept unwrapped so the turn's direction is fixed at
                    # its start; a half turn always goes counter-clockwise (its direction
                    # must not depend on float noise in the body's angle).
                    turn = float(wrap(want - angle))
                    if turn < -math.pi + 1e-6:
                        turn += 2 * math.pi
                    st.ang_ref[i] = angle
                    st.heading[i] = angle + turn
                    st.mode[i] = TURN
                    self.adg.set_heading(i, nxt.direction)
                else:
                    st.mode[i] = HOLD
                return
        if t + 1e-9 < st.hold_until[i]:
            return  # a planned dwell (pick, hand-over, place, parking) is not over
        if delayed:
            return
        if self.spec.adg:
            if not self.adg.ready(i):
                if self.adg.listening(i):
                    # Its cells are free; the message saying so is on its way
                    # (executor.comm_latency_s): decide again at the next look.
                    st.listening[i] = True
                    return
                st.waiting[i] = True
                self._asleep[i] = self.adg.wait_on(i)
                return
        elif t + 1e-9 < nxt.tick * st.tick_s:
            return
        self._start(i, t)

    def _turn_in_place(self, i: int, angle: float) -> None:
        """Turn standing AGV ``i`` to the heading its plan ends in (``_face``)."""
        d = self._face.pop(i)
        dr, dc = _DIRS[d]
        want = math.atan2(dr, dc)
        turn = float(wrap(want - angle))
        if abs(turn) < TURN_EPS_RAD:
            return
        if turn < -math.pi + 1e-6:
            turn += 2 * math.pi
        st = self.st
        st.ang_ref[i] = angle
        st.heading[i] = angle + turn
        st.mode[i] = TURN
        self.adg.set_heading(i, (dr, dc))

    def _start(self, i: int, t: float) -> None:
        st = self.st
        # It is awake: a decide in mid-turn may have put it to sleep just before its turn
        # ended and it started in the same step (a stale flag would keep it asleep later).
        self._asleep[i] = False
        a = self.adg.start(i) if self.spec.adg else self._force_start(i)
        x, y = cell_centre(a.src, st.k[i], st.cols, st.cell_m)
        st.origin[i] = (x, y)
        st.direction[i] = (a.direction[1], a.direction[0])
        st.cur_end[i] = st.cell_m
        st.stop_s[i] = st.cell_m
        st.mode[i] = DRIVE
        st.speed[i] = 0.0
        st.s_ref[i] = 0.0
        if not st.omni[i]:
            st.heading[i] = math.atan2(a.direction[0], a.direction[1])
        self._begin_action(i, a, t)
        self._extend(i)

    def _force_start(self, i: int) -> Action:
        """Naive following: start the next action whatever its dependencies say."""
        return self.adg.start(i, force=True)

    def _begin_action(self, i: int, a: Action, t: float) -> None:
        self.st.has_next[i] = self.adg.next_action(i) is not None
        self.acc.action_begun(i, a, t)

    def _extend(self, i: int, again: bool = False) -> None:
        """Push the stop point to the end of the released collinear run ahead.

        ``again``: a look from the decision steps, which may find nothing changed since
        the last: then it is skipped. The answer depends only on the running action, the
        AGV's plan and dwells, the loaded AGVs and the queue of the cell where the released
        actions stopped, so it is kept (``_ext_for``) until one of these changes (the ADG's
        ``ext_woken``, :meth:`~.adg.ActionGraph.wait_release`); never with a
        communication latency (then it is also a matter of time)."""
        st, adg = self.st, self.adg
        cur = adg.current(i)
        if cur is None:
            return
        if again and self._ext_for[i] is cur and i not in adg.ext_woken:
            return
        run = 0
        if self.spec.adg:
            adg.ext_woken.discard(i)
            ahead = adg.released(i, LOOKAHEAD)
            stop = adg.released_stop
        else:
            limit = (st.sim_s / st.tick_s) + 1
            ahead = [a for a in self.adg.upcoming(i, LOOKAHEAD) if a.tick <= limit]
        holds = self._holds.get(i, {})
        for a in ahead:
            if a.direction != cur.direction or a.seq in holds:
                break  # a turn, or a planned dwell before this action: stop here
            run += 1
        capped = False
        if self.reorder is not None and run:
            # Reordering: claim (and stop) only as far as the AGV must look ahead not to
            # brake before its next look, plus a cell; the cells beyond stay switchable.
            over = (st.s_ref[i] + st.speed[i] ** 2 / (2 * st.amax[i])
                    + 2 * st.vmax[i] * st.dt * st.decide_every + 0.05 - st.cur_end[i])
            cap = max(0, math.ceil(over / st.cell_m - 1e-9)) + 1
            if run > cap:
                run, capped = cap, True
        if self.spec.adg and run:
            # Committed: no later plan may put another AGV ahead of it on these cells.
            adg.claim(i, run, released=ahead)
        st.stop_s[i] = st.cur_end[i] + run * st.cell_m
        if capped:
            self._ext_for[i] = None  # look again as it drives on
            return
        if self.spec.adg and adg.latency_s == 0:
            if run == len(ahead) and stop is not None:
                if stop is False:
                    self._ext_for[i] = None
                    return
                adg.wait_release(i, stop)
            self._ext_for[i] = cur  # a turn, a dwell, the look-ahead or the plan's end

    def _arrive(self, i: int, t: float) -> None:
        st = self.st
        done = self.adg.finish(i)
        st.last_finish[i] = t
        self.acc.action_done(i, t)
        nxt = self.adg.next_action(i)
        hold = self._holds.get(i, {}).get(nxt.seq) if nxt is not None else None
        if hold:
            st.hold_until[i] = t + hold * st.tick_s
        if nxt is not None and nxt.direction == done.direction and not st.failed[i] and \
                st.stop_s[i] > st.cur_end[i] + ARRIVE_EPS_M:
            a = self.adg.start(i) if self.spec.adg and self.adg.ready(i) else (
                None if self.spec.adg else self._force_start(i))
            if a is not None:
                st.cur_end[i] += st.cell_m
                self._begin_action(i, a, t)
                return
        st.mode[i] = HOLD
        self.adg.unclaim(i)  # it stops here: claims further on are stale
        st.hold_xy[i] = cell_centre(done.dst, st.k[i], st.cols, st.cell_m)
        st.stop_s[i] = st.cur_end[i]

    # ------------------------------------------------------------------------- back to the grid

    def write_back(self, view: TickView, pos: np.ndarray, report: StepReport) -> None:
        """Fill ``report`` with every AGV's discrete state, lateness, blocked AGVs and AGVs
        to replan (deviation from the path line, stale plans, dependency deadlocks)."""
        st, acc = self.st, self.acc
        tick_next = view.tick + 1
        states, late, has_next, running = self.adg.progress(st.n, tick_next)
        report.states.update(enumerate(states))
        cut = self.adg.cut_node
        report.committed.update((i, c) for i, c in ((i, cut(i)) for i in range(st.n)
                                                    if running[i] or has_next[i])
                                if c != states[i][1])
        report.behind.update(enumerate(map(int, late)))
        report.blocked.extend(np.flatnonzero(st.waiting).tolist())
        # Distance of driving bodies from their path line (across the move direction).
        rel = pos - st.origin
        off = np.abs(rel[:, 0] * -st.direction[:, 1] + rel[:, 1] * st.direction[:, 0])
        deviated = np.flatnonzero((st.mode == DRIVE) & (off > self.spec.deviation_m))
        acc.deviations += len(deviated)
        report.replan.extend(deviated.tolist())
        pending = np.array(has_next, dtype=bool)
        st.pending = pending
        report.settled = self.settled(pending, report.poses, np.array(running, dtype=bool))
        for i in sorted(self._resync):
            if i not in report.replan:
                report.replan.append(i)
        self._resync.clear()
        cycles = self.adg.deadlock_cycles() if self.spec.adg else []
        seen = set()
        for cyc in cycles:
            key = frozenset(cyc)
            seen.add(key)
            if key not in self._cycles_seen:
                acc.deadlocks += 1
                report.events.append(("deadlock", {"agvs": sorted(cyc)}))
            report.replan.extend(i for i in cyc if i not in report.replan)
        self._cycles_seen = seen
        if self.freezes is not None and view.goals:
            report.freezes = self.freezes.update(
                tick_next, [report.states[i][1] for i in range(st.n)], view.goals,
                [s in WORK_TASK_STATES for s in view.task_state], st.failed,
                lambda: self._waits_on(report, view.goals))
        acc.replans_asked += len(report.replan)
        report.replan.sort()

    def _waits_on(self, report: StepReport, goals: tuple[int | None, ...]
                  ) -> dict[int, set[int]]:
        """Wait-for edges for the freeze detector: the ADG's (an AGV waits on the AGVs
        ahead of it in the queues of the cells it enters next), plus the AGVs standing on
        an AGV's goal (it waits for its goal to be free)."""
        st = self.st
        waits = {a: set(b) for a, b in self.adg.waiting_for().items()} if self.spec.adg else {}
        owner: dict[int, int] = {}
        for i in range(st.n):
            for c in occupancy(report.states[i], int(st.k[i]), st.cols):
                owner[c] = i
        for i, goal in enumerate(goals):
            if goal is None:
                continue
            for c in footprint_nodes(goal, int(st.k[i]), st.cols):
                j = owner.get(c)
                if j is not None and j != i:
                    waits.setdefault(i, set()).add(j)
        return waits

    def settled(self, pending: np.ndarray, poses: np.ndarray | None,
                running: np.ndarray | None = None) -> frozenset[int]:
        """AGVs at rest: standing with no action running or left, not failed, within
        :data:`~warerover_phys.validate.DWELL_POS_TOL_M` of the cell centre they hold and
        :data:`~warerover_phys.validate.DWELL_HEADING_TOL_RAD` of the heading they hold
        (``poses``: (N, 3) x, y, heading at the end of the tick; ``running``: (N,) bool,
        whether an action runs, if known; else the ADG is asked)."""
        st = self.st
        if poses is None:
            return frozenset()
        idle = (st.mode == HOLD) & ~pending & ~st.failed
        if running is None:
            running = np.array([self.adg.current(i) is not None for i in range(st.n)],
                               dtype=bool)
        idle &= ~running
        off = np.hypot(poses[:, 0] - st.hold_xy[:, 0], poses[:, 1] - st.hold_xy[:, 1])
        turn = np.abs(wrap(poses[:, 2] - st.heading))
        ok = idle & (off <= DWELL_POS_TOL_M) & (turn <= DWELL_HEADING_TOL_RAD)
        return frozenset(np.flatnonzero(ok).tolist())

    # ------------------------------------------------------------------------- fault hooks

    def remaining(self, i: int) -> list[tuple[int, int]]:
        """What AGV ``i`` still has to drive, as states (running action, then the rest)."""
        if not self.synced_once(i):
            return []
        out = []
        cur = self.adg.current(i)
        if cur is not None:
            out.append((cur.src, cur.dst))
        out += [(a.src, a.dst) for a in self.adg.upcoming(i)]
        return out

    def stop_short(self, i: int, cells: frozenset[int], view: TickView) -> tuple[bool, bool]:
        """A corridor opened over ``cells``: stop AGV ``i`` as soon as its braking distance
        allows (its later claims are given back). Returns ``(True, enters)``: enters is True
        if the part it can no longer drop (running and still claimed actions) enters
        ``cells``. Before its first plan reaches it, the loop cuts the path instead."""
        if not self.synced_once(i):
            return False, False
        st = self.st
        committed = []
        cur = self.adg.current(i)
        if cur is not None:
            committed.append(cur)
            keep = 0
            if st.mode[i] == DRIVE:
                brake = st.speed[i] ** 2 / (2 * st.amax[i])
                over = st.s_ref[i] + brake - st.cur_end[i]
                keep = max(0, math.ceil(over / st.cell_m - 1e-9))
            claimed = self.adg.claimed(i)
            kept = claimed[:keep]
            self.adg.unclaim(i, len(kept))
            committed += kept
            st.stop_s[i] = min(st.stop_s[i], st.cur_end[i] + len(kept) * st.cell_m)
        # Drop everything after the stop (a new plan comes once it stands there).
        node = self.adg.cut_node(i)
        self.adg.set_plan(i, TimedPath(i, view.tick, ((node, node),)))
        st.has_next[i] = self.adg.next_action(i) is not None
        return True, any(cells.intersection(a.enters) for a in committed)
