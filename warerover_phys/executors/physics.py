"""Physics executor: the committed plans, carried out by rigid bodies in continuous time.

Each tick (``tick_s`` seconds) the executor

1. hands every new or changed plan to the :class:`~.adg.ActionGraph` (commit cut: the AGV
   keeps the action it is driving, the rest is replaced);
2. draws the tick's random delays (seeded, ``executor.delays``);
3. steps the pymunk world ``tick_s / dt_s`` times. Per step, the plan follower extends
   and starts actions as the ADG allows (or, with ``adg: false``, at their planned ticks:
   naive time-indexed following, for comparison), every AGV's continuous-time reference
   runs through the step (actions and turns end at their exact times inside it), and a
   vectorised control law gives every body the velocity that puts it on its reference at
   the step's end (kinematic drive: the body and its control body get it directly, so with
   no contact the poses at the step ends common to two ``dt_s`` are the same);
4. reports each AGV's discrete state (standing at a cell, or moving between two) for the
   loop to write into the world, blocked AGVs (waiting on a dependency) and AGVs to replan
   (dependency deadlock, deviation from the path). It never touches the world itself.

The work is split by concern, each part in a module whose name says so; they share the
per-AGV arrays of one :class:`~.fleet_state.FleetState`:

- :mod:`.bodies`: building the pymunk world and the AGV bodies (parked AGVs out of the
  space, drive joints only where an obstacle is within reach);
- :mod:`.control`: the control law (compiled in :mod:`.control_nb`);
- :mod:`.follow`: following the dependency graph (decide, start, extend, arrive, delays,
  plan sync and commit cut, ``stop_short``, ``remaining``);
- :mod:`.accounting`: contact and clearance accounting (contact handlers, minimum
  clearance and measured limits from :mod:`.measured`, swept checks, corridor checks,
  delay shares), :meth:`summary` and
  :meth:`trajectory` (poses recorded at ``trajectory_hz``, streamed to disk by
  :mod:`.recording`);
- :mod:`.step_kernels`: the per-step loops over the fleet compiled with numba (accounting,
  the start of a step, the parking and drive-joint tests), each with its numpy reference.

This module builds them (:meth:`PhysicsExecutor.bind`) and runs the tick.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from ..planning.sweep import agv_sweeps
from .accounting import Accounting
from .adg import ActionGraph
from .base import ExecutorSetup, StepReport, TickView
from .bodies import (
    BodyIO,
    ObstacleReach,
    PhysicalFleet,
    build_space,
    cell_centre,
    unsolved_agv_contacts,
)
from .control import OFF_REFERENCE_M, steer, wrap
from .diffdrive import DiffParams, WheelMonitor, sync_references
from .fleet_state import HOLD, FleetState
from .follow import DECIDE_S, PlanFollower
from .measured import LIMIT_TOLERANCE
from .step_kernels import settled, step_prelude

if TYPE_CHECKING:
    from ..config import ExecutorSpec

__all__ = ["PhysicsExecutor", "PARK_EPS_M", "PARK_SPEED", "PARK_EPS_RAD"]

PARK_EPS_M = 1e-3
"""A standing AGV is parked (``executor.park``) once its body is this close to its hold
point (metres), ..."""
PARK_SPEED = 1e-3
"""... moves slower than this (m/s, and turns slower than this in rad/s) ..."""
PARK_EPS_RAD = 1e-3
"""... and faces its heading to within this (radians)."""
STATIC_AFTER_S = 2.0
"""A parked AGV leaves the space (:meth:`PhysicsExecutor._park_settled`) once it has
stood this long since its last action (simulated seconds), or at once with nothing left
to do."""
REACH_SLOP_M = 0.05
"""Extra reach (metres) of the obstacle test that keeps a body's drive joints in the space
(:meth:`PhysicalFleet.set_joints`), beyond twice the farthest it can move in a step."""


class PhysicsExecutor:
    name = "physics"

    def __init__(self, spec: ExecutorSpec) -> None:
        self.spec = spec
        self._bound = False

    @property
    def acyclic_plans(self) -> bool:
        """Whether plans must have no cycle of moves within a tick (``PlanRequest.acyclic``):
        following the action dependency graph (``executor.adg``), an AGV enters a cell only
        once the AGV before it has left it, so a rotation would never start."""
        return bool(getattr(self.spec, "adg", True))

    # ------------------------------------------------------------------------- set-up

    def bind(self, setup: ExecutorSetup) -> None:
        spec, layout, agvs = self.spec, setup.layout, setup.agvs
        self.layout = layout
        self.tick_s = setup.tick_s
        self.steps_per_tick = max(1, round(self.tick_s / spec.dt_s))
        self.dt = self.tick_s / self.steps_per_tick
        self.space, shelf_of = build_space(layout)
        n = len(agvs)
        self.n = n
        k = np.array([a.k for a in agvs])
        poses = [(*cell_centre(a.start[1], a.k, layout.cols, layout.cell_m), 0.0) for a in agvs]
        self.fleet = PhysicalFleet.add_to(
            self.space, poses, [tuple(a.spec.body_m) for a in agvs],
            [a.spec.mass_kg for a in agvs], [a.spec.max_accel_mps2 for a in agvs])
        self.io = BodyIO(self.space, self.fleet)
        self._reach = ObstacleReach(layout)
        self._no_shelf = np.zeros((n, 2))
        self._settled_ids = np.zeros(n, dtype=np.int64)
        self.rng = rng = setup.rng
        lo, hi = spec.speed_scale
        self.scale = rng.uniform(lo, hi, n) if hi > lo else np.full(n, lo)
        no_slip = np.array([a.spec.drive != "omni" for a in agvs], dtype=bool) \
            if getattr(spec, "no_slip", False) else None
        self.state = FleetState(
            cols=layout.cols, cell_m=layout.cell_m, tick_s=self.tick_s, dt=self.dt, k=k,
            vmax=np.array([a.spec.max_speed_mps for a in agvs]) * self.scale,
            amax=np.array([a.spec.max_accel_mps2 for a in agvs]),
            wmax=np.array([a.spec.max_turn_rate_radps for a in agvs]),
            omni=np.array([a.spec.drive == "omni" for a in agvs]),
            origin=np.array([p[:2] for p in poses], dtype=float),
            no_slip=no_slip, diff=None if no_slip is None else DiffParams.of(agvs),
            decide_every=max(1, round(DECIDE_S / self.dt)))
        sweeps = agv_sweeps([a.spec for a in agvs], layout.cell_m, layout)
        if not getattr(spec, "shelf_sweeps", False):
            sweeps = {i: sw._replace(shelf_cells=()) for i, sw in sweeps.items()}
        self.adg = ActionGraph(layout.cols, {a.id: a.k for a in agvs},
                               sweeps=sweeps,
                               rows=layout.rows,
                               latency_s=getattr(spec, "comm_latency_s", 0.0))
        self.acc = Accounting(self.state, self.space, self.fleet, self.io, self.adg, layout,
                              shelf_of, spec.trajectory_hz,
                              intrusion_checker=setup.intrusion_checker)
        self.follow = PlanFollower(self.state, self.adg, spec, rng, self.acc)
        self._mass = np.array([a.spec.mass_kg for a in agvs], dtype=float)
        self._payload = np.array([a.spec.payload_kg for a in agvs], dtype=float) \
            if getattr(spec, "payload", False) else np.zeros(n)
        self._amax_empty = self.state.amax.copy()
        self._amax_loaded = self._amax_empty * self._mass / (self._mass + self._payload)
        self._loaded = np.zeros(n, dtype=bool)
        """Loaded AGVs as the payload limits last saw them."""
        self._comm_wait_s = 0.0
        """AGV-seconds spent with free cells ahead, waiting for the message saying so."""
        self.contact_until = np.zeros(n)
        """Simulated time until which an AGV brakes after an AGV-AGV contact began."""
        self._tick = 0
        self._last_contact: tuple | None = None
        unsolved_agv_contacts(self.space, self.fleet.agv_of_shape, self._contact,
                              begin=self.acc.agv_agv_begin)
        self._shelf_contacts = bool(getattr(spec, "shelf_contacts", False))
        self._park = bool(getattr(spec, "park", True))
        self.parked_steps = 0
        """AGV-steps spent parked (``executor.park``)."""
        self._off = np.zeros(n, dtype=bool)
        self._step_bufs = (np.empty(n, dtype=bool), np.empty(n, dtype=bool), np.empty((n, 2)))
        """The injected and delayed masks and the reference points of a physics step."""
        self._all_bodies = np.ones(n, dtype=bool)
        self.off_reference = 0
        """Times a body was found off its reference (:meth:`_off_reference_events`)."""
        half = self.fleet.half_size
        self._reach_margin = (2.0 * self.state.vmax + 2.0 * self.state.wmax
                              * np.hypot(half[:, 0], half[:, 1])) * (
            self.dt * self.state.decide_every) + REACH_SLOP_M
        """Per AGV: how far (metres) beyond its box an obstacle keeps its drive joints in
        (twice the farthest it can move before the next look, plus the slop)."""
        self._wheels = None if no_slip is None else WheelMonitor(self.state.diff, no_slip,
                                                                 LIMIT_TOLERANCE)
        """No-slip drive: the wheel speeds measured from the poses (AGVs with wheel
        limits)."""
        self._bound = True

    def _contact(self, a: int, b: int, point: tuple[float, float]) -> None:
        """Two AGVs touch (the contact is not solved): both brake at their limit for a tick."""
        key = (min(a, b), max(a, b), self.state.sim_s)
        if key == self._last_contact:  # the wildcard handler runs once per shape
            return
        self._last_contact = key
        until = self.state.sim_s + self.tick_s
        self.contact_until[[a, b]] = np.maximum(self.contact_until[[a, b]], until)
        self.acc.events.append(("contact_brake", {
            "tick": self._tick, "agvs": sorted((a, b)), "t_s": round(self.state.sim_s, 3),
            "x": round(point[0], 3), "y": round(point[1], 3)}))

    # ------------------------------------------------------------------------- the tick

    def step(self, view: TickView) -> StepReport:
        if not self._bound:
            raise RuntimeError("PhysicsExecutor.step before bind()")
        wall0 = time.perf_counter()
        acc, follow = self.acc, self.follow
        carried = acc.begin_tick(view)
        self._tick = view.tick
        self._apply_payload(view.loaded)
        if carried:  # who carries a shelf changed (or the first tick)
            self.adg.set_loaded([c is not None for c in view.carried])
        if self._shelf_contacts and self.fleet.carry_shelves(
                self.space, self.acc.shelf_m[:, 0], self.io.read()[1]):
            self.io.reorder()
        follow.sync_plans(view)
        acc.events.extend(follow.draw_delays())
        follow.sync_failed(view.failed)
        acc.sync_corridors(view.corridors)
        for s in range(self.steps_per_tick):
            self._physics_step(decide=(s % self.state.decide_every == 0))
        pos, ang, vel, _ = self.io.read()
        acc.measure(pos, ang, self.state.sim_s)
        report = StepReport(collisions=acc.tick_agv_contacts,
                            poses=np.column_stack([pos, ang]).astype(float),
                            speeds=np.hypot(vel[:, 0], vel[:, 1]).astype(float))
        follow.write_back(view, pos, report)
        report.events = acc.events + report.events
        report.intrusion_checks = acc.intrusion_checks
        acc.wall_s += time.perf_counter() - wall0
        return report

    def _apply_payload(self, loaded: tuple[bool, ...]) -> None:
        """``executor.payload``: AGVs that picked up or put down a shelf since the last tick
        get the acceleration limit of their new load (drive force / (mass + payload)) in
        the control law and the measured-limit checks, and their body its new mass."""
        if not self._payload.any() or len(loaded) != self.n:
            return
        now = np.asarray(loaded, dtype=bool)
        changed = np.flatnonzero(now != self._loaded)
        if len(changed) == 0:
            return
        self._loaded = now
        st = self.state
        st.amax = np.where(now, self._amax_loaded, self._amax_empty)
        self.acc.limits.set_limit("accel", st.amax)
        for i in changed:
            self.fleet.set_mass(int(i), float(self._mass[i] + (self._payload[i] if now[i]
                                                                  else 0.0)))

    def _physics_step(self, decide: bool) -> None:
        st = self.state
        raw, raw_ang, v_now, w_now = self.io.read()
        t = st.sim_s
        if st.no_slip is not None:  # no-slip drive: driving references start from the bodies
            sync_references(st, raw, v_now)
        n = self.n
        injected, delayed, ref0 = self._step_bufs  # (used within the step only)
        off = np.empty(n, dtype=bool)  # (kept as _off until the next step)
        step_prelude(raw, st.mode, st.s_ref, st.origin, st.direction, st.hold_xy,
                     st.delayed_until, st.failed, self.contact_until, t, st.dt, OFF_REFERENCE_M,
                     injected, delayed, off, ref0)
        self._off_reference_events(off, raw)
        self.follow.advance(raw, raw_ang, delayed, decide)
        self._comm_wait_s += float(np.count_nonzero(st.listening)) * st.dt
        # Commands of AGVs out of the space that stay put are read by no one.
        vel, w = steer(st, raw, raw_ang, v_now, ref0, self.fleet.static & (st.mode == HOLD))
        if self._shelf_contacts:
            self.fleet.orient_shelves(raw_ang)
        # Kinematic drive: the bodies get the step's velocities directly (pymunk moves
        # them with their present velocity before it solves joints and contacts), their
        # control bodies the same, so the drive joints exert nothing unless a contact
        # changed a body's velocity.
        self.io.write(vel, w, bodies=self._all_bodies)
        unparked = self._park and self._update_parking(raw, raw_ang, v_now, w_now, vel, w,
                                                       decide)
        if decide or unparked:
            self._keep_joints(raw, raw_ang)
        self.space.step(st.dt)
        st.sim_s = t + st.dt
        self.acc.after_step(raw, raw_ang, injected, t)
        if self._wheels is not None:
            self.acc.events.extend(self._wheels.measure(raw, raw_ang, t))

    def _keep_joints(self, pos: np.ndarray, ang: np.ndarray) -> None:
        """Drive joints in the space for the moving bodies that could touch an obstacle
        before the next look (decision steps, and steps in which a parked AGV moves off),
        out for every other (:meth:`.bodies.PhysicalFleet.set_joints`)."""
        fleet = self.fleet
        shelf = self.acc.shelf_m / 2 if self._shelf_contacts else self._no_shelf
        want = self._reach.fleet_near(pos, ang, fleet.half_size, shelf, self._reach_margin,
                                      fleet.parked)
        fleet.set_joints(self.space, want)

    def _off_reference_events(self, off: np.ndarray, pos: np.ndarray) -> None:
        """``off``: driving bodies more than :data:`~.control.OFF_REFERENCE_M` behind their
        reference points along the run (held back by a contact or an obstacle; computed
        with the step's other masks by :func:`~.step_kernels.step_prelude`): their
        references brake until the bodies are back. Each new such episode is an
        ``off_reference`` event. (A sideways offset is no hold-up: the control law steers
        it out, and a large one is a deviation the follower replans.)"""
        new = off & ~self._off
        self._off = off
        if not new.any():
            return
        st = self.state
        lag = st.s_ref - st.along(pos)
        for i in np.flatnonzero(new):
            self.off_reference += 1
            self.acc.events.append(("off_reference", {
                "tick": self._tick, "agv": int(i), "t_s": round(st.sim_s, 3),
                "m": round(float(lag[i]), 3)}))

    def _update_parking(self, pos: np.ndarray, ang: np.ndarray, v: np.ndarray,
                        w: np.ndarray, cmd: np.ndarray, cmd_w: np.ndarray,
                        look: bool) -> bool:
        """``executor.park``: unpark parked AGVs that are about to move (no longer
        standing), and, when ``look``ing (the follower's decision steps), park standing
        AGVs whose bodies have settled on their hold points (see :data:`PARK_EPS_M`). Runs
        after this step's commands (``cmd``, ``cmd_w``) are written, before the step;
        returns whether any AGV was unparked."""
        st, fleet = self.state, self.fleet
        parked = fleet.parked
        self.parked_steps += fleet.n_parked
        changed = unparked = False
        if fleet.n_parked:
            for i in np.flatnonzero(parked & (st.mode != HOLD)):
                i = int(i)
                changed |= fleet.unpark(self.space, i, tuple(cmd[i]), float(cmd_w[i]))
                unparked = True
        if look:
            changed |= self._park_settled(pos, ang, v, w)
        if changed:
            self.io.reorder()
        return unparked

    def _park_settled(self, pos: np.ndarray, ang: np.ndarray, v: np.ndarray,
                      w: np.ndarray) -> bool:
        """Park the standing AGVs whose bodies have settled on their hold points, and take
        out of the space (static stand-ins where the next step's deadbeat command would
        take them, :func:`.control.steer`) those with nothing left to do and those that
        have stood for :data:`STATIC_AFTER_S` (a body in the space costs pymunk's step and
        the batch reads and writes every step; leaving and coming back cost a few hundred
        microseconds, a re-read of the space's body order included: at 1,000 AGVs hundreds
        stand in queues for minutes, while most waits are short). Whether any body left."""
        st, fleet = self.state, self.fleet
        ids = self._settled_ids
        k = settled(st.mode, fleet.parked, st.hold_xy, pos, np.ascontiguousarray(v),
                    np.ascontiguousarray(w), st.heading, ang, st.speed, PARK_EPS_M,
                    PARK_SPEED, PARK_EPS_RAD, ids)
        long = st.sim_s - st.last_finish >= STATIC_AFTER_S - 1e-9
        left = False
        ns = st.no_slip

        def hold_pose(i: int) -> tuple[float, float, float]:
            if ns is not None and ns[i]:  # no-slip drive: parks where it stands (no sideways jump)
                return float(pos[i, 0]), float(pos[i, 1]), float(ang[i])
            return (float(st.hold_xy[i, 0]), float(st.hold_xy[i, 1]),
                    float(ang[i] + wrap(st.heading[i] - ang[i])))

        for i in ids[:k].tolist():
            out = not st.has_next[i] or bool(long[i])
            fleet.park(self.space, i, *hold_pose(i), static=out)
            left |= out
        for i in np.flatnonzero(fleet.parked & ~fleet.static & long
                                & (st.mode == HOLD)).tolist():
            fleet.leave(self.space, i, *hold_pose(i))
            left = True
        return left

    # ------------------------------------------------------------------------- fault hooks

    def remaining(self, i: int) -> list[tuple[int, int]]:
        """What AGV ``i`` still has to drive, as states (running action, then the rest)."""
        return self.follow.remaining(i)

    def stop_short(self, i: int, cells: frozenset[int], view: TickView) -> tuple[bool, bool]:
        """A corridor opened over ``cells``: stop AGV ``i`` as soon as its braking distance
        allows; see :meth:`.follow.PlanFollower.stop_short`."""
        return self.follow.stop_short(i, cells, view)

    # ------------------------------------------------------------------------- state views

    @property
    def mode(self) -> np.ndarray:
        """Each AGV's driving mode (``fleet_state.HOLD`` / ``TURN`` / ``DRIVE``)."""
        return self.state.mode

    @property
    def sim_s(self) -> float:
        """Simulated time (seconds)."""
        return self.state.sim_s

    @property
    def delayed_until(self) -> np.ndarray:
        """Simulated time until which an injected delay holds each AGV (writable)."""
        return self.state.delayed_until

    @property
    def last_finish(self) -> np.ndarray:
        """Simulated time at which each AGV last finished an action."""
        return self.state.last_finish

    @property
    def _wall(self) -> float:
        """Wall seconds spent in :meth:`step` (``tools/bench_physics.py`` reads it)."""
        return self.acc.wall_s if self._bound else 0.0

    # ------------------------------------------------------------------------- results

    def summary(self) -> dict:
        """Executor figures for ``metrics.json`` (seconds of simulated time unless noted)."""
        if not self._bound:
            return {}
        out = self.acc.summary()
        spec = self.spec
        # Omnidirectional AGVs drive sideways by design: the slip figure is the
        # differential-drive AGVs' (trajectories.npz has every AGV's).
        lateral = self.acc.limits.lateral[~self.state.omni]
        out.update({
            "peak_lateral_speed_mps": float(lateral.max()) if len(lateral) else 0.0,
            "no_slip": bool(getattr(spec, "no_slip", False)),
            "payload": bool(getattr(spec, "payload", False)),
            "comm_latency_s": float(getattr(spec, "comm_latency_s", 0.0)),
            "delay_comm_latency_s": self._comm_wait_s,
            "parked_agv_s": self.parked_steps * self.dt,
            "off_reference": self.off_reference,
        })
        if self.follow.reorder is not None:
            out.update(self.follow.reorder.summary())
        if self._wheels is not None and len(self._wheels.rows):
            out["limit_violations"] += self._wheels.violations
            out["wheel_speed_violations"] = self._wheels.violations
            out["peak_wheel_speed_ratio"] = self._wheels.ratio()
        return out

    def cause_log(self):
        """Every finished action with the labelled physics steps of its interval
        (:class:`~.causes.CauseLog`), for the open-loop gap's split of lost time."""
        return self.acc.causes.log() if self._bound else None

    def trajectory(self) -> dict[str, np.ndarray] | None:
        """Recorded poses: ``t`` (T,), ``x``, ``y``, ``heading`` (T, N), ``state`` (task
        state, 7 = failed) and ``loaded`` (T, N), what each AGV was doing (``exec_state``,
        ``blocker``, ``plan_tick``: :mod:`.recording`), and what a renderer needs to draw them:
        ``footprint``, ``body_m``, ``cell_m``, ``tick_s`` and the layout ``grid`` (the loop
        adds ``corridors_json``: the episode's corridors, see ``World.corridor_log``).
        Recordings longer than :data:`~.recording.CHUNK` samples are read-only memory maps
        of files in a temporary folder, removed when this executor is garbage collected."""
        if not self._bound:
            return None
        out = self.acc.trajectory()
        out["limit_accel_mps2"] = self._amax_empty.copy()
        out["limit_accel_loaded_mps2"] = self._amax_loaded.copy()
        out["peak_accel_ratio"] = self.acc.limits.peak_ratio("accel")
        out["peak_lateral_speed_mps"] = self.acc.limits.lateral.copy()
        if self._wheels is not None and len(self._wheels.rows):
            d = self.state.diff
            out["wheel_base_m"] = d.half_base * 2
            out["limit_wheel_speed_mps"] = d.wheel_max.copy()
            out["peak_wheel_speed_mps"] = self._wheels.peak.copy()
        return out
