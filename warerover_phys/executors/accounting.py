"""The physics executor's contact and clearance accounting, and its recordings.

- contacts come from pymunk collision handlers: AGV-AGV, AGV-obstacle, and a loaded AGV
  against a shelf other than its own (shelves are sensors);
- the true minimum clearance between AGVs (edge to edge between their rectangles, the
  carried shelf included) and each AGV's peak speed, acceleration and turn rate are
  measured at every physics step (:mod:`.measured`); a limit exceeded by more than 5% is a
  counted ``limit_violation``;
- a swept segment query catches any body that moves farther than half its width in one
  physics step (tunnelling);
- open safety corridors are checked every step (``faults.checker``: numpy or python-fcl
  candidates, measured in closed form, :mod:`warerover_phys.faults.intrusion`);
- delay shares (dependency waits, injected delays, turns, kinematic lag) are summed per step;
- poses are recorded at ``trajectory_hz`` into a :class:`~.recording.TrajectoryStore`, with
  what each AGV was doing (:meth:`Accounting.execution`: a few array operations per sample,
  none per step).

The per-step loops (monitors, delay shares, cause labels) run compiled
(:mod:`.step_kernels`, ``engine="numba"``) for fleets of at least :data:`ENGINE_MIN_AGVS`
AGVs, else as numpy (``engine="numpy"``, the reference); both give the same figures bit for
bit.

:meth:`Accounting.summary` gives the figures for ``metrics.json`` and
:meth:`Accounting.trajectory` the recorded poses.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from .bodies import AGV, OBSTACLE, SHELF, SHELF_SIDE
from .causes import CauseRecorder
from .delays import held
from .fleet_state import DRIVE, HOLD, TURN, FleetState
from .measured import ClearanceMonitor, LimitMonitor
from .recording import (
    DELAYED,
    DRIVING,
    FINISHED,
    STANDING,
    TURNING,
    WAITING,
    WORKING,
    TrajectoryStore,
)
from .recording import FAILED as X_FAILED

if TYPE_CHECKING:
    import pymunk

    from ..layout import Layout
    from .adg import Action, ActionGraph
    from .base import TickView
    from .bodies import BodyIO, PhysicalFleet

__all__ = ["ENGINE_MIN_AGVS", "Accounting", "engine_for"]

ENGINE_MIN_AGVS = 0
"""Fleets of at least this many AGVs run the per-step accounting compiled
(:mod:`.step_kernels`); smaller ones the numpy reference (the same figures)."""


def engine_for(n: int) -> str:
    """The accounting engine for a fleet of ``n`` AGVs (``numba`` or ``numpy``)."""
    return "numba" if n >= ENGINE_MIN_AGVS else "numpy"


class Accounting:
    """Counters, per-tick outputs (events, intrusion checks) and the pose recording."""

    def __init__(self, st: FleetState, space: pymunk.Space, fleet: PhysicalFleet, io: BodyIO,
                 adg: ActionGraph, layout: Layout, shelf_of: dict[int, int],
                 trajectory_hz: float, engine: str | None = None,
                 intrusion_checker: str | None = None) -> None:
        n = st.n
        self.st, self.space, self.fleet, self.io, self.adg = st, space, fleet, io, adg
        self.layout = layout
        self._shelf_of = shelf_of
        self._agv_of_shape = fleet.agv_of_shape  # carried shelves' shapes join it
        self.view: TickView | None = None
        # per tick
        self.events: list[tuple[str, dict]] = []
        self.intrusion_checks: list[list[tuple[int, int, float]]] = []
        self.tick_agv_contacts = 0
        # corridors
        self._corridor_keys: tuple[int, ...] = ()
        self._checker = None
        self.intrusion_checker = intrusion_checker
        """``faults.checker`` (None: the schema's default), built on the first corridor."""
        # figures
        self.wall_s = 0.0
        self.steps = 0
        self.agv_contacts = 0
        self.static_contacts = 0
        self.engine = engine_for(n) if engine is None else engine
        """``numba``: the per-step work runs in :mod:`.step_kernels`; ``numpy``: the
        reference (the same figures)."""
        self.clearance = ClearanceMonitor(fleet.half_size, engine=self.engine)
        self.limits = LimitMonitor(st.vmax, st.amax, st.wmax, engine=self.engine)
        self._shelf_side = {sh.id: SHELF_SIDE * sh.size * layout.cell_m for sh in layout.shelves}
        self.shelf_m = np.zeros((n, 2))
        """(N, 2) length and width of the shelf each AGV carries this tick (0: none)."""
        self.deadlocks = 0
        self.replans_asked = 0
        self.deviations = 0
        self.swept_checks = 0
        self.swept_hits = 0
        self._swept_key: tuple | None = None
        self._swept_need = False
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
        self._traj_every = max(1, round(1.0 / (trajectory_hz * st.dt)))
        self._traj = TrajectoryStore(n)
        self._due: tuple | None = None
        """A sample due (time, task states, loaded flags, shelf sizes, execution fields),
        recorded with the poses of that time at the next :meth:`measure` (the poses before
        the next step, or at the end of the tick): no extra read of the bodies."""
        self.plan_tick = np.full(n, -1, dtype=np.int32)
        """Per AGV, the plan tick of the state it drives to or last reached (the arrival
        tick of its latest begun action; -1: none yet), for the recording."""
        self._task_state = np.zeros(n, dtype=np.int8)
        self._loaded = np.zeros(n, dtype=bool)
        self._last_view: tuple = (None, None, None)
        """The view's carried shelves, task states and loads at the last tick."""
        self.causes = CauseRecorder(st, adg)
        """Per-step labels of every AGV's time, per action (:mod:`.causes`)."""
        self._install_handlers()

    def _install_handlers(self) -> None:
        def agv_agv(arbiter, space, data) -> None:
            self.agv_contacts += 1
            self.tick_agv_contacts += 1
            a, b = (self._agv_of_shape[id(s)] for s in arbiter.shapes)
            self.events.append(("contact", {
                "agvs": sorted((a, b)), "t_s": round(self.st.sim_s, 3),
                "states": [list(self.adg.state(a)), list(self.adg.state(b))]}))

        def agv_static(arbiter, space, data) -> None:
            self.static_contacts += 1
            shape = next(s for s in arbiter.shapes if s.collision_type == AGV)
            self.events.append(("static_contact", {
                "agv": self._agv_of_shape[id(shape)], "t_s": round(self.st.sim_s, 3)}))

        def agv_shelf(arbiter, space, data) -> None:
            a, b = arbiter.shapes
            agv_shape, shelf_shape = (a, b) if a.collision_type == AGV else (b, a)
            i = self._agv_of_shape[id(agv_shape)]
            shelf = self._shelf_of.get(id(shelf_shape))
            carried = self.view.carried[i] if self.view is not None else None
            if carried is not None and shelf != carried:
                self.static_contacts += 1

        self.agv_agv_begin = agv_agv
        """The AGV-AGV ``begin`` callback (installed with the pair's ``pre_solve`` by
        :func:`.bodies.unsolved_agv_contacts`: one handler per pair)."""
        self.space.on_collision(AGV, AGV, begin=agv_agv)
        self.space.on_collision(AGV, OBSTACLE, begin=agv_static)
        self.space.on_collision(AGV, SHELF, begin=agv_shelf)

    # ------------------------------------------------------------------------- per tick

    def begin_tick(self, view: TickView) -> bool:
        """Take this tick's view; returns whether who carries which shelf changed since
        the last tick (always on the first)."""
        self.view = view
        self.events, self.intrusion_checks = [], []
        self.tick_agv_contacts = 0
        # (The arrays of the last tick are kept, never changed in place, while the view's
        # tuples are the same: the recorder keeps references to them.)
        now = (tuple(view.carried), tuple(view.task_state), tuple(view.loaded))
        carried = now[0] != self._last_view[0]
        if carried:
            shelf = np.zeros((self.st.n, 2))
            for i, c in enumerate(view.carried):
                if c is not None:
                    shelf[i] = self._shelf_side.get(c, 0.0)
            self.shelf_m = shelf
            self.clearance.set_shelves(shelf / 2)
        if now[1] != self._last_view[1]:
            self._task_state = np.array(view.task_state, dtype=np.int8)
        if now[2] != self._last_view[2]:
            self._loaded = np.array(view.loaded, dtype=bool)
        self._last_view = now
        return carried

    def sync_corridors(self, corridors: dict) -> None:
        """Open corridors go to the corridor checker (``faults.checker``, built on the
        first one)."""
        keys = tuple(sorted(corridors))
        if keys != self._corridor_keys:
            self._corridor_keys = keys
            if keys:
                if self._checker is None:
                    from ..config import FaultsSpec
                    from ..faults.checker import make_checker

                    kind = self.intrusion_checker or FaultsSpec().checker
                    self._checker = make_checker(kind, self.fleet.half_size)
                self._checker.set_corridors([corridors[k] for k in keys])

    # ------------------------------------------------------------------------- actions

    def action_begun(self, i: int, a: Action, t: float) -> None:
        self._act_start[i] = t
        self._act_planned[i] = a.ticks * self.st.tick_s
        self._act_injected[i] = 0.0
        self.plan_tick[i] = a.tick + a.ticks
        self.causes.action_begun(i, a)

    def action_done(self, i: int, t: float) -> None:
        self.actions_done += 1
        self.causes.action_done(i)
        self.kin_lag.append(t - self._act_start[i] - self._act_injected[i] - self._act_planned[i])

    # ------------------------------------------------------------------------- per step

    def after_step(self, raw: np.ndarray, raw_ang: np.ndarray, injected: np.ndarray,
                   t: float) -> None:
        """Sum the step's delay shares, measure clearance and limits and run the swept and
        corridor checks (on the poses before the step, at simulated time ``t``) and record
        poses when due."""
        st = self.st
        self.steps += 1
        self.measure(raw, raw_ang, t)
        if self.engine == "numba":
            self._active += self.causes.step_with_shares(
                injected, self.dep_wait, self.injected, self.turn_time, self._act_injected)
        else:
            self._shares_numpy(injected)
        self._swept_check(raw)
        if self._corridor_keys:
            self._check_corridors(raw, raw_ang)
        if self.steps % self._traj_every == 0:
            self._due = (st.sim_s, self._task_state, self._loaded, self.shelf_m,
                         self.execution(injected))

    def execution(self, injected: np.ndarray | None = None,
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What each AGV does in the step just run, for the recording: ``exec_state``
        (:data:`~.recording.EXEC_STATES`, the priorities of :mod:`.causes`: working, failed,
        delayed, driving, turning, waiting, then standing, or finished with nothing left),
        ``blocker`` (the AGV a waiting one waits for, else -1) and ``plan_tick`` (copies).
        ``injected``: the step's injected-delay mask (None: read from the delays)."""
        st = self.st
        mid = st.sim_s - 0.5 * st.dt
        hold = st.mode == HOLD
        state = np.where(hold & ~st.has_next, FINISHED, STANDING).astype(np.int8)
        state[st.waiting] = WAITING
        state[st.mode == TURN] = TURNING
        state[st.mode == DRIVE] = DRIVING
        if injected is None:
            injected = held(st.delayed_until, st.sim_s, st.dt)
        state[injected & (~hold | st.has_next)] = DELAYED
        state[st.failed] = X_FAILED
        state[(st.hold_until > mid) & (st.last_finish <= mid)] = WORKING
        blocker = np.where(state == WAITING, self.causes.blocker, -1).astype(np.int32)
        return state, blocker, self.plan_tick.copy()

    def _shares_numpy(self, injected: np.ndarray) -> None:
        """The step's delay shares and cause labels, the numpy reference of
        :meth:`.causes.CauseRecorder.step_with_shares`."""
        st = self.st
        busy = (st.mode != HOLD) | st.waiting
        self.dep_wait += st.waiting * st.dt
        self.injected += (injected & (busy | st.pending)) * st.dt
        self.turn_time += (st.mode == TURN) * st.dt
        self._active += int(np.count_nonzero(st.mode != HOLD))
        # A running action's kinematic lag leaves out the time it was held by an injected
        # delay or a failure (a down AGV's action is still running; its repair is not lag).
        self._act_injected += ((injected | st.failed) & (st.mode == DRIVE)) * st.dt
        self.causes.step(injected)

    def _swept_check(self, prev: np.ndarray) -> None:
        """Bodies that moved farther than half their width in one step: look along the
        swept segment for anything they may have passed through."""
        if not self._need_swept():
            return
        pos = np.array([b.position for b in self.fleet.bodies])
        step = np.linalg.norm(pos - prev, axis=1)
        import pymunk

        for i in np.flatnonzero(step > self.fleet.half_size.min(axis=1)):
            self.swept_checks += 1
            me = self.fleet.bodies[i]  # its body shape and its carried shelf's
            hits = self.space.segment_query(tuple(prev[i]), tuple(pos[i]), 0.0,
                                            pymunk.ShapeFilter())
            if any(h.shape is not None and h.shape.body is not me and not h.shape.sensor
                   for h in hits):
                self.swept_hits += 1

    def _need_swept(self) -> bool:
        """Cheap bound: no body can move farther than v_max x headroom x dt (computed once
        for the limits and step in force)."""
        st = self.st
        key = (st.vmax, st.dt)  # the array itself is kept: a new one is a new key
        if self._swept_key is None or key[0] is not self._swept_key[0] or (
                key[1] != self._swept_key[1]):
            self._swept_key = key
            self._swept_need = bool(
                (st.vmax * 2.0 * st.dt > self.fleet.half_size.min(axis=1)).any())
        return self._swept_need

    def _check_corridors(self, pos: np.ndarray, ang: np.ndarray) -> None:
        """Check of every AGV body against the open corridors' protected zones."""
        poses = np.column_stack([pos, ang])
        skip = {c.agv for c in self.view.corridors.values()}
        self.intrusion_checks.append(
            [(h.agv, h.corridor, h.depth_m) for h in self._checker.check(poses, skip)])

    def measure(self, pos: np.ndarray, ang: np.ndarray, t: float) -> None:
        """Clearance and peak speed / acceleration / turn rate at the poses of simulated
        time ``t`` (each time is taken once, whoever calls first); records the pose sample
        due at ``t``."""
        due = self._due
        if due is not None and due[0] == t:
            self._due = None
            self._traj.append(t, pos, ang, *due[1:])
        self.clearance.measure(pos, ang, t)
        self.events.extend(self.limits.measure(pos, ang, t))

    def _record(self) -> None:
        """Record the bodies' poses now (a sample still due first, at its own time)."""
        pos, ang, _, _ = self.io.read()
        due = self._due
        if due is not None:
            self._due = None
            self._traj.append(due[0], pos, ang, *due[1:])
            return
        self._traj.append(self.st.sim_s, pos, ang, self._task_state, self._loaded,
                          self.shelf_m, self.execution())

    # ------------------------------------------------------------------------- results

    def summary(self) -> dict[str, Any]:
        """Executor figures for ``metrics.json`` (seconds of simulated time unless noted)."""
        st = self.st
        lag = np.array(self.kin_lag) if self.kin_lag else np.zeros(1)
        c = self.clearance.min_m
        clear = float(c) if math.isfinite(c) else None
        ratios = self.limits.ratios()
        return {
            "agv_contacts": self.agv_contacts,
            "static_contacts": self.static_contacts,
            "min_clearance_m": clear,
            "min_clearance_t_s": self.clearance.at_s,
            "min_separation_m": clear,
            "limit_violations": self.limits.violations,
            "peak_speed_ratio": ratios["speed"],
            "peak_accel_ratio": ratios["accel"],
            "peak_turn_rate_ratio": ratios["turn_rate"],
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
            "physics_dt_s": st.dt,
            "physics_steps": self.steps,
            "moving_share": self._active / max(1, self.steps * st.n),
            "real_time_factor": st.sim_s / self.wall_s if self.wall_s > 0 else 0.0,
        }

    def trajectory(self) -> dict[str, np.ndarray]:
        """Recorded poses (see :meth:`.physics.PhysicsExecutor.trajectory`); long recordings
        come back as read-only memory maps of the files they were streamed to."""
        if len(self._traj) == 0 or self._due is not None:
            self._record()
        out = self._traj.arrays()
        st = self.st
        out.update({
            "footprint": st.k.copy(),
            "body_m": self.fleet.half_size * 2,
            "limit_speed_mps": self.limits.limits["speed"].copy(),
            "limit_accel_mps2": self.limits.limits["accel"].copy(),
            "limit_turn_rate_radps": self.limits.limits["turn_rate"].copy(),
            "peak_speed_mps": self.limits.peak["speed"].copy(),
            "peak_accel_mps2": self.limits.peak["accel"].copy(),
            "peak_turn_rate_radps": self.limits.peak["turn_rate"].copy(),
            "cell_m": np.array(st.cell_m),
            "tick_s": np.array(st.tick_s),
            "grid": self.layout.grid.copy(),
        })
        return out
