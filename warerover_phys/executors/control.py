"""The physics executor's control law: exact references and deadbeat tracking.

Every AGV has a continuous-time reference, advanced once per physics step by
:func:`run_references` and evaluated analytically, so it is the same at every step end
whatever ``dt``:

- along the current straight run a reference point runs the time-optimal trapezoid to the
  stop point (accelerate at ``a`` to ``v_max``, cruise, brake at ``a`` to stand exactly on
  it; a triangle when the run is too short), recomputed from its present position and speed
  whenever the stop point moves (:func:`_phases`, :func:`_eval`); a delayed or failed AGV's
  reference brakes at ``a`` from where it is;
- a turning AGV's reference heading turns at ``max_turn_rate``.

An action that ends inside a step is an *event* at its exact time (:func:`_time_to`): the
follower finishes it there and the time left in the step goes to the next action (a move
starts at the exact end of its turn; a run goes on into its next cell without a pause).
Events are defined on the reference, not on the body.

The body tracks the reference deadbeat (:func:`steer`): the velocity commanded for the step
is ``(ref(t + dt) - pos(t)) / dt`` (and the same for the angle), which obeys the limits
because the reference does; the executor gives it to the body directly (and to its control
body, so the drive joints exert nothing), so an unobstructed body ends every step on the
reference up to float error. The command still goes through :func:`limit_command` (at most
``v_max``, at most ``a dt`` away from the body's present velocity): a body that was put off
its reference (a contact, a blocked move) cannot exceed its limits catching up. Standing
AGVs hold their cell centre (deadbeat within a few millimetres, on the braking curve farther
out). With ``executor.no_slip`` the differential-drive rows get the unicycle law of
:mod:`.diffdrive` instead (velocity along the heading only, every limit kept by
construction).

The numpy functions here are the reference. The executor runs the same arithmetic compiled
(:mod:`.control_nb`, bit for bit the same numbers): :func:`steer` and the follower's event
loop use the kernels whenever :data:`COMPILED` is set (the default where numba imports;
:func:`steer_numpy` and :func:`run_references` are the numpy versions,
:func:`run_references_compiled` the compiled one with the same interface).
"""

from __future__ import annotations

import math

import numpy as np

from . import diffdrive
from .control_nb import advance_rows, steer_rows
from .fleet_state import DRIVE, TURN, FleetState

__all__ = ["COMPILED", "ARRIVE_EPS_M", "TURN_EPS_RAD", "ALIGN_EPS_RAD", "OFF_REFERENCE_M",
           "HOLD_SPEED", "limit_command", "run_references", "steer",
           "stop_speed", "wrap", "run_references_compiled", "steer_compiled", "steer_numpy"]

ARRIVE_EPS_M = 0.02
"""A run continues into its next action without stopping only if its stop point lies more
than this beyond the end of the running action (metres)."""
TURN_EPS_RAD = 0.01
"""A move needs a turn first if the heading is off by more than this."""
ALIGN_EPS_RAD = 0.03
"""Largest heading error of a body that follows its turning reference (radians): with
deadbeat tracking the body is on the reference at every step end, so a turn ends exactly
when its reference heading arrives."""
OFF_REFERENCE_M = 0.05
"""Sanity check: a driving body this far (metres) behind its reference point along the
run at a step's start was held back (a contact, an obstacle): its reference brakes at the
limit until the body is back, and the executor reports it (``off_reference`` events)."""
EVENT_EPS_S = 1e-9
"""An event this close after a step's end (seconds; float error) belongs to that step, so
that an action that ends on a step boundary ends in the step before it, whatever ``dt``."""
HOLD_SPEED = 0.3
"""m/s: fastest approach of a standing body that is off its hold point."""


def _numba_available() -> bool:
    try:
        import numba  # noqa: F401
    except ImportError:  # pragma: no cover - numba is a dependency
        return False
    return True


COMPILED = _numba_available()
"""Run the control law compiled (:mod:`.control_nb`; the same numbers as the numpy
reference). The kernels compile once per numba cache (2.8-3.7 s of CPU measured); a later
process pays numba's import (~0.5 s of CPU) and loads them (~0.6 s). Per physics step they
save 0.5-0.7 ms of CPU whatever the fleet size (the numpy law is bound by its number
of numpy calls, not by its rows), so they are always used. Tests set it False to run the
numpy reference."""


def wrap(a: np.ndarray | float) -> np.ndarray | float:
    """Angles wrapped to ``[-pi, pi)``."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def stop_speed(d: np.ndarray, a: np.ndarray, dt: float, v_prev: np.ndarray) -> np.ndarray:
    """Highest speed (m/s) at the end of this step from which braking at ``a`` still stops
    within the distance ``d`` (metres) left at its start, for a speed profile integrated by
    the trapezoidal rule (``s += (v_prev + v) / 2 dt``).

    Solves ``v^2 / (2 a) = d - (v_prev + v) / 2 dt`` (what is left after the step is the
    braking distance from ``v``): ``v = sqrt(a^2 dt^2 / 4 + 2 a d - a dt v_prev) - a dt / 2``.
    From ``v_prev = sqrt(2 a d)`` this gives exactly ``v_prev - a dt``. Used by the no-slip
    law to keep a body that steers back onto its path from braking too late.

    >>> one = np.array([1.0])
    >>> float(stop_speed(np.array([0.0]), one, 0.02, np.array([0.0]))[0])
    0.0
    >>> v0 = np.sqrt(2 * 2.0)  # on the braking curve 2 m before the stop
    >>> round(float(v0 - stop_speed(np.array([2.0]), one, 0.02, np.array([v0]))[0]), 12)
    0.02
    """
    h = 0.5 * a * dt
    r = h * h + 2.0 * a * np.maximum(d, 0.0) - a * dt * v_prev
    return np.maximum(np.sqrt(np.maximum(r, 0.0)) - h, 0.0)


def limit_command(cmd: np.ndarray, v_now: np.ndarray, vmax: np.ndarray, amax: np.ndarray,
                  dt: float) -> np.ndarray:
    """``cmd`` (N, 2) capped at speed ``vmax`` and moved to within ``amax dt`` of the
    bodies' present velocities ``v_now`` (both as vectors). A tolerance of 1e-9 relative
    leaves commands that obey the limits up to float error untouched."""
    speed2 = np.einsum("ij,ij->i", cmd, cmd)
    over = speed2 > (vmax * (1 + 1e-9)) ** 2
    if over.any():
        cmd = cmd.copy()
        cmd[over] *= (vmax[over] / np.sqrt(speed2[over]))[:, None]
    dv = cmd - v_now
    step2 = np.einsum("ij,ij->i", dv, dv)
    room = amax * dt
    far = step2 > (room * (1 + 1e-9)) ** 2
    if not far.any():
        return cmd
    out = cmd.copy()
    out[far] = v_now[far] + dv[far] * (room[far] / np.sqrt(step2[far]))[:, None]
    return out


# ----------------------------------------------------------------------------- the reference


def _phases(d: np.ndarray, v: np.ndarray, vmax: np.ndarray, a: np.ndarray,
            braking: np.ndarray) -> tuple[np.ndarray, ...]:
    """The time-optimal profile from speed ``v`` (m/s) to standing still ``d`` metres ahead:
    ``(vc, t1, t2, t3, d1, d2)``: accelerate at ``a`` to ``vc`` in ``t1`` s over ``d1`` m,
    cruise at ``vc`` for ``t2`` s over ``d2`` m, brake at ``a`` to 0 in ``t3`` s. Braking
    (``braking``: delayed or failed), or on or above the braking curve
    (``v^2 >= 2 a d``), it brakes at once (and may then end past ``d``: callers stop it
    there)."""
    v = np.clip(v, 0.0, vmax)
    d = np.maximum(d, 0.0)
    now = braking | (v * v >= 2.0 * a * d)
    vc = np.where(now, v, np.maximum(np.minimum(np.sqrt(a * d + 0.5 * v * v), vmax), v))
    t1 = (vc - v) / a
    d1 = 0.5 * (vc * vc - v * v) / a
    d2 = np.where(now, 0.0, np.maximum(d - d1 - 0.5 * vc * vc / a, 0.0))
    t2 = np.where(vc > 0, d2 / np.maximum(vc, 1e-300), 0.0)
    return v, vc, t1, t2, vc / a, d1, d2


def _eval(ph: tuple[np.ndarray, ...], a: np.ndarray, tau: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray]:
    """Distance covered (m) and speed (m/s) of the profile ``ph`` after ``tau`` seconds."""
    v, vc, t1, t2, t3, d1, d2 = ph
    u1 = np.minimum(tau, t1)
    u2 = np.clip(tau - t1, 0.0, t2)
    u3 = np.clip(tau - t1 - t2, 0.0, t3)
    s = v * u1 + 0.5 * a * u1 * u1 + vc * u2 + vc * u3 - 0.5 * a * u3 * u3
    speed = np.where(tau < t1, v + a * u1, np.where(tau < t1 + t2, vc, vc - a * u3))
    return s, np.maximum(speed, 0.0)


def _time_to(ph: tuple[np.ndarray, ...], a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Seconds until the profile ``ph`` has covered ``x`` metres (inf if it stops short)."""
    v, vc, t1, t2, t3, d1, d2 = ph
    x = np.maximum(x, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.sqrt(v * v + 2.0 * a * x)
        ta = np.where(r1 + v > 0, 2.0 * x / (r1 + v), 0.0)
        tb = t1 + (x - d1) / vc
        x3 = x - d1 - d2
        disc = vc * vc - 2.0 * a * x3
        r3 = np.sqrt(np.maximum(disc, 0.0))
        tc = t1 + t2 + np.where(vc + r3 > 0, 2.0 * x3 / (vc + r3), 0.0)
    out = np.where(x <= d1, ta, np.where(x <= d1 + d2, tb, tc))
    return np.where((x > d1 + d2) & (disc < -1e-12 * np.maximum(vc * vc, 1.0)), np.inf, out)


def run_references(st: FleetState, idx: np.ndarray, h: np.ndarray, braking: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Advance the references of AGVs ``idx`` by ``h`` seconds each, or up to their next
    event (a turn's reference heading arrives; a run's reference point reaches the end of
    the running action); ``braking``: their references brake at the limit (delayed or
    failed). Returns the seconds used and which of them stopped at an event (the
    follower finishes their actions there and gives them what is left)."""
    used = h.copy()
    event = np.zeros(len(idx), dtype=bool)
    mode = st.mode[idx]
    turn = mode == TURN
    if turn.any():
        j = idx[turn]
        left = st.heading[j] - st.ang_ref[j]  # both unwrapped (see follow._decide)
        need = np.abs(left) / st.wmax[j]
        done = need <= h[turn] + EVENT_EPS_S
        st.ang_ref[j] = np.where(done, st.heading[j],
                                 st.ang_ref[j] + np.sign(left) * st.wmax[j] * h[turn])
        used[turn] = np.where(done, np.minimum(need, h[turn]), h[turn])
        event[turn] = done
    drive = mode == DRIVE
    if drive.any():
        j = idx[drive]
        a, s0 = st.amax[j], st.s_ref[j]
        ph = _phases(st.stop_s[j] - s0, st.speed[j], st.vmax[j], a, braking[drive])
        hj = h[drive]
        # The event: the end of the running action (at the stop point, where the profile
        # ends: a braking reference that overshoots it is stopped there).
        x_end = st.cur_end[j] - s0
        t_end = _time_to(ph, a, x_end)
        t_stop = _time_to(ph, a, st.stop_s[j] - s0)
        at_stop = st.cur_end[j] >= st.stop_s[j] - 1e-12
        t_end = np.where(at_stop, np.minimum(t_end, t_stop), t_end)
        done = t_end <= hj + EVENT_EPS_S
        tau = np.where(done, np.minimum(t_end, hj), hj)
        s, v = _eval(ph, a, tau)
        s = np.minimum(s0 + s, np.maximum(st.stop_s[j], s0))
        s = np.where(done, st.cur_end[j], s)
        v = np.where(done & at_stop, 0.0, v)
        st.s_ref[j] = s
        st.speed[j] = v
        used[drive] = tau
        event[drive] = done
    return used, event


def run_references_compiled(st: FleetState, idx: np.ndarray, h: np.ndarray,
                            braking: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`run_references` compiled (:func:`.control_nb.advance_rows`): the same
    results and the same writes (``idx``: distinct AGVs)."""
    idx = np.asarray(idx, dtype=np.int64)
    left = np.zeros(st.n)
    left[idx] = h
    brk = np.zeros(st.n, dtype=bool)
    brk[idx] = braking
    used = np.zeros(st.n)
    events = np.empty(len(idx), dtype=np.int64)
    k = advance_rows(False, idx, left, brk, st.mode, st.heading, st.ang_ref, st.wmax, st.amax,
                     st.vmax, st.s_ref, st.stop_s, st.cur_end, st.speed, used, events)
    return used[idx], np.isin(idx, events[:k])


# ----------------------------------------------------------------------------- the body


def steer(st: FleetState, pos: np.ndarray, ang: np.ndarray, v_now: np.ndarray,
          ref0: np.ndarray, skip: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`steer_numpy`'s commands, compiled (:func:`.control_nb.steer_rows`) when
    :data:`COMPILED` is set. ``skip`` ((N,) bool): rows whose commands nobody reads (the
    compiled law leaves them zero; the numpy one computes them anyway)."""
    if not COMPILED:
        return steer_numpy(st, pos, ang, v_now, ref0)
    return steer_compiled(st, pos, ang, v_now, ref0, skip)


def steer_compiled(st: FleetState, pos: np.ndarray, ang: np.ndarray, v_now: np.ndarray,
                   ref0: np.ndarray, skip: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`steer_numpy` compiled (:func:`.control_nb.steer_rows`; the no-slip rows then
    by :func:`.diffdrive.steer`): the same commands (zero on the rows ``skip``)."""
    n = st.n
    cmd = np.empty((n, 2))
    w = np.empty(n)
    pos = np.ascontiguousarray(pos, dtype=np.float64)
    ang = np.ascontiguousarray(ang, dtype=np.float64)
    if skip is None:
        skip = np.zeros(n, dtype=np.bool_)
    steer_rows(float(st.dt), st.mode, st.origin, st.direction, st.s_ref, st.hold_xy, st.ang_ref,
               st.heading, st.vmax, st.amax, st.wmax, pos, ang,
               np.ascontiguousarray(v_now, dtype=np.float64),
               np.ascontiguousarray(ref0, dtype=np.float64), cmd, w, skip)
    if st.no_slip is not None and st.no_slip.any():
        diffdrive.steer(st, pos, ang, v_now, cmd, w, skip)
    return cmd, w


def steer_numpy(st: FleetState, pos: np.ndarray, ang: np.ndarray, v_now: np.ndarray,
                ref0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Velocities ``(N, 2)`` and turn rates ``(N,)`` that take bodies at ``pos`` / ``ang``
    (moving at ``v_now``, (N, 2)) onto their references at the end of this step (the
    references already advanced by :func:`run_references`; ``ref0``: the reference points
    at the step's start). The reference's own velocity over the step plus a pull onto it:
    the whole error in one step (deadbeat) when that is within braking reach, else on the
    braking curve ``sqrt(2 a e)`` (a body put off its reference does not overshoot it and
    swing around it); standing bodies approach at most :data:`HOLD_SPEED`."""
    dt, a = st.dt, st.amax
    target = st.ref_xy()
    err = ref0 - pos
    dist = np.sqrt(np.einsum("ij,ij->i", err, err))
    hold = st.mode != DRIVE
    cap = np.sqrt(2 * a * dist)
    cap = np.where(hold, np.minimum(cap, HOLD_SPEED), cap)
    far = dist / dt > cap
    vel = (target - pos) / dt
    if far.any():
        vel[far] = (target[far] - ref0[far]) / dt + err[far] * (cap[far] / dist[far])[:, None]
    want = np.where(st.mode == TURN, st.ang_ref, st.heading)
    w = np.clip(wrap(want - ang) / dt, -st.wmax, st.wmax)
    cmd = limit_command(vel, v_now, st.vmax, a, dt)
    if st.no_slip is not None and st.no_slip.any():
        diffdrive.steer(st, pos, ang, v_now, cmd, w)
    return cmd, w
