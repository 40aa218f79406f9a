"""The physics executor's control law: control-body velocities from the AGVs' references.

Vectorised over the fleet, once per physics step. Along the current straight run a
reference point runs an exact trapezoid to the stop point,
``v = min(v_max * scale, sqrt(2 a d), v_prev + a dt, d / dt)``, and the body follows it
through its pivot joint with a small proportional pull on the along-track and lateral
errors; a delayed or failed AGV brakes at its limit. Standing AGVs hold their cell centre.
Differential-drive AGVs hold their heading, and turn in place behind a reference heading
that turns at ``max_turn_rate``; omnidirectional AGVs never turn.
"""

from __future__ import annotations

import math

import numpy as np

from .fleet_state import DRIVE, TURN, FleetState

__all__ = ["ARRIVE_EPS_M", "TURN_EPS_RAD", "ALIGN_EPS_RAD", "LATERAL_GAIN", "ALONG_GAIN",
           "HEADING_GAIN", "steer", "wrap"]

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


def wrap(a: np.ndarray | float) -> np.ndarray | float:
    """Angles wrapped to ``[-pi, pi)``."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def steer(st: FleetState, pos: np.ndarray, ang: np.ndarray,
          delayed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Control-body velocities ``(N, 2)`` and turn rates ``(N,)`` for bodies at ``pos`` /
    ``ang``; advances the references (``speed``, ``s_ref``, ``heading``, ``ang_ref``)."""
    dt, a = st.dt, st.amax
    along = st.along(pos)
    vel = np.zeros((st.n, 2))
    drive = st.mode == DRIVE
    # The reference runs on its own kinematic state (s_ref, speed): an exact trapezoid
    # to the stop point; the body follows it through the joint, with a small pull on the
    # along-track and lateral errors.
    d = np.maximum(st.stop_s - st.s_ref, 0.0)
    v = np.minimum.reduce([st.vmax, np.sqrt(2 * a * d), st.speed + a * dt, d / dt])
    v = np.where(delayed, np.maximum(st.speed - a * dt, 0.0), v)
    v = np.where(drive, v, 0.0)
    st.speed = v
    v_along = v + np.clip(ALONG_GAIN * (st.s_ref - along), -0.2, 0.2)
    st.s_ref = np.where(drive, st.s_ref + v * dt, st.s_ref)
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
    return vel, w
