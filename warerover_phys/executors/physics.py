"""Physics executor: the committed plans, carried out by rigid bodies in continuous time.

Each tick (``tick_s`` seconds) the executor

1. hands every new or changed plan to the :class:`~.adg.ActionGraph` (commit cut: the AGV
   keeps the action it is driving, the rest is replaced);
2. draws the tick's random delays (seeded, ``executor.delays``);
3. steps the pymunk world ``tick_s / dt_s`` times. Per step, a vectorised controller sets
   every control body's velocity: along the current straight run
   ``v = min(v_max * scale, sqrt(2 a d), v_prev + a dt)`` with ``d`` the distance to the next
   *unreleased* point (the end of the run of collinear actions the ADG already allows), a
   proportional pull back onto the path line, and heading hold. Differential-drive AGVs turn
   in place at ``max_turn_rate`` before a move in a new direction (while they wait for the
   move's dependencies); omnidirectional AGVs never turn. An action starts only when the ADG
   says its cells are free (or, with ``adg: false``, at its planned tick: naive
   time-indexed following, for comparison);
4. reports each AGV's discrete state (standing at a cell, or moving between two) for the
   loop to write into the world, blocked AGVs (waiting on a dependency) and AGVs to replan
   (dependency deadlock, deviation from the path). It never touches the world itself.

Contacts come from pymunk collision handlers (AGV-AGV, AGV-obstacle, a loaded AGV against
another shelf), the minimum centre-to-edge separation between AGVs is sampled every tick,
and a swept segment query catches any body that moves farther than half its width in one
step (tunnelling). :meth:`summary` gives the figures that go into ``metrics.json``, and
:meth:`trajectory` the poses recorded at ``trajectory_hz``.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np

from ..planning.base import TimedPath
from .adg import Action, ActionGraph
from .base import ExecutorSetup, StepReport, TickView
from .bodies import AGV, OBSTACLE, SHELF, BodyIO, PhysicalFleet, build_space, cell_centre

if TYPE_CHECKING:
    from ..config import ExecutorSpec

__all__ = ["PhysicsExecutor"]

HOLD, TURN, DRIVE = 0, 1, 2
ARRIVE_EPS_M = 0.02
"""An action is done when its reference point has reached the target centre and the body's
centre is this close to it (or past it)."""
TURN_EPS_RAD = 0.01
"""A move needs a turn first if the heading is off by more than this."""
ALIGN_EPS_RAD = 0.03
"""A turn is done when its reference heading has arrived and the body is this close."""
LATERAL_GAIN = 3.0
"""1/s: pull back onto the path line."""
ALONG_GAIN = 4.0
"""1/s: pull towards the reference point along the path."""
HEADING_GAIN = 6.0
"""1/s: heading hold while driving or standing."""
LOOKAHEAD = 8
"""Actions looked at (and claimed) ahead of a driving AGV."""
DECIDE_EVERY = 5
"""Physics steps between checks of standing AGVs (may they start their next action?)."""


def _point_to_box(p: np.ndarray, centre: np.ndarray, angle: np.ndarray,
                  half: np.ndarray) -> np.ndarray:
    """Signed distance from points ``p`` (M, 2) to boxes (centre, angle, half sizes):
    positive outside, negative inside (minus the depth to the nearest edge)."""
    rel = p - centre
    c, s = np.cos(angle), np.sin(angle)
    local = np.abs(np.stack([c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1]],
                            axis=1)) - half
    outside = np.linalg.norm(np.maximum(local, 0.0), axis=1)
    inside = np.minimum(local.max(axis=1), 0.0)
    return outside + inside


def _wrap(a: np.ndarray | float) -> np.ndarray | float:
    return (a + math.pi) % (2 * math.pi) - math.pi


class PhysicsExecutor:
    name = "physics"

    def __init__(self, spec: ExecutorSpec) -> None:
        self.spec = spec
        self._bound = False

    # ------------------------------------------------------------------------- set-up

    def bind(self, setup: ExecutorSetup) -> None:
        spec, layout = self.spec, setup.layout
        self.layout = layout
        self.cols, self.cell_m = layout.cols, layout.cell_m
        self.tick_s = setup.tick_s
        self.steps_per_tick = max(1, round(self.tick_s / spec.dt_s))
        self.dt = self.tick_s / self.steps_per_tick
        self.space, self._shelf_of = build_space(layout, len(setup.agvs))
        agvs = setup.agvs
        n = len(agvs)
        self.n = n
        self.k = np.array([a.k for a in agvs])
        self._events: list[tuple[str, dict]] = []
        self._intrusion_checks: list[list[tuple[int, int, float]]] = []
        self._view: TickView | None = None
        poses = []
        for a in agvs:
            x, y = cell_centre(a.start[1], a.k, self.cols, self.cell_m)
            poses.append((x, y, 0.0))
        self.fleet = PhysicalFleet.add_to(
            self.space, poses, [tuple(a.spec.body_m) for a in agvs],
            [a.spec.mass_kg for a in agvs], [a.spec.max_accel_mps2 for a in agvs])
        self.io = BodyIO(self.space, self.fleet)
        self._agv_of_shape = {id(s): i for i, s in enumerate(self.fleet.shapes)}
        self.rng = rng = setup.rng
        lo, hi = spec.speed_scale
        self.scale = rng.uniform(lo, hi, n) if hi > lo else np.full(n, lo)
        self.vmax = np.array([a.spec.max_speed_mps for a in agvs]) * self.scale
        self.amax = np.array([a.spec.max_accel_mps2 for a in agvs])
        self.wmax = np.array([a.spec.max_turn_rate_radps for a in agvs])
        self.omni = np.array([a.spec.drive == "omni" for a in agvs])
        self.mode = np.full(n, HOLD, dtype=np.int8)
        self.origin = np.array([p[:2] for p in poses], dtype=float)
        self.direction = np.zeros((n, 2))
        self.hold_xy = self.origin.copy()
        self.heading = np.zeros(n)
        """Heading to hold (radians)."""
        self.ang_ref = np.zeros(n)
        """Reference heading while turning."""
        self.cur_end = np.zeros(n)
        self.stop_s = np.zeros(n)
        self.speed = np.zeros(n)
        self.s_ref = np.zeros(n)
        """Reference position along the current run (metres from its origin)."""
        self.delayed_until = np.zeros(n)
        self.waiting = np.zeros(n, dtype=bool)
        self.failed = np.zeros(n, dtype=bool)
        self._corridor_keys: tuple[int, ...] = ()
        self._resync: set[int] = set()
        """AGVs whose new plan did not fit their commit cut: replanned once they stand."""
        self._checker = None
        self._pending = np.zeros(n, dtype=bool)
        self.has_next = np.zeros(n, dtype=bool)
        """AGVs with a not-started action (kept up to date on every ADG change)."""
        self.last_finish = np.zeros(n)
        """Simulated time at which each AGV last finished an action."""
        self.prev_pos = self.origin.copy()
        self.adg = ActionGraph(self.cols, {a.id: a.k for a in agvs})
        self._synced: dict[int, TimedPath | None] = {a.id: None for a in agvs}
        self.sim_s = 0.0
        self._wall = 0.0
        self._step_count = 0
        # figures
        self.agv_contacts = 0
        self.static_contacts = 0
        self._tick_agv_contacts = 0
        self.min_sep = math.inf
        self.deadlocks = 0
        self._cycles_seen: set[frozenset[int]] = set()
        self.replans_asked = 0
        self.deviations = 0
        self.swept_checks = 0
        self.swept_hits = 0
        self.dep_wait = np.zeros(n)
        self.injected = np.zeros(n)
        self.turn_time = np.zeros(n)
        self.kin_lag: list[float] = []
        self._act_start = np.zeros(n)
        self._act_planned = np.zeros(n)
        self._act_injected = np.zeros(n)
        self.actions_done = 0
        self._active = 0
        # trajectories
        self._traj_every = max(1, round(1.0 / (spec.trajectory_hz * self.dt)))
        self._traj: list[tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self._install_handlers()
        self._bound = True

    def _install_handlers(self) -> None:
        def agv_agv(arbiter, space, data) -> None:
            self.agv_contacts += 1
            self._tick_agv_contacts += 1
            a, b = (self._agv_of_shape[id(s)] for s in arbiter.shapes)
            self._events.append(("contact", {
                "agvs": sorted((a, b)), "t_s": round(self.sim_s, 3),
                "states": [list(self.adg.state(a)), list(self.adg.state(b))]}))

        def agv_static(arbiter, space, data) -> None:
            self.static_contacts += 1
            shape = next(s for s in arbiter.shapes if s.collision_type == AGV)
            self._events.append(("static_contact", {
                "agv": self._agv_of_shape[id(shape)], "t_s": round(self.sim_s, 3)}))

        def agv_shelf(arbiter, space, data) -> None:
            a, b = arbiter.shapes
            agv_shape, shelf_shape = (a, b) if a.collision_type == AGV else (b, a)
            i = self._agv_of_shape[id(agv_shape)]
            shelf = self._shelf_of.get(id(shelf_shape))
            carried = self._view.carried[i] if self._view is not None else None
            if carried is not None and shelf != carried:
                self.static_contacts += 1

        self.space.on_collision(AGV, AGV, begin=agv_agv)
        self.space.on_collision(AGV, OBSTACLE, begin=agv_static)
        self.space.on_collision(AGV, SHELF, begin=agv_shelf)

    # ------------------------------------------------------------------------- the tick

    def step(self, view: TickView) -> StepReport:
        if not self._bound:
            raise RuntimeError("PhysicsExecutor.step before bind()")
        wall0 = time.perf_counter()
        self._view = view
        self._events, self._intrusion_checks = [], []
        self._sync_plans(view)
        self._draw_delays()
        self._sync_faults(view)
        self._tick_agv_contacts = 0
        for s in range(self.steps_per_tick):
            self._physics_step(decide=(s % DECIDE_EVERY == 0))
        report = self._write_back(view)
        report.events = self._events + report.events
        report.intrusion_checks = self._intrusion_checks
        self._wall += time.perf_counter() - wall0
        return report

    def _sync_faults(self, view: TickView) -> None:
        """Failed AGVs brake and start nothing; open corridors go to the fcl checker."""
        self.failed = np.zeros(self.n, dtype=bool)
        self.failed[list(view.failed)] = True
        corridors = view.corridors
        keys = tuple(sorted(corridors))
        if keys != self._corridor_keys:
            self._corridor_keys = keys
            if keys:
                if self._checker is None:
                    from ..faults.intrusion import IntrusionChecker

                    self._checker = IntrusionChecker(self.fleet.half_size)
                self._checker.set_corridors([corridors[k] for k in keys])

    def remaining(self, i: int) -> list[tuple[int, int]]:
        """What AGV ``i`` still has to drive, as states (running action, then the rest)."""
        if not self._synced_once(i):
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
        if not self._synced_once(i):
            return False, False
        committed = []
        cur = self.adg.current(i)
        if cur is not None:
            committed.append(cur)
            keep = 0
            if self.mode[i] == DRIVE:
                brake = self.speed[i] ** 2 / (2 * self.amax[i])
                over = self.s_ref[i] + brake - self.cur_end[i]
                keep = max(0, math.ceil(over / self.cell_m - 1e-9))
            claimed = self.adg.claimed(i)
            kept = claimed[:keep]
            self.adg.unclaim(i, len(kept))
            committed += kept
            self.stop_s[i] = min(self.stop_s[i], self.cur_end[i] + len(kept) * self.cell_m)
        # Drop everything after the stop (a new plan comes once it stands there).
        node = self.adg.cut_node(i)
        self.adg.set_plan(i, TimedPath(i, view.tick, ((node, node),)))
        self.has_next[i] = self.adg.next_action(i) is not None
        return True, any(cells.intersection(a.enters) for a in committed)

    def _check_corridors(self, pos: np.ndarray, ang: np.ndarray) -> None:
        """fcl check of every AGV body against the open corridors' protected zones."""
        poses = np.column_stack([pos, ang])
        skip = {c.agv for c in self._view.corridors.values()}
        self._intrusion_checks.append(
            [(h.agv, h.corridor, h.depth_m) for h in self._checker.check(poses, skip)])

    def _sync_plans(self, view: TickView) -> None:
        paths = view.plans
        for i in range(self.n):
            path = paths.get(i)
            if path is None or path is self._synced[i]:
                continue
            self._synced[i] = path
            cut = self._cut(i, path)
            node = cut.states[0][0]
            if all(a == b == node for a, b in cut.states) and self._synced_once(i) \
                    and self.adg.next_action(i) is None:
                continue  # a plan to stay where it will stop anyway: nothing changes
            self.adg.set_plan(i, cut)
            self.has_next[i] = self.adg.next_action(i) is not None

    def _cut(self, i: int, path: TimedPath) -> TimedPath:
        """The part of ``path`` from where the AGV will stand after its current action."""
        if self._synced_once(i):
            node = self.adg.cut_node(i)
        else:
            node = path.states[0][0]
        for j, (a, b) in enumerate(path.states):
            if a == b == node:
                return TimedPath(i, path.start_tick + j, path.states[j:])
        # The plan does not pass where the AGV will stop (it was made from a stale view):
        # stop there and ask for a new plan.
        self._resync.add(i)
        return TimedPath(i, path.start_tick, ((node, node),))

    def _synced_once(self, i: int) -> bool:
        try:
            self.adg.state(i)
        except KeyError:
            return False
        return True

    def _draw_delays(self) -> None:
        d = self.spec.delays
        if d.model == "none" or d.prob <= 0:
            return
        rng = self.rng
        if d.model == "bernoulli":
            events = rng.random(self.n) < d.prob
        else:
            events = rng.poisson(d.prob, self.n) > 0
        if d.duration == "uniform":
            ticks = rng.integers(d.min_ticks, d.max_ticks + 1, self.n)
        else:
            ticks = np.clip(np.rint(rng.normal(d.mean_ticks, d.std_ticks, self.n)),
                            d.min_ticks, d.max_ticks)
        start = events & (self.delayed_until <= self.sim_s)
        self.delayed_until[start] = self.sim_s + ticks[start] * self.tick_s
        for i in np.flatnonzero(start):
            self._events.append(("delay", {"agv": int(i), "ticks": int(ticks[i])}))

    def _physics_step(self, decide: bool) -> None:
        raw, raw_ang, v_now, w_now = self.io.read()
        raw, raw_ang = raw.copy(), raw_ang.copy()
        # pymunk moves bodies with the velocity of the previous step before it solves the
        # joints: decide and steer on the pose the body has after this step's move.
        pos = raw + v_now * self.dt
        ang = raw_ang + w_now * self.dt
        t = self.sim_s
        injected = self.delayed_until > t
        delayed = injected | self.failed
        along = ((pos - self.origin) * self.direction).sum(axis=1)
        driving = self.mode == DRIVE
        # Arrived at the action's target: the reference has reached it and the body is
        # within ARRIVE_EPS_M of it (or past it).
        for i in np.flatnonzero(driving & (self.s_ref >= self.cur_end - 1e-9)
                                & (along >= self.cur_end - ARRIVE_EPS_M)):
            self._arrive(int(i), t)
        if decide:
            # Look further ahead for AGVs that would otherwise start braking before the
            # next look (the margin covers two decision intervals).
            driving = self.mode == DRIVE
            brake = self.speed ** 2 / (2 * self.amax) + 2 * self.vmax * self.dt * DECIDE_EVERY
            for i in np.flatnonzero(driving & ~delayed & (self.stop_s - along < brake + 0.05)):
                self._extend(int(i))
            self.waiting[:] = False
            for i in np.flatnonzero((self.mode != DRIVE) & self.has_next):
                self._decide(int(i), t, bool(delayed[i]), float(ang[i]))
        turning = self.mode == TURN
        if turning.any():
            aligned = turning & (self.ang_ref == self.heading) & (
                np.abs(_wrap(self.heading - ang)) < ALIGN_EPS_RAD)
            for i in np.flatnonzero(aligned):
                self.mode[i] = HOLD
                self._decide(int(i), t, bool(delayed[i]), float(ang[i]))
        vel, w = self._control(pos, ang, delayed)
        self.io.write(vel, w)
        self.space.step(self.dt)
        self.sim_s = t + self.dt
        self._step_count += 1
        # accounting
        busy = (self.mode != HOLD) | self.waiting
        self.dep_wait += self.waiting * self.dt
        self.injected += (injected & (busy | self._pending_mask())) * self.dt
        self.turn_time += (self.mode == TURN) * self.dt
        self._active += int(np.count_nonzero(self.mode != HOLD))
        self._act_injected += (injected & (self.mode == DRIVE)) * self.dt
        self._swept_check(raw)
        if self._corridor_keys:
            self._check_corridors(raw, raw_ang)
        if self._step_count % self._traj_every == 0:
            self._record()

    def _pending_mask(self) -> np.ndarray:
        return self._pending

    # ------------------------------------------------------------------------- decisions

    def _decide(self, i: int, t: float, delayed: bool, angle: float) -> None:
        """A standing (or turning) AGV: turn towards its next move, then start it once the
        ADG allows it (or its planned tick has come, without the ADG)."""
        nxt = self.adg.next_action(i)
        if nxt is None:
            return
        if not self.omni[i]:
            want = math.atan2(nxt.direction[0], nxt.direction[1])
            if abs(_wrap(want - angle)) >= TURN_EPS_RAD:
                if not delayed:
                    self.heading[i] = want
                    self.mode[i] = TURN
                else:
                    self.mode[i] = HOLD
                return
        if delayed:
            return
        if self.spec.adg:
            if not self.adg.ready(i):
                self.waiting[i] = True
                return
        elif t + 1e-9 < nxt.tick * self.tick_s:
            return
        self._start(i, t)

    def _start(self, i: int, t: float) -> None:
        a = self.adg.start(i) if self.spec.adg else self._force_start(i)
        x, y = cell_centre(a.src, self.k[i], self.cols, self.cell_m)
        self.origin[i] = (x, y)
        self.direction[i] = (a.direction[1], a.direction[0])
        self.cur_end[i] = self.cell_m
        self.stop_s[i] = self.cell_m
        self.mode[i] = DRIVE
        self.speed[i] = 0.0
        self.s_ref[i] = 0.0
        self._begin_action(i, a, t)
        self._extend(i)

    def _force_start(self, i: int) -> Action:
        """Naive following: start the next action whatever its dependencies say."""
        return self.adg.start(i, force=True)

    def _begin_action(self, i: int, a: Action, t: float) -> None:
        self.has_next[i] = self.adg.next_action(i) is not None
        self._act_start[i] = t
        self._act_planned[i] = a.ticks * self.tick_s
        self._act_injected[i] = 0.0

    def _extend(self, i: int) -> None:
        """Push the stop point to the end of the released collinear run ahead."""
        cur = self.adg.current(i)
        if cur is None:
            return
        run = 0
        if self.spec.adg:
            ahead = self.adg.released(i, LOOKAHEAD)
        else:
            limit = (self.sim_s / self.tick_s) + 1
            ahead = [a for a in self.adg.upcoming(i, LOOKAHEAD) if a.tick <= limit]
        for a in ahead:
            if a.direction != cur.direction:
                break
            run += 1
        if self.spec.adg and run:
            # Committed: no later plan may put another AGV ahead of it on these cells.
            self.adg.claim(i, run)
        self.stop_s[i] = self.cur_end[i] + run * self.cell_m

    def _arrive(self, i: int, t: float) -> None:
        done = self.adg.finish(i)
        self.actions_done += 1
        self.last_finish[i] = t
        self.kin_lag.append(t - self._act_start[i] - self._act_injected[i] - self._act_planned[i])
        nxt = self.adg.next_action(i)
        if nxt is not None and nxt.direction == done.direction and not self.failed[i] and \
                self.stop_s[i] > self.cur_end[i] + ARRIVE_EPS_M:
            a = self.adg.start(i) if self.spec.adg and self.adg.ready(i) else (
                None if self.spec.adg else self._force_start(i))
            if a is not None:
                self.cur_end[i] += self.cell_m
                self._begin_action(i, a, t)
                return
        self.mode[i] = HOLD
        self.adg.unclaim(i)  # it stops here: claims further on are stale
        self.hold_xy[i] = cell_centre(done.dst, self.k[i], self.cols, self.cell_m)
        self.stop_s[i] = self.cur_end[i]

    # ------------------------------------------------------------------------- control

    def _control(self, pos: np.ndarray, ang: np.ndarray,
                 delayed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dt, a = self.dt, self.amax
        along = ((pos - self.origin) * self.direction).sum(axis=1)
        vel = np.zeros((self.n, 2))
        w = np.zeros(self.n)
        drive = self.mode == DRIVE
        # The reference runs on its own kinematic state (s_ref, speed): an exact trapezoid
        # to the stop point; the body follows it through the joint, with a small pull on the
        # along-track and lateral errors.
        d = np.maximum(self.stop_s - self.s_ref, 0.0)
        v = np.minimum.reduce([self.vmax, np.sqrt(2 * a * d), self.speed + a * dt, d / dt])
        v = np.where(delayed, np.maximum(self.speed - a * dt, 0.0), v)
        v = np.where(drive, v, 0.0)
        self.speed = v
        v_along = v + np.clip(ALONG_GAIN * (self.s_ref - along), -0.2, 0.2)
        self.s_ref = np.where(drive, self.s_ref + v * dt, self.s_ref)
        rel = pos - self.origin
        normal = np.stack([-self.direction[:, 1], self.direction[:, 0]], axis=1)
        lateral = (rel * normal).sum(axis=1)
        v_lat = np.clip(-LATERAL_GAIN * lateral, -0.3, 0.3)
        vel[drive] = (self.direction * v_along[:, None] + normal * v_lat[:, None])[drive]
        # Standing: hold the cell centre.
        hold = ~drive
        err = self.hold_xy - pos
        dist = np.linalg.norm(err, axis=1)
        cap = np.minimum(0.3, np.sqrt(2 * a * dist))
        gain = np.where(dist > 1e-9, np.minimum(2.0 * dist, cap) / np.maximum(dist, 1e-9), 0.0)
        vel[hold] = (err * gain[:, None])[hold]
        # Heading: turn at the limit, else hold.
        target = np.where(drive & ~self.omni,
                          np.arctan2(self.direction[:, 1], self.direction[:, 0]), self.heading)
        self.heading = np.where(drive & ~self.omni, target, self.heading)
        herr = _wrap(target - ang)
        turning = self.mode == TURN
        # Turning: a reference heading turns at the limit; the body follows it.
        left = _wrap(self.heading - self.ang_ref)
        turn_step = np.sign(left) * np.minimum(self.wmax * dt, np.abs(left))
        w_turn = np.clip(_wrap(self.ang_ref + turn_step - ang) / dt, -self.wmax, self.wmax)
        self.ang_ref = np.where(turning, np.where(np.abs(left) <= self.wmax * dt, self.heading,
                                                  self.ang_ref + turn_step), ang)
        w_hold = np.clip(HEADING_GAIN * herr, -self.wmax, self.wmax)
        w = np.where(turning, w_turn, w_hold)
        return vel, w

    # ------------------------------------------------------------------------- checks

    def _swept_check(self, prev: np.ndarray) -> None:
        """Bodies that moved farther than half their width in one step: look along the
        swept segment for anything they may have passed through."""
        pos = np.array([b.position for b in self.fleet.bodies]) if self._need_swept(prev) \
            else None
        if pos is None:
            return
        step = np.linalg.norm(pos - prev, axis=1)
        import pymunk

        for i in np.flatnonzero(step > self.fleet.half_size.min(axis=1)):
            self.swept_checks += 1
            me = self.fleet.shapes[i]
            hits = self.space.segment_query(tuple(prev[i]), tuple(pos[i]), 0.0,
                                            pymunk.ShapeFilter())
            if any(h.shape is not me and h.shape is not None and not h.shape.sensor
                   for h in hits):
                self.swept_hits += 1

    def _need_swept(self, prev: np.ndarray) -> bool:
        """Cheap bound: no body can move farther than v_max x headroom x dt."""
        return bool((self.vmax * 2.0 * self.dt > self.fleet.half_size.min(axis=1)).any())

    def _min_separation(self, pos: np.ndarray, ang: np.ndarray) -> None:
        """Smallest centre-to-edge distance between two AGVs (negative: overlap), over the
        pairs a k-d tree finds near each other, in closed form for rotated boxes."""
        if self.n < 2:
            return
        from scipy.spatial import cKDTree

        half = self.fleet.half_size
        reach = float(np.linalg.norm(half, axis=1).max()) * 2 + 0.5
        pairs = cKDTree(pos).query_pairs(reach, output_type="ndarray")
        if len(pairs) == 0:
            return
        i, j = pairs[:, 0], pairs[:, 1]
        d = np.minimum(_point_to_box(pos[i], pos[j], ang[j], half[j]),
                       _point_to_box(pos[j], pos[i], ang[i], half[i]))
        self.min_sep = min(self.min_sep, float(d.min()))

    def _record(self) -> None:
        pos, ang, _, _ = self.io.read()
        view = self._view
        if view is None:
            state, loaded = np.zeros(self.n, dtype=np.int8), np.zeros(self.n, dtype=bool)
        else:
            state = np.array(view.task_state, dtype=np.int8)
            loaded = np.array(view.loaded, dtype=bool)
        self._traj.append((self.sim_s, pos.copy(), ang.copy(), state, loaded))

    # ------------------------------------------------------------------------- back to the grid

    def _write_back(self, view: TickView) -> StepReport:
        pos, ang, _, _ = self.io.read()
        self._min_separation(pos, ang)
        report = StepReport(collisions=self._tick_agv_contacts)
        tick_next = view.tick + 1
        pending = np.zeros(self.n, dtype=bool)
        for i in range(self.n):
            report.states[i] = self.adg.state(i)
            nxt = self.adg.next_action(i)
            cur = self.adg.current(i)
            pending[i] = nxt is not None
            late = (nxt is not None and cur is None and nxt.tick < tick_next) or (
                cur is not None and cur.tick + cur.ticks < tick_next)
            report.behind[i] = 1 if late else 0
            if self.waiting[i]:
                report.blocked.append(i)
            if self.mode[i] == DRIVE:
                rel = pos[i] - self.origin[i]
                normal = (-self.direction[i, 1], self.direction[i, 0])
                if abs(rel[0] * normal[0] + rel[1] * normal[1]) > self.spec.deviation_m:
                    self.deviations += 1
                    report.replan.append(i)
        self._pending = pending
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
                self.deadlocks += 1
                report.events.append(("deadlock", {"agvs": sorted(cyc)}))
            report.replan.extend(i for i in cyc if i not in report.replan)
        self._cycles_seen = seen
        self.replans_asked += len(report.replan)
        report.replan.sort()
        return report

    # ------------------------------------------------------------------------- results

    def summary(self) -> dict:
        """Executor figures for ``metrics.json`` (seconds of simulated time unless noted)."""
        if not self._bound:
            return {}
        lag = np.array(self.kin_lag) if self.kin_lag else np.zeros(1)
        return {
            "agv_contacts": self.agv_contacts,
            "static_contacts": self.static_contacts,
            "min_separation_m": float(self.min_sep) if math.isfinite(self.min_sep) else None,
            "deadlocks": self.deadlocks,
            "executor_replans": self.replans_asked,
            "deviations": self.deviations,
            "swept_checks": self.swept_checks,
            "swept_hits": self.swept_hits,
            "actions_executed": self.actions_done,
            "delay_dependency_wait_s": float(self.dep_wait.sum()),
            "delay_kinematic_s": float(lag.sum() + self.turn_time.sum()),
            "delay_turns_s": float(self.turn_time.sum()),
            "delay_injected_s": float(self.injected.sum()),
            "kinematic_lag_mean_s": float(lag.mean()),
            "physics_dt_s": self.dt,
            "physics_steps": self._step_count,
            "moving_share": self._active / max(1, self._step_count * self.n),
            "real_time_factor": self.sim_s / self._wall if self._wall > 0 else 0.0,
        }

    def trajectory(self) -> dict[str, np.ndarray]:
        """Recorded poses: ``t`` (T,), ``x``, ``y``, ``heading`` (T, N), ``state`` (task
        state, 7 = failed) and ``loaded`` (T, N), and what a renderer needs to draw them:
        ``footprint``, ``body_m``, ``cell_m``, ``tick_s`` and the layout ``grid`` (the loop
        adds ``corridors_json``: the episode's corridors, see ``World.corridor_log``)."""
        if not self._bound:
            return None
        if not self._traj:
            self._record()
        t = np.array([r[0] for r in self._traj])
        pos = np.stack([r[1] for r in self._traj])
        return {
            "t": t, "x": pos[:, :, 0], "y": pos[:, :, 1],
            "heading": np.stack([r[2] for r in self._traj]),
            "state": np.stack([r[3] for r in self._traj]),
            "loaded": np.stack([r[4] for r in self._traj]),
            "footprint": self.k.copy(),
            "body_m": self.fleet.half_size * 2,
            "cell_m": np.array(self.cell_m),
            "tick_s": np.array(self.tick_s),
            "grid": self.layout.grid.copy(),
        }
