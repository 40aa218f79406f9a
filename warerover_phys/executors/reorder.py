"""Reordering the dependency graph while executing (``executor.reorder``).

A plan executed through a fixed action dependency graph keeps the plan's passing order at
every shared cell: when the AGV that should pass first is late, everyone behind it waits.
:class:`Reorderer` lets the waiting AGV go first where that wins time, by switching edges
of the graph (:mod:`.switch`, which keeps it acyclic). Every ``reorder_every_s`` simulated
seconds (at a decision step of the follower, before the standing AGVs are decided) it
looks at the AGVs found waiting on the graph:

1. **Candidates.** For a waiting AGV ``j`` whose next action's cells are reserved for
   AGVs that have not entered them yet (``i``): the :class:`~.switch.Group` of the visits
   it would pass (:meth:`~.switch.SwitchableGraph.candidate`). And for a driving AGV
   whose stop point is that of a dependency: the first action it has not claimed goes
   on in its direction, but its cells are reserved for others; once it would have to
   start braking for it within ``reorder_ahead_s`` seconds at top speed
   (:meth:`Reorderer.approaching`), the group that lets it drive on. Switched, it does
   not stop: it saves the wait and the time that stopping and starting again cost
   (``speed / acceleration``), which its estimate adds to the wait (2026-11-29: of
   LaCAM's 400-agent plan's switches, bernoulli 0.1, seed 0, 275 of 451 came within a
   second after the AGV had stopped on a straight run).
2. **Estimates** from the motion model (:class:`~warerover_phys.planning.motion.MotionModel`
   of each AGV: straight runs from rest to rest, turns in place, planned dwells; stretched
   by the share of time the configured random delays are expected to hold an AGV,
   :func:`slowdown`) and the AGVs' states now (an injected delay's end, a dwell's end, the
   running action's rest, and, two levels down, the AGV an AGV waits for): when each
   passed AGV would enter and leave each cell and ``j`` would leave it. Without the switch
   ``j`` waits until ``i`` has left the cells of ``j``'s next action (``wait``); with it
   each passed AGV waits at each cell until ``j`` has left it (its ``cost``). Each counts
   once for the AGV and once for every AGV waiting on it, directly or down a chain.
3. **Choice.** ``greedy``: switch when ``wait - costs > reorder_margin_s`` (the AGV that
   should go first is late, and the other passes and clears the cells sooner).
   ``milp``: :func:`.reorder_milp.choose` (the receding-horizon program over the
   candidates and the AGVs they touch; greedy where it finds no optimum in its budget).
4. **Switch** (checked acyclic) and account: the switched AGV's current interval is
   credited ``wait`` (``reorder_gain`` in the lost-time causes, :mod:`warerover_phys.gap.open_loop`),
   and a ``reorder`` event names the AGVs and cells.

Deterministic: candidates are taken in AGV id order, the estimates are arithmetic on the
simulation's state, and the program stops at a node limit (a wall-clock limit is optional,
``reorder_time_limit_s``, and then results may depend on the machine's speed).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from itertools import islice
from typing import TYPE_CHECKING

import numpy as np

from ..planning.base import footprint_nodes
from ..planning.motion import MotionModel, quarter_turns
from .control import wrap
from .delays import DelayForesight
from .fleet_state import DRIVE, TURN
from .reorder_types import Estimate
from .switch import SEGMENT_LIMIT, Group, SwitchableGraph

if TYPE_CHECKING:
    from ..config import DelaySpec, ExecutorSpec
    from .accounting import Accounting
    from .adg import ActionGraph
    from .fleet_state import FleetState

__all__ = ["Estimate", "Reorderer", "FAILED_S", "check_executed"]

FAILED_S = 40.0
"""Seconds a failed AGV is taken to stay down (its repair time is not known here)."""
WAIT_DEPTH = 2
"""How far down a chain of waiting AGVs an estimate looks (an AGV that waits starts
after the one it waits for has left the cell, estimated in turn)."""
WAIT_LOOKAHEAD = 32
"""Actions of the AGV waited for that an estimate looks at (beyond: not counted)."""


class Reorderer:
    """Switches edges of the follower's dependency graph (see the module doc)."""

    wait_depth = WAIT_DEPTH
    """:data:`WAIT_DEPTH`, read by :mod:`.reorder_milp` (:class:`~.reorder_types.Decider`)."""

    def __init__(self, st: FleetState, adg: ActionGraph, spec: ExecutorSpec,
                 holds: dict[int, dict[int, int]], acc: Accounting, *,
                 check: bool = False) -> None:
        self.st, self.adg, self.acc, self.holds = st, adg, acc, holds
        self.mode = spec.reorder
        self.every_s = float(spec.reorder_every_s)
        self.margin_s = float(spec.reorder_margin_s)
        self.horizon = int(spec.reorder_horizon)
        self.node_limit = int(spec.reorder_node_limit)
        self.time_limit_s = spec.reorder_time_limit_s
        self.milp_band_s = spec.reorder_milp_band_s
        self.milp_max_vars = spec.reorder_milp_max_vars
        self.ahead_s = float(spec.reorder_ahead_s)
        self.graph = SwitchableGraph(adg, check=check)
        self.slow = slowdown(spec.delays)
        """Driving times are stretched by this factor: the share of time random delays
        are expected to hold an AGV (``executor.delays``)."""
        self.delays = spec.delays
        self.clairvoyant = spec.reorder_estimates == "clairvoyant"
        self.foresight: DelayForesight | None = None
        """``reorder_estimates: clairvoyant``: the delays to come (:meth:`see_delays`),
        instead of :attr:`slow`."""
        self._declined: set[tuple] = set()
        self._declined_version = -1
        self._cyclic: set[tuple] = set()
        """The pairs of visits of groups refused for a cycle. Whether a group closes a
        cycle depends on the graph, not on delays, so it is not tried again while the
        plans stay the same. A cycle through other AGVs' actions can open as they move on;
        those few switches are given up for the checks saved (lacam3's 1,000-agent plan,
        bernoulli 0.1, seed 1, ``greedy``: 6,709 checks refused instead of 34,446, 14.2
        instead of 41.3 ms of decision CPU per plan tick, AET 1,454.3 s instead of
        1,451.6). The visits themselves are kept, not their ``id``, so none is reused."""
        self._switched_now: set[int] = set()
        self._behind: dict[int, int] = {}
        self._next_s = 0.0
        self._models: dict[int, tuple[tuple[float, float, float], MotionModel]] = {}
        self._memo: dict[tuple[int, int], tuple] = {}
        self.decisions = 0
        self.candidates = 0
        self.switches_ahead = 0
        """Switches made for driving AGVs (:meth:`approaching`)."""
        self.gain_s = 0.0
        self.wall_s = 0.0
        self.cpu_s = 0.0
        """Wall and CPU seconds spent deciding (CPU: this process's, which a loaded
        machine does not inflate)."""
        self.milp_solves = 0
        self.milp_fallbacks = 0
        self.milp_clear = 0
        """``milp``: lone candidates decided by the greedy rule (clear-cut)."""
        self.milp_large = 0
        """``milp``: problems decided by the greedy rule, their program over
        ``reorder_milp_max_vars``."""
        self.audit: dict[str, float] = {}
        """Simulated AGV-seconds the waiting AGVs spent, sampled at the decisions, by what
        held them: ``switched``, ``declined`` (not worth it, or declined before),
        ``refused`` (a cycle), ``overlap`` (its cells in another candidate),
        ``held_delayed`` / ``held_moving`` / ``claimed`` / ``sweep`` / ``plan_end`` /
        ``unmovable`` / ``other`` (no candidate: :meth:`_why_not`), ``chain_X`` (held by an
        AGV that waits in turn, down a chain to one whose wait is ``X``; ``chain_moving``:
        to one not looked at, e.g. driving), ``delayed`` (delayed or failed itself)."""

    # ----------------------------------------------------------------- decisions

    def decide(self, t: float, delayed: np.ndarray) -> int:
        """Look at the waiting AGVs if a decision is due at ``t``; returns the switches
        made."""
        if t + 1e-9 < self._next_s:
            return 0
        self._next_s = t + self.every_s
        wall0, cpu0 = time.perf_counter(), time.process_time()
        self.decisions += 1
        st = self.st
        waiting = np.flatnonzero(st.waiting).tolist()
        cands = np.flatnonzero(st.waiting & ~delayed & ~st.failed).tolist()
        self._behind = self._chains(waiting)
        self._memo.clear()
        ests: list[Estimate] = []
        used: set[int] = set()
        keys: dict[int, tuple] = {}
        why: dict[int, str] = {}
        on: dict[int, int] = {}
        # standing and driving AGVs in id order (a driving one does not wait: the audit
        # leaves it out, below)
        driving = set(self.approaching(delayed)) if self.ahead_s > 0 else set()
        for j in sorted(driving.union(cands)):
            g = self.graph.candidate(j, SEGMENT_LIMIT, j in driving)
            if g is None:
                why[j], on[j] = self._why_not(j, delayed)
                continue
            key = self._key(g)
            if key in self._declined:
                why[j] = "declined"
                continue
            if g.pairs in self._cyclic:
                why[j] = "refused"
                continue
            ids = {id(v) for pair in g.pairs for v in pair}
            if ids & used:
                why[j] = "overlap"
                continue
            used |= ids
            keys[j] = key
            ests.append(self.estimate(g, t))
        self.candidates += len(ests)
        if self.mode == "milp" and ests:
            from .reorder_milp import choose

            chosen = choose(self, ests, t)
        else:
            chosen = [e for e in ests if self.worth(e)]
        made = 0
        sg = self.graph
        for e in chosen:
            refused = sg.refused
            if sg.switch(e.group):
                made += 1
                self._record(e, t)
                self.stop_at_claims(sorted({u.agv for u, _ in e.group.pairs}))
            else:
                why[e.group.second] = "refused"
                if sg.refused > refused:
                    if len(self._cyclic) > 100_000:
                        self._cyclic.clear()
                    self._cyclic.add(e.group.pairs)
        for e in ests:  # declined: not again until something it depends on moves
            j = e.group.second
            why.setdefault(j, "switched" if j in self._switched_now else "declined")
            if j not in self._switched_now:
                self._declined.add(keys[j])
        for j in driving:
            why.pop(j, None)
        for j in waiting:
            why.setdefault(j, "delayed")
        self._account(why, on)
        self._switched_now.clear()
        self.wall_s += time.perf_counter() - wall0
        self.cpu_s += time.process_time() - cpu0
        return made

    def approaching(self, delayed: np.ndarray) -> list[int]:
        """Driving AGVs (not delayed, not failed) that will stop for a dependency: the
        first action each has not claimed goes on in the direction of the one it drives,
        with no planned dwell before it, but another AGV's visit ahead of its own holds
        one of its cells back; and it would have to start braking for it within
        ``reorder_ahead_s`` seconds at top speed (its stop point, the end of its claims,
        is at most its braking distance plus ``reorder_ahead_s x max speed`` ahead)."""
        st, adg = self.st, self.adg
        near = st.stop_s - st.s_ref <= (st.speed ** 2 / (2 * st.amax)
                                        + self.ahead_s * st.vmax + 1e-9)
        out = []
        for j in np.flatnonzero((st.mode == DRIVE) & ~delayed & ~st.failed & near).tolist():
            rec = adg._agents.get(j)
            if rec is None or rec.running is None:
                continue
            step = next((s for s in rec.pending if not s.claimed), None)
            if step is None or step.action.direction != rec.running.action.direction \
                    or step.action.seq in self.holds.get(j, {}):
                continue
            if not all(adg._first(v) for v in step.enter_visits):
                out.append(j)
        return out

    def stop_at_claims(self, agvs: list[int]) -> None:
        """Driving AGVs among ``agvs`` stop at the end of what they claim (within their
        braking distance). For an AGV that gave back claims
        (:meth:`~.follow.PlanFollower._give_back_delayed`) when a switch passes it, or
        when plans change: the cells it gave back may no longer be its next."""
        st = self.st
        for a in agvs:
            if st.mode[a] == DRIVE:
                end = st.cur_end[a] + len(self.adg.claimed(a)) * st.cell_m
                st.stop_s[a] = min(st.stop_s[a], end)

    def _key(self, g: Group) -> tuple:
        """A group declined (not worth it, or refused: a cycle) is not looked at again
        while the plans, its two AGVs' next actions, the other's delay and whether it
        waits stay the same."""
        agents = self.adg._agents
        heads = []
        for a in (g.first, g.second):
            rec = agents[a]
            head = rec.running if rec.running is not None else (
                rec.pending[0] if rec.pending else None)
            heads.append(id(head.action) if head is not None else None)
        if self._declined_version != self.adg.plan_version or len(self._declined) > 100_000:
            self._declined.clear()
            self._cyclic.clear()
            self._declined_version = self.adg.plan_version
        st = self.st
        passed = sorted({u.agv for u, _ in g.pairs})
        return (g.second, *heads, *passed, *(float(st.delayed_until[a]) for a in passed),
                *(bool(st.waiting[a]) for a in passed))

    def _account(self, why: dict[int, str], on: dict[int, int]) -> None:
        """Add the decision's waits to :attr:`audit`; a wait behind an AGV that waits in
        turn (``held_waiting``) goes to the end of the chain's reason (``chain_...``)."""
        for j, w in why.items():
            if w == "held_waiting":
                seen = {j}
                h = on[j]
                while why.get(h) == "held_waiting" and h not in seen:
                    seen.add(h)
                    h = on[h]
                w = "chain_" + why.get(h, "moving")
            self.audit[w] = self.audit.get(w, 0.0) + self.every_s

    def _why_not(self, j: int, delayed: np.ndarray) -> tuple[str, int]:
        """Why waiting AGV ``j`` has no candidate (the audit, :attr:`audit`): the visit
        ahead of its own at a cell its next action enters is ``held`` by its AGV
        (standing on it or driving off it: ``held_delayed`` if that AGV is delayed or
        failed, ``held_waiting`` if it waits in turn, else ``held_moving``), or may not
        move (``claimed``: its AGV drives through without stopping; ``sweep``: a turn's
        swept cell; ``plan_end``: its AGV's plan ends there; ``unmovable``: a visit
        between, or one at a later cell of the group), or none of these (``other``);
        and the AGV of that visit (-1: none)."""
        rec = self.adg._agents[j]
        if rec.running is not None or not rec.pending:
            return "other", -1
        queues, st = self.adg._queues, self.st
        for v in rec.pending[0].enter_visits:
            if self.adg._first(v):
                continue
            q = queues[v.cell]
            ahead = [x for x in q[:q.index(v)] if x.agv != j]
            if not ahead:
                continue
            h = ahead[0]
            if not h.entered:
                return ("claimed" if h.claimed else "sweep" if h.sweep or h.shelf
                        else "plan_end" if h.leave is None else "unmovable"), h.agv
            if delayed[h.agv] or st.failed[h.agv]:
                return "held_delayed", h.agv
            return ("held_waiting" if st.waiting[h.agv] else "held_moving"), h.agv
        return "other", -1

    def worth(self, e: Estimate) -> bool:
        """The greedy rule: the switch wins more than the margin."""
        return e.gain_s > self.margin_s

    def _record(self, e: Estimate, t: float) -> None:
        g, st = e.group, self.st
        self._switched_now.add(g.second)
        driving = not st.waiting[g.second]
        self.switches_ahead += driving
        wait = max(0.0, e.wait_s)
        self.gain_s += wait
        self.acc.causes.reorder_gain(g.second, int(round(wait / st.dt)))
        cols = st.cols
        self.acc.events.append(("reorder", {
            "t_s": round(t, 3), "first": g.second, "then": g.first,
            "passed": sorted({u.agv for u, _ in g.pairs}),
            "cells": [list(divmod(c, cols)) for c in g.cells],
            "wait_s": round(e.wait_s, 3), "cost_s": round(e.cost_s, 3),
            "driving": bool(driving)}))

    # ----------------------------------------------------------------- estimates

    def estimate(self, g: Group, t: float) -> Estimate:
        """The effect of switching ``g`` (see the module doc, step 2)."""
        sg = self.graph
        j = g.second

        def k(action) -> int:
            return sg.pending_index(sg.step_of(action))

        rows = [(u.agv, k(u.enter), k(u.leave), k(w.enter), k(w.leave)) for u, w in g.pairs]
        need: dict[int, int] = {}
        for a, _, ko, _, _ in rows:
            need[a] = max(need.get(a, 0), ko)
        times = {a: self.times(a, n, t) for a, n in sorted(need.items())}
        # (j as if the action it waits for were free: the switch makes it so; its
        # first, 0 standing, the first it has not claimed driving)
        times[j] = sj, ej = self.times(j, max(r[4] for r in rows), t, WAIT_DEPTH)
        k0 = rows[0][3]
        wait = max(times[a][1][ko] for a, _, ko, kin, _ in rows if kin == k0) - sj[k0]
        costs: dict[int, float] = {}
        for a, ki, _, _, kjo in rows:
            costs[a] = max(costs.get(a, 0.0), ej[kjo] - times[a][0][ki])
        for a, c in costs.items():  # a driving AGV that now waits stops, and starts again
            costs[a] = c + self._restart_s(a, c)
        behind = {a: self._behind.get(a, 0) for a in times}
        return Estimate(g, wait, costs, times, behind, self._restart_s(j, wait))

    def see_delays(self, rng: np.random.Generator) -> None:
        """Called by the follower before each tick's delay draws from ``rng``: with
        clairvoyant estimates the first call takes a copy of it, whose replays foretell
        every AGV's delays (:class:`~.delays.DelayForesight`)."""
        if self.clairvoyant and self.foresight is None:
            st = self.st
            self.foresight = DelayForesight(rng, self.delays, st.n, t0_s=st.sim_s,
                                            tick_s=st.tick_s, dt_s=st.dt)

    def after(self, a: int, t0: float, d: float) -> float:
        """When AGV ``a``, free to go at ``t0``, is through ``d`` seconds of the motion
        model's driving: ``t0 + d x`` :attr:`slow` (the share of time delays are expected
        to hold it), or, clairvoyant, after the delays it will have in between."""
        if self.foresight is not None:
            return self.foresight.after(a, t0, d)
        return t0 + d * self.slow

    def _restart_s(self, a: int, wait: float) -> float:
        """What a wait of ``wait`` seconds adds for AGV ``a`` if it drives now: stopping
        and starting again, ``min(wait, speed / acceleration)``; 0 standing or no wait."""
        st = self.st
        if wait <= 0 or st.mode[a] != DRIVE:
            return 0.0
        return min(wait, float(st.speed[a] / st.amax[a]))

    def _chains(self, waiting: list[int]) -> dict[int, int]:
        """Per AGV: how many waiting AGVs wait on it, directly or down a chain (each
        waiting AGV's blocker: :meth:`~.adg.ActionGraph.blockers`)."""
        on = dict(zip(waiting, self.adg.blockers(waiting), strict=True))
        count: dict[int, int] = {}
        for a in waiting:
            seen = {a}
            b = on.get(a, -1)
            while b >= 0 and b not in seen:
                count[b] = count.get(b, 0) + 1
                seen.add(b)
                b = on.get(b, -1)
        return count

    def model(self, a: int) -> MotionModel:
        """The motion model of AGV ``a`` with its limits in force."""
        st = self.st
        key = (float(st.vmax[a]), float(st.amax[a]), float(st.wmax[a]))
        got = self._models.get(a)
        if got is None or got[0] != key:
            got = (key, MotionModel(max_speed_mps=key[0], max_accel_mps2=key[1],
                                    max_turn_rate_radps=key[2], omni=bool(st.omni[a]),
                                    cell_m=st.cell_m))
            self._models[a] = got
        return got[1]

    def ready_s(self, a: int, t: float, depth: int = 0
                ) -> tuple[float, tuple[int, int] | None, bool]:
        """When AGV ``a`` could start its next action (after its delay, failure, dwell
        and running action, and, ``depth`` levels down, after the AGV it waits for has
        left the cell), the direction it then faces and whether it is still driving a
        run it may go on with."""
        st = self.st
        rec = self.adg._agents[a]
        m = self.model(a)
        t0 = max(t, float(st.delayed_until[a]))
        if st.failed[a]:
            t0 += FAILED_S
        heading = rec.heading
        rolling = False
        if rec.running is not None:
            act = rec.running.action
            mode = st.mode[a]
            if mode == DRIVE:
                left = max(0.0, float(st.cur_end[a] - st.s_ref[a]))
                rolling = st.stop_s[a] > st.cur_end[a] + 1e-9
                t0 += left / max(float(st.speed[a]), 0.5 * m.max_speed_mps)
            elif mode == TURN:
                t0 += abs(float(wrap(st.heading[a] - st.ang_ref[a]))) / m.max_turn_rate_radps
                t0 += m.run_s(1)
            else:
                t0 += m.run_s(1)
            heading = act.direction
        else:
            t0 = max(t0, float(st.hold_until[a]))
            if depth < WAIT_DEPTH and st.waiting[a] and rec.pending:
                t0 = max(t0, self._free_s(rec.pending[0], a, t, depth))
        return t0, heading, rolling

    def _free_s(self, step, a: int, t: float, depth: int) -> float:
        """When the cells ``step`` of AGV ``a`` enters are free of the visits ahead of
        its own (their AGVs' estimates, one level further down)."""
        sg, queues = self.graph, self.adg._queues
        out = t
        for v in step.enter_visits:
            q = queues[v.cell]
            h = q[0]
            if h is v or h.agv == a or h.leave is None:
                continue
            k = sg.pending_index(sg.step_of(h.leave))
            if k < 0:
                out = max(out, self.ready_s(h.agv, t, depth + 1)[0])
            elif k < WAIT_LOOKAHEAD:
                out = max(out, self.times(h.agv, k, t, depth + 1)[1][k])
        return out

    def times(self, a: int, upto: int, t: float, depth: int = 0
              ) -> tuple[list[float], list[float]]:
        """Estimated start and finish times of AGV ``a``'s next ``upto + 1`` actions (a
        running one not included), driving without waiting on anyone: collinear moves as
        one run from rest to rest, a turn in place before a change of direction, planned
        dwells. Memoised within a decision (nothing moves while one is made: the switches
        come after every estimate)."""
        memo = self._memo.get((a, depth))
        if memo is not None and memo[0] == t and (memo[1] >= upto or memo[2]):
            return memo[3][:upto + 1], memo[4][:upto + 1]
        starts, ends = self._times(a, upto, t, depth)
        if memo is None or memo[0] != t or upto > memo[1]:
            self._memo[(a, depth)] = (t, upto, len(starts) <= upto, starts, ends)
        return starts, ends

    def _times(self, a: int, upto: int, t: float, depth: int
               ) -> tuple[list[float], list[float]]:
        """:meth:`times` (not memoised)."""
        st = self.st
        m = self.model(a)
        after = self.after
        t0, heading, rolling = self.ready_s(a, t, depth)
        steps = [s.action for s in islice(self.adg._agents[a].pending, upto + 1)]
        holds = self.holds.get(a, {})
        starts: list[float] = []
        ends: list[float] = []
        k = 0
        now = t0
        while k < len(steps):
            d = steps[k].direction
            n = 1
            while k + n < len(steps) and steps[k + n].direction == d \
                    and steps[k + n].seq not in holds:
                n += 1
            hold = holds.get(steps[k].seq, 0) * st.tick_s
            if k == 0 and rolling and d == heading and not hold:
                for q in range(n):  # going on at cruise speed, braking at the end
                    starts.append(after(a, now, q * m.pass_s(1)))
                    ends.append(after(a, now, (q + 1) * m.pass_s(1)))
                ends[-1] = after(a, ends[-1], m.max_speed_mps / (2 * m.max_accel_mps2))
                now = ends[-1]
            else:
                now = after(a, now + hold, m.turn_s(quarter_turns(heading, d)))
                for q in range(n):
                    starts.append(after(a, now, m.reach_s(q, n)))
                    ends.append(after(a, now, m.reach_s(q + 1, n)))
                now = after(a, now, m.run_s(n))
            heading = d
            k += n
        return starts, ends

    # ----------------------------------------------------------------- results

    def summary(self) -> dict:
        """Figures for ``metrics.json``."""
        sw = self.graph
        ticks = max(1.0, self.st.sim_s / self.st.tick_s)
        out = {
            "reorder": self.mode,
            "reorder_switches": sw.switches,
            "reorder_switches_driving": self.switches_ahead,
            "reorder_refused": sw.refused,
            "reorder_candidates": self.candidates,
            "reorder_decisions": self.decisions,
            "reorder_gain_s": self.gain_s,
            "reorder_order_rebuilds": sw.rebuilds,
            "reorder_wall_s": self.wall_s,
            "reorder_wall_ms_per_tick": 1000.0 * self.wall_s / ticks,
            "reorder_cpu_s": self.cpu_s,
            "reorder_cpu_ms_per_tick": 1000.0 * self.cpu_s / ticks,
        }
        out.update({f"reorder_audit_{k}_s": v for k, v in sorted(self.audit.items())})
        if self.mode == "milp":
            out["reorder_milp_solves"] = self.milp_solves
            out["reorder_milp_fallbacks"] = self.milp_fallbacks
            out["reorder_milp_clear"] = self.milp_clear
            out["reorder_milp_large"] = self.milp_large
        return out


def slowdown(d: DelaySpec) -> float:
    """``1 / (1 - share)`` of the share of time random delays ``d`` hold an AGV: a delay
    starts with probability ``p`` per tick while none runs and lasts ``D`` ticks on
    average, so the share is ``D / (D + 1 / p)``."""
    if d.model == "none" or d.prob <= 0:
        return 1.0
    p = d.prob if d.model == "bernoulli" else 1.0 - math.exp(-d.prob)
    mean = (d.min_ticks + d.max_ticks) / 2 if d.duration == "uniform" else min(
        max(d.mean_ticks, d.min_ticks), d.max_ticks)
    return 1.0 + mean * p


def _cells_visited(states) -> list[int]:
    """The anchors a sequence of states ``(a, b)`` passes through, in order (states
    sampled once a tick: a move's both ends, so none is missed while an AGV covers at
    most two cells a tick)."""
    out = [states[0][0]] if len(states) else []
    for a, b in states:
        if b == out[-1]:
            continue
        if a != out[-1]:
            out.append(a)
        if b != a:
            out.append(b)
    return out


def check_executed(planned: Mapping[int, Sequence[tuple[int, int]]],
                   executed: Mapping[int, Sequence[tuple[int, int]]], cols: int,
                   sizes: Mapping[int, int] | None = None) -> list[str]:
    """An independent check of an execution (reordered or not) against its plan: every
    AGV passes exactly its plan's cells in their order, and at no tick do two AGVs hold
    one cell (a moving AGV holds both ends of its move; ``sizes``: footprints, default
    1). Returns the problems found (empty: none)."""
    problems = []
    for i, states in sorted(planned.items()):
        if _cells_visited(states) != _cells_visited(executed.get(i, ())):
            problems.append(f"AGV {i} did not pass its plan's cells in order")
    sizes = sizes or {}
    ticks = max((len(s) for s in executed.values()), default=0)
    for t in range(ticks):
        owner: dict[int, int] = {}
        for i, states in executed.items():
            a, b = states[min(t, len(states) - 1)]
            k = sizes.get(i, 1)
            for c in {*footprint_nodes(a, k, cols), *footprint_nodes(b, k, cols)}:
                j = owner.setdefault(c, i)
                if j != i:
                    problems.append(f"tick {t}: AGVs {j} and {i} both hold cell "
                                    f"{divmod(c, cols)}")
    return problems
