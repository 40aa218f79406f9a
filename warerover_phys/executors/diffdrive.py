"""Differential drive without side slip (``executor.no_slip``): the unicycle control law.

A differential-drive AGV moves along its heading only, at speed ``u`` (m/s), and turns at
``omega`` (rad/s); its wheels, ``wheel_base_m`` apart, then turn at ``u +- omega b / 2``.
The executor's references already describe such a motion (:mod:`.control`): a standing
AGV turns in place at its cell centre to face its next move, then drives straight along
the run, its reference point running the time-optimal trapezoid to the stop point (the end
of the released cells). This module makes the body *be* that reference instead of tracking
it:

- **The reference starts from the body** (:func:`sync_references`, at the start of every
  physics step): a driving AGV's reference point is put where its body is along the run,
  and its reference speed within ``a dt / 2`` of the body's speed along it. The step's
  profile then changes the body's velocity by at most ``a dt`` (the body's velocity over
  the last step is the mean of a profile whose acceleration is at most ``a``, and so is the
  next), and the braking profile ahead is computed from where the body really is, so it
  stops at the stop point whatever happened before (no lag to catch up, nothing to
  overshoot: the old law tracked a reference it could fall behind, and a body that caught
  up at the limit could not lose the speed it had gained when its reference braked, which
  put bodies against walls and each other).
- **Commands along the heading only** (:func:`steer_rows`): the speed is the reference's
  mean speed over the step along the run (driving), or the default law's hold pull along
  the heading (standing, turning); the velocity vector is that speed along the step's chord (the heading at the
  middle of the step, ``theta + omega dt / 2``, as the body turns while it moves), so the
  lateral speed measured from the poses is zero up to float error. A body put off its path
  line (a contact, a start off the cell centre) steers back (a heading offset
  ``atan(-STEER_GAIN x lateral / speed)``, at most :data:`MAX_STEER_RAD`), turning no faster
  than its forward speed over its half width, so that no point of the body moves backwards
  (a corner does not swing into what is behind it).
- **The limiter** (:func:`limit_unicycle`) takes the wanted ``(u, omega)`` to the nearest
  pair within every limit: ``|omega| <= max_turn_rate``, ``|u| <= max_speed``, each wheel
  ``|u +- omega b / 2| <= max_wheel_speed``, and the velocity vector at most ``a dt`` from the
  present one (which bounds the turn of a moving body: ``u omega`` is centripetal
  acceleration). Braking comes first, then steering, then speeding up: a turn that would
  leave no room to brake as wanted is cut back; a speed-up that the turn leaves no room for
  is cut back. What is cut back the next step's reference starts from.

The wheel limits (``AgvTypeSpec.wheel_base_m``, ``max_wheel_speed_mps``) are validated to
allow the type's top speed driving straight and its turn rate in place, so they bind only
when a body turns while it moves; the durations of :mod:`warerover_phys.planning.motion`
stay those of this drive.

Every function here is compiled with numba (``cache=True``); :func:`limit_unicycle` and
:func:`steer_rows` are plain scalar loops whose ``.py_func`` is the same code uncompiled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from .fleet_state import DRIVE

if TYPE_CHECKING:
    from .base import AgvBody

__all__ = ["DiffParams", "MAX_STEER_RAD", "STEER_DEADBAND_M", "STEER_GAIN",
           "WheelMonitor", "limit_unicycle", "steer_rows", "sync_references", "sync_rows"]

STEER_DEADBAND_M = 1e-3
"""Lateral offsets from the path line below this (metres) are not steered out: they come
from float error and from the last step of a turn, which ends as the run begins (micrometres),
and a turn at the run's end takes them along."""
STEER_GAIN = 1.5
"""1/s: the heading offset that steers a body back onto its path line is
``atan(-STEER_GAIN x lateral / max(speed, STEER_MIN_SPEED))``."""
STEER_MIN_SPEED = 0.2
"""m/s: the speed below which the steering offset no longer grows."""
MAX_STEER_RAD = 0.35
"""Largest heading offset from the path used to steer back onto it (radians)."""
_BISECT = 40
"""Bisection steps of the limiter's turn-rate search (a factor 2^-40 of the range)."""


@dataclass(frozen=True)
class DiffParams:
    """Per-AGV constants of the no-slip law (arrays indexed by AGV id)."""

    half_width: np.ndarray
    """Half the body's width (metres): the steering turn rate is at most speed over it."""
    half_base: np.ndarray
    """Half the wheel base (metres; 0 without a wheel limit)."""
    wheel_max: np.ndarray
    """Wheel speed limit (m/s; inf without one)."""

    @classmethod
    def of(cls, agvs: tuple[AgvBody, ...]) -> DiffParams:
        half_w = np.array([a.spec.body_m[1] / 2 for a in agvs], dtype=float)
        base = [a.spec.wheel_base_m for a in agvs]
        wheel = [a.spec.max_wheel_speed_mps for a in agvs]
        return cls(half_width=half_w,
                   half_base=np.array([0.0 if b is None else b / 2 for b in base]),
                   wheel_max=np.array([math.inf if w is None else w for w in wheel]))

    @classmethod
    def default(cls, n: int) -> DiffParams:
        """No wheel limits, 0.7 m wide bodies (the default AGV type)."""
        return cls(half_width=np.full(n, 0.35), half_base=np.zeros(n),
                   wheel_max=np.full(n, math.inf))

    @property
    def has_wheels(self) -> bool:
        return bool(np.isfinite(self.wheel_max).any())


# ----------------------------------------------------------------------------- the limiter


@njit(cache=True, inline="always")
def _wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


@njit(cache=True, inline="always")
def _clamp(x, lo, hi):
    return lo if x < lo else (hi if x > hi else x)


@njit(cache=True)
def _speed_range(w, th, vx, vy, vmax, room, wheel_max, half_base, dt):
    """The speeds ``u`` a body at angle ``th`` moving at ``(vx, vy)`` may take this step if it
    turns at ``w``: ``(lo, hi, hx, hy)`` (empty if ``lo > hi``), ``(hx, hy)`` the chord's
    direction. ``|u h - v| <= room``: ``u`` within ``sqrt(room^2 - (v x h)^2)`` of ``v . h``."""
    m = th + 0.5 * w * dt
    hx = math.cos(m)
    hy = math.sin(m)
    along = vx * hx + vy * hy
    across = vx * hy - vy * hx
    disc = room * room - across * across
    if disc < 0.0:
        return 1.0, -1.0, hx, hy
    r = math.sqrt(disc)
    cap = min(vmax, wheel_max - abs(w) * half_base)
    lo = max(along - r, -cap)
    hi = min(along + r, cap)
    return lo, hi, hx, hy


@njit(cache=True)
def limit_unicycle(u_t, w_t, th, vx, vy, vmax, amax, wmax, wheel_max, half_base, dt):
    """The speed and turn rate nearest the wanted ``(u_t, w_t)`` for a body at angle ``th``
    moving at ``(vx, vy)``, within the limits (see the module docstring): returns
    ``(u, w, hx, hy)``, the command being velocity ``u (hx, hy)`` and turn rate ``w``.

    The turn rate is searched on the segment from an *anchor* (the turn that keeps the
    chord along the present velocity, where every speed within ``a dt`` of the present one
    is allowed) to the wanted one, for the turn closest to the wanted one that still lets
    the body slow down to ``u_t`` (bisection); the speed is then ``u_t`` clamped to what
    that turn allows."""
    room = amax * dt
    wcap = wmax
    if half_base > 0.0:
        wcap = min(wcap, wheel_max / half_base)
    w_t = _clamp(w_t, -wcap, wcap)
    lo, hi, hx, hy = _speed_range(w_t, th, vx, vy, vmax, room, wheel_max, half_base, dt)
    if lo <= hi and u_t >= lo:
        return _clamp(u_t, lo, hi), w_t, hx, hy
    sp = math.hypot(vx, vy)
    if sp <= room:
        w_a = 0.0
    else:
        d = _wrap(math.atan2(vy, vx) - th)
        if math.cos(d) < 0.0:  # moving backwards: the chord along -v
            d = _wrap(d + math.pi)
        w_a = _clamp(2.0 * d / dt, -wcap, wcap)
    good = 0.0
    step = 1.0
    for _ in range(_BISECT):
        step *= 0.5
        lam = good + step
        w = w_a + lam * (w_t - w_a)
        lo, hi, hx, hy = _speed_range(w, th, vx, vy, vmax, room, wheel_max, half_base, dt)
        if lo <= hi and u_t >= lo:
            good = lam
    w = w_a + good * (w_t - w_a)
    lo, hi, hx, hy = _speed_range(w, th, vx, vy, vmax, room, wheel_max, half_base, dt)
    if lo > hi:  # nothing is within the limits (a body a contact has thrown): stop turning
        w = w_a
        lo, hi, hx, hy = _speed_range(w, th, vx, vy, vmax, room, wheel_max, half_base, dt)
        if lo > hi:
            along = vx * hx + vy * hy
            return along, w, hx, hy
    return _clamp(u_t, lo, hi), w, hx, hy


# ----------------------------------------------------------------------------- per step


@njit(cache=True)
def sync_rows(dt, no_slip, mode, origin, direction, s_ref, speed, amax, vmax, pos, v_now):
    """:func:`sync_references` for every no-slip row."""
    for i in range(len(mode)):
        if not no_slip[i] or mode[i] != DRIVE:
            continue
        dx = direction[i, 0]
        dy = direction[i, 1]
        s_ref[i] = (pos[i, 0] - origin[i, 0]) * dx + (pos[i, 1] - origin[i, 1]) * dy
        u_now = v_now[i, 0] * dx + v_now[i, 1] * dy
        h = 0.5 * amax[i] * dt
        sp = _clamp(speed[i], u_now - h, u_now + h)
        speed[i] = _clamp(sp, 0.0, vmax[i])


def sync_references(st, pos: np.ndarray, v_now: np.ndarray) -> None:
    """At a physics step's start: the references of driving no-slip AGVs start from their
    bodies (``st``: the :class:`~.fleet_state.FleetState`; ``pos`` / ``v_now``: the bodies'
    positions and velocities, (N, 2)). See the module docstring."""
    if st.no_slip is None:
        return
    sync_rows(float(st.dt), st.no_slip, st.mode, st.origin, st.direction, st.s_ref, st.speed,
              st.amax, st.vmax, np.ascontiguousarray(pos, dtype=np.float64),
              np.ascontiguousarray(v_now, dtype=np.float64))


@njit(cache=True)
def _steer_back(i, dt, origin, direction, heading, pos, ang, speed):
    """Row ``i`` driving: the turn rate that steers it back onto its path line (a heading
    offset ``atan(-STEER_GAIN x lateral / speed)``), or nan within
    :data:`STEER_DEADBAND_M` of the line."""
    dx, dy = direction[i, 0], direction[i, 1]
    lateral = (pos[i, 0] - origin[i, 0]) * -dy + (pos[i, 1] - origin[i, 1]) * dx
    if abs(lateral) <= STEER_DEADBAND_M:
        return math.nan
    off = math.atan2(-STEER_GAIN * lateral, max(abs(speed), STEER_MIN_SPEED))
    return _wrap(heading[i] + _clamp(off, -MAX_STEER_RAD, MAX_STEER_RAD) - ang[i]) / dt


@njit(cache=True)
def steer_rows(dt, no_slip, skip, mode, origin, direction, s_ref, heading, vmax, amax, wmax,
               half_w, half_base, wheel_max, pos, ang, v_now, cmd, w):
    """The no-slip rows' commands (``no_slip``, but not ``skip``), written
    over ``cmd`` (N, 2) and ``w`` (N,), which hold the default law's
    (:func:`.control.steer`: the deadbeat pull onto the reference, the turn onto its
    heading). Driving, the speed wanted is the reference's mean speed over the step along
    the run (the reference started from the body), the turn the default's or the one that
    steers back onto the path; standing or turning, the default's command along the step's
    chord and its turn. Other rows are left as they are."""
    for i in range(len(mode)):
        if not no_slip[i] or skip[i]:  # (the default law left skipped rows zero)
            continue
        th = ang[i]
        w_t = w[i]
        if mode[i] == DRIVE:  # the reference's mean speed over the step, along the run
            along = (pos[i, 0] - origin[i, 0]) * direction[i, 0] + (
                pos[i, 1] - origin[i, 1]) * direction[i, 1]
            u_t = (s_ref[i] - along) / dt
            w_s = _steer_back(i, dt, origin, direction, heading, pos, ang, u_t)
            if w_s == w_s:  # steering: no faster than its speed over its half width
                lim = abs(u_t) / half_w[i]
                w_t = _clamp(w_s, -lim, lim)
        else:
            m = th + 0.5 * w_t * dt
            u_t = cmd[i, 0] * math.cos(m) + cmd[i, 1] * math.sin(m)
        u, wr, hx, hy = limit_unicycle(u_t, w_t, th, v_now[i, 0], v_now[i, 1], vmax[i],
                                       amax[i], wmax[i], wheel_max[i], half_base[i], dt)
        cmd[i, 0] = u * hx
        cmd[i, 1] = u * hy
        w[i] = wr


def steer(st, pos: np.ndarray, ang: np.ndarray, v_now: np.ndarray, cmd: np.ndarray,
          w: np.ndarray, skip: np.ndarray | None = None) -> None:
    """Overwrite the commands of the no-slip rows of ``st`` (a
    :class:`~.fleet_state.FleetState` whose references ran through the step; ``cmd`` /
    ``w``: the default law's commands, :func:`.control.steer`) with the unicycle law's;
    ``skip``: rows whose commands nobody reads (left as the default law left them: zero)."""
    n = st.n
    p = st.diff if st.diff is not None else DiffParams.default(n)
    if skip is None:
        skip = np.zeros(n, dtype=np.bool_)
    f64 = np.float64
    steer_rows(float(st.dt), np.ascontiguousarray(st.no_slip, dtype=np.bool_),
               np.ascontiguousarray(skip, dtype=np.bool_), st.mode, st.origin, st.direction,
               st.s_ref, st.heading, st.vmax, st.amax, st.wmax, p.half_width, p.half_base, p.wheel_max,
               np.ascontiguousarray(pos, dtype=f64), np.ascontiguousarray(ang, dtype=f64),
               np.ascontiguousarray(v_now, dtype=f64), cmd, w)


# ----------------------------------------------------------------------------- wheel speeds


class WheelMonitor:
    """Per-AGV peak wheel speed (m/s), measured from poses at consecutive physics steps: the
    speed along the chord ``v . h(mid)`` and the turn rate ``wrap(d theta) / dt`` give the
    wheels ``|u| + |omega| b / 2``; a violation each time it rises above
    ``max_wheel_speed x (1 + tolerance)`` (as :class:`.measured.LimitMonitor` counts)."""

    def __init__(self, params: DiffParams, rows: np.ndarray, tolerance: float) -> None:
        self.rows = np.flatnonzero(np.asarray(rows, dtype=bool) & np.isfinite(params.wheel_max))
        self.half_base = params.half_base[self.rows]
        self.limit = params.wheel_max[self.rows]
        self.peak = np.zeros(len(params.wheel_max))
        self.violations = 0
        self._bound = self.limit * (1 + tolerance)
        self._over = np.zeros(len(self.rows), dtype=bool)
        self._prev: tuple[np.ndarray, np.ndarray] | None = None
        self._t = -math.inf

    def measure(self, pos: np.ndarray, ang: np.ndarray, t: float) -> list[tuple[str, dict]]:
        """Take the poses at simulated time ``t``; returns ``limit_violation`` events."""
        if len(self.rows) == 0 or t <= self._t:
            return []
        dt = t - self._t
        self._t = t
        r = self.rows
        p, a = pos[r], ang[r]
        prev, self._prev = self._prev, (p.copy(), a.copy())
        if prev is None:
            return []
        d_ang = (a - prev[1] + math.pi) % (2 * math.pi) - math.pi
        mid = prev[1] + 0.5 * d_ang
        v = (p - prev[0]) / dt
        u = v[:, 0] * np.cos(mid) + v[:, 1] * np.sin(mid)
        wheel = np.abs(u) + np.abs(d_ang / dt) * self.half_base
        self.peak[r] = np.maximum(self.peak[r], wheel)
        over = wheel > self._bound
        new = over & ~self._over
        self._over = over
        events = []
        for k in np.flatnonzero(new):
            self.violations += 1
            events.append(("limit_violation", {
                "agv": int(r[k]), "kind": "wheel_speed", "value": round(float(wheel[k]), 4),
                "limit": float(self.limit[k]), "t_s": round(t, 4)}))
        return events

    def ratio(self) -> float:
        """Highest peak / limit over the AGVs with a wheel limit (0.0 without any)."""
        if len(self.rows) == 0:
            return 0.0
        return float((self.peak[self.rows] / self.limit).max())
