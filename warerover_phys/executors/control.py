"""The physics executor's control law: control-body velocities from the AGVs' references.

Vectorised over the fleet, once per physics step. Along the current straight run a
reference point runs a trapezoid to the stop point that is exact *in steps of dt*:
``v = min(v_max * scale, v_prev + a dt, v_stop)`` with the position integrated by the
trapezoidal rule, ``s += (v_prev + v) / 2 dt``, and ``v_stop`` the speed from which braking
at ``a`` ends exactly at the stop point (:func:`stop_speed`): it covers the
distance of the continuous profile whatever ``dt`` and never brakes harder than ``a`` (the
former ``d / dt`` term and ``s += v dt`` stopped with one step of up to ``2 a``, and ran
up to ``dt / 2`` ahead of the continuous profile). The body follows the reference
through its pivot joint with a small proportional pull on the along-track and lateral
errors; a delayed or failed AGV brakes at its limit. Standing AGVs hold their cell centre.
Differential-drive AGVs hold their heading, and turn in place behind a reference heading
that turns at ``max_turn_rate``; omnidirectional AGVs never turn. With
``executor.no_slip`` a differential-drive body gets velocity only along its heading and
steers back onto the path line instead of being pulled sideways (:func:`_no_slip`).

Whatever the mode, the commanded velocity finally goes through :func:`limit_command`: at
most ``v_max`` and at most ``a dt`` away from the body's present velocity. The pivot joint
(force headroom 2x) then gives the body exactly that velocity, so neither switching modes
(drive -> hold at the end of an action) nor the corrective pulls can accelerate a body
beyond its limits; only contacts can.
"""

from __future__ import annotations

import math

import numpy as np

from .fleet_state import DRIVE, TURN, FleetState

__all__ = ["ARRIVE_EPS_M", "TURN_EPS_RAD", "ALIGN_EPS_RAD", "LATERAL_GAIN", "ALONG_GAIN",
           "HEADING_GAIN", "limit_command", "steer", "stop_speed", "wrap"]

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
MAX_STEER_RAD = 0.35
"""No-slip drive (``executor.no_slip``): largest heading offset used to steer back onto the
path line."""
STEER_ACCEL_SHARE = 0.6
"""No-slip drive: share of the acceleration limit the centripetal acceleration of a
steering correction may take (the rest is left to speed changes)."""


def wrap(a: np.ndarray | float) -> np.ndarray | float:
    """Angles wrapped to ``[-pi, pi)``."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def stop_speed(d: np.ndarray, a: np.ndarray, dt: float, v_prev: np.ndarray) -> np.ndarray:
    """Highest speed (m/s) at the end of this step from which braking at ``a`` still stops
    within the distance ``d`` (metres) left at its start, for a reference integrated by the
    trapezoidal rule (``s += (v_prev + v) / 2 dt``).

    Solves ``v^2 / (2 a) = d - (v_prev + v) / 2 dt`` (what is left after the step is the
    braking distance from ``v``): ``v = sqrt(a^2 dt^2 / 4 + 2 a d - a dt v_prev) - a dt / 2``.
    From ``v_prev = sqrt(2 a d)`` this gives exactly ``v_prev - a dt``: the reference brakes
    at exactly ``a`` and covers the distance of the continuous profile, whatever ``dt``
    (``v = sqrt(2 a d)`` with ``s += v dt``, as before, ran ahead of it by up to ``dt / 2``,
    and its ``d / dt`` last step braked at up to ``2 a``).

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
    bodies' present velocities ``v_now`` (both as vectors)."""
    speed2 = np.einsum("ij,ij->i", cmd, cmd)
    over = speed2 > vmax * vmax
    if over.any():
        cmd = cmd.copy()
        cmd[over] *= (vmax[over] / np.sqrt(speed2[over]))[:, None]
    dv = cmd - v_now
    step2 = np.einsum("ij,ij->i", dv, dv)
    room = amax * dt
    far = step2 > room * room
    if not far.any():
        return cmd
    out = cmd.copy()
    out[far] = v_now[far] + dv[far] * (room[far] / np.sqrt(step2[far]))[:, None]
    return out


def steer(st: FleetState, pos: np.ndarray, ang: np.ndarray, delayed: np.ndarray,
          v_now: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Control-body velocities ``(N, 2)`` and turn rates ``(N,)`` for bodies at ``pos`` /
    ``ang`` moving at ``v_now`` (N, 2); advances the references (``speed``, ``s_ref``,
    ``heading``, ``ang_ref``)."""
    dt, a = st.dt, st.amax
    along = st.along(pos)
    vel = np.zeros((st.n, 2))
    drive = st.mode == DRIVE
    # The reference runs on its own kinematic state (s_ref, speed): a trapezoid to the
    # stop point, exact in steps of dt; the body follows it through the joint, with a
    # small pull on the along-track and lateral errors.
    d = np.maximum(st.stop_s - st.s_ref, 0.0)
    v = np.minimum.reduce([st.vmax, stop_speed(d, a, dt, st.speed), st.speed + a * dt])
    v = np.where(delayed, np.maximum(st.speed - a * dt, 0.0), v)
    v = np.where(drive, v, 0.0)
    v_prev = st.speed
    st.speed = v
    v_along = v + np.clip(ALONG_GAIN * (st.s_ref - along), -0.2, 0.2)
    # Trapezoidal integration: the reference covers exactly the distance of the continuous
    # profile, whatever dt. The last step of a stop may reach a little past the stop point
    # (less than a dt^2 / 2): the reference stops on it.
    ds = 0.5 * (v_prev + v) * dt
    st.s_ref = np.where(drive, np.minimum(st.s_ref + ds, np.maximum(st.stop_s, st.s_ref)),
                        st.s_ref)
    rel = pos - st.origin
    normal = np.stack([-st.direction[:, 1], st.direction[:, 0]], axis=1)
    lateral = (rel * normal).sum(axis=1)
    v_lat = np.clip(-LATERAL_GAIN * lateral, -0.3, 0.3)
    vel[drive] = (st.direction * v_along[:, None] + normal * v_lat[:, None])[drive]
    # Standing: hold the cell centre.
    hold = ~drive
    err = st.hold_xy - pos
    dist = np.linalg.norm(err, axis=1)
    cap = np.minimum(0.3, np.sqrt(2 * a * dist))
    gain = np.where(dist > 1e-9, np.minimum(2.0 * dist, cap) / np.maximum(dist, 1e-9), 0.0)
    vel[hold] = (err * gain[:, None])[hold]
    # Heading: turn at the limit, else hold.
    target = np.where(drive & ~st.omni,
                      np.arctan2(st.direction[:, 1], st.direction[:, 0]), st.heading)
    st.heading = np.where(drive & ~st.omni, target, st.heading)
    herr = wrap(target - ang)
    turning = st.mode == TURN
    # Turning: a reference heading turns at the limit; the body follows it.
    left = wrap(st.heading - st.ang_ref)
    turn_step = np.sign(left) * np.minimum(st.wmax * dt, np.abs(left))
    w_turn = np.clip(wrap(st.ang_ref + turn_step - ang) / dt, -st.wmax, st.wmax)
    st.ang_ref = np.where(turning, np.where(np.abs(left) <= st.wmax * dt, st.heading,
                                            st.ang_ref + turn_step), ang)
    w_hold = np.clip(HEADING_GAIN * herr, -st.wmax, st.wmax)
    w = np.where(turning, w_turn, w_hold)
    cmd = limit_command(vel, v_now, st.vmax, a, dt)
    if st.no_slip is not None and st.no_slip.any():
        ns = np.flatnonzero(st.no_slip)
        cmd[ns], w[ns] = _no_slip(st, ns, ang[ns], v_now[ns], vel[ns], w[ns],
                                  v_along[ns], lateral[ns], along[ns], drive[ns])
    return cmd, w


def _no_slip(st: FleetState, ns: np.ndarray, ang: np.ndarray, v_now: np.ndarray,
             vel: np.ndarray, w: np.ndarray, v_along: np.ndarray, lateral: np.ndarray,
             along: np.ndarray, drive: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Commands for bodies that cannot move sideways (rows ``ns``): a speed along the
    heading only. Driving, the lateral error is corrected by steering (a heading offset
    ``atan(-LATERAL_GAIN x lateral / speed)``, at most :data:`MAX_STEER_RAD`), with the turn
    rate capped so that the centripetal acceleration ``speed x turn rate`` takes at most
    :data:`STEER_ACCEL_SHARE` of the acceleration limit; the speed then changes by at most
    what is left, so the velocity vector changes by at most ``max_accel dt`` per step.
    The speed is also kept to what still stops the *body* at the stop point (a body that
    steered back onto the line lags its reference and would otherwise catch up and brake
    too late). Standing or turning, the hold pull is projected onto the heading."""
    dt, a, vmax = st.dt, st.amax[ns], st.vmax[ns]
    hx, hy = np.cos(ang), np.sin(ang)
    u_now = v_now[:, 0] * hx + v_now[:, 1] * hy
    ref = np.maximum(np.abs(st.speed[ns]), np.abs(u_now))
    steer_off = np.clip(np.arctan2(-LATERAL_GAIN * lateral, np.maximum(ref, 0.2)),
                        -MAX_STEER_RAD, MAX_STEER_RAD)
    path = np.arctan2(st.direction[ns, 1], st.direction[ns, 0])
    cap = np.minimum(st.wmax[ns], STEER_ACCEL_SHARE * a / np.maximum(np.abs(u_now), 1e-6))
    w_drive = np.clip(HEADING_GAIN * wrap(path + steer_off - ang), -cap, cap)
    w = np.where(drive, w_drive, w)
    stop = stop_speed(st.stop_s[ns] - along, a, dt, np.maximum(u_now, 0.0))
    u_want = np.where(drive, np.minimum(v_along, stop), vel[:, 0] * hx + vel[:, 1] * hy)
    room = np.sqrt(np.maximum(a * a - (u_now * w) ** 2, (0.1 * a) ** 2)) * dt
    u = np.clip(np.clip(u_want, u_now - room, u_now + room), -vmax, vmax)
    # Along the heading the body will have in the middle of the next move.
    mid = ang + 0.5 * w * dt
    return np.column_stack([u * np.cos(mid), u * np.sin(mid)]), w
