"""The control law of :mod:`.control` compiled with numba: the same numbers, bit for bit.

The numpy functions of :mod:`.control` cost one numpy call per operation whatever the
number of rows (about 60 calls for :func:`~.control.run_references`, 40 for
:func:`~.control.steer`), so in the long tail of a run, with a few dozen AGVs moving, the
physics step is bound by numpy's call overhead. Here the same arithmetic runs as one loop
over the rows, compiled with ``numba.njit(cache=True)``:

- :func:`advance_rows`: :func:`~.control.run_references` (``_phases``, ``_time_to`` and
  ``_eval`` inlined per row) for rows ``idx``, taking each row's step from ``left`` and
  returning the rows that stopped at an event, in ascending order (the follower's event
  loop, :meth:`.follow.PlanFollower.advance`);
- :func:`steer_rows`: :func:`~.control.steer` with :func:`~.control.limit_command` for every
  row (the no-slip rows are then done by :func:`.control._no_slip` in numpy, as before).

Every expression is written in the numpy code's order and association, ``np.where``
branches are ``if``/``else``, no ``fastmath`` (no reassociation, no fused multiply-add) and
numpy's error model (float division by zero gives inf/nan, as numpy does). numpy's
``maximum`` / ``minimum`` / ``clip`` return a particular operand on ties (which matters for
the sign of zero): :func:`_mx`, :func:`_mn` and :func:`_clip` copy that
(``tests/executors/test_control_nb.py`` checks every kernel against numpy, bit for bit,
signed zeros included).

Compile time: the first call without numba's cache compiles the kernels (2.8-3.7 s of CPU,
see ``tools/README.md``, issue 12); later processes load them from ``__pycache__`` (~0.6 s
of CPU, after numba's import).
:func:`.control.use_compiled` says when they are used.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .fleet_state import DRIVE, TURN

__all__ = ["advance_rows", "steer_rows", "warm_up"]

# As in .control (imported there from here would be a circle; the tests check they match).
EVENT_EPS_S = 1e-9
HOLD_SPEED = 0.3
_TWO_PI = 2 * math.pi


@njit(cache=True, inline="always")
def _mx(x, y):
    """``np.maximum(x, y)``: ``y`` on a tie (``x`` if it is nan)."""
    return x if (x > y or x != x) else y


@njit(cache=True, inline="always")
def _mn(x, y):
    """``np.minimum(x, y)``: ``y`` on a tie (``x`` if it is nan)."""
    return x if (x < y or x != x) else y


@njit(cache=True, inline="always")
def _clip(x, lo, hi):
    """``np.clip(x, lo, hi)`` where a bound is an array (as at every call here; with two
    scalar bounds numpy returns ``x`` on a tie instead): the bound on a tie (``x`` if it is
    nan)."""
    if x != x:
        return x
    m = x if x > lo else lo
    return m if m < hi else hi


@njit(cache=True, inline="always")
def _sign(x):
    """``np.sign(x)``."""
    if x > 0:
        return 1.0
    if x < 0:
        return -1.0
    if x == 0:
        return 0.0
    return x


@njit(cache=True, inline="always")
def _time_to(v, vc, t1, t2, d1, d2, a, x):
    """``control._time_to`` of one row."""
    x = _mx(x, 0.0)
    x3 = x - d1 - d2
    disc = vc * vc - 2.0 * a * x3
    if x <= d1:
        r1 = math.sqrt(v * v + 2.0 * a * x)
        out = 2.0 * x / (r1 + v) if r1 + v > 0 else 0.0
    elif x <= d1 + d2:
        out = t1 + (x - d1) / vc
    else:
        r3 = math.sqrt(_mx(disc, 0.0))
        out = t1 + t2 + (2.0 * x3 / (vc + r3) if vc + r3 > 0 else 0.0)
    if x > d1 + d2 and disc < -1e-12 * _mx(vc * vc, 1.0):
        return np.inf
    return out


@njit(cache=True, error_model="numpy")
def _row(i, h, braking, mode, heading, ang_ref, wmax, amax, vmax, s_ref, stop_s, cur_end,
         speed):
    """``control.run_references`` for AGV ``i`` over ``h`` seconds: (seconds used, event)."""
    m = mode[i]
    if m == TURN:
        left = heading[i] - ang_ref[i]
        need = abs(left) / wmax[i]
        if need <= h + EVENT_EPS_S:
            ang_ref[i] = heading[i]
            return _mn(need, h), True
        ang_ref[i] = ang_ref[i] + _sign(left) * wmax[i] * h
        return h, False
    if m != DRIVE:
        return h, False
    a, s0, stop, end = amax[i], s_ref[i], stop_s[i], cur_end[i]
    # _phases
    v = _clip(speed[i], 0.0, vmax[i])
    d = _mx(stop - s0, 0.0)
    now = braking or (v * v >= 2.0 * a * d)
    if now:
        vc = v
    else:
        vc = _mx(_mn(math.sqrt(a * d + 0.5 * v * v), vmax[i]), v)
    t1 = (vc - v) / a
    d1 = 0.5 * (vc * vc - v * v) / a
    if now:
        d2 = 0.0
    else:
        d2 = _mx(d - d1 - 0.5 * vc * vc / a, 0.0)
    t2 = d2 / _mx(vc, 1e-300) if vc > 0 else 0.0
    t3 = vc / a
    # the event
    t_end = _time_to(v, vc, t1, t2, d1, d2, a, end - s0)
    t_stop = _time_to(v, vc, t1, t2, d1, d2, a, stop - s0)
    at_stop = end >= stop - 1e-12
    if at_stop:
        t_end = _mn(t_end, t_stop)
    done = t_end <= h + EVENT_EPS_S
    tau = _mn(t_end, h) if done else h
    # _eval
    u1 = _mn(tau, t1)
    u2 = _clip(tau - t1, 0.0, t2)
    u3 = _clip(tau - t1 - t2, 0.0, t3)
    s = v * u1 + 0.5 * a * u1 * u1 + vc * u2 + vc * u3 - 0.5 * a * u3 * u3
    if tau < t1:
        sp = v + a * u1
    elif tau < t1 + t2:
        sp = vc
    else:
        sp = vc - a * u3
    sp = _mx(sp, 0.0)
    s = _mn(s0 + s, _mx(stop, s0))
    if done:
        s = end
        if at_stop:
            sp = 0.0
    s_ref[i] = s
    speed[i] = sp
    return tau, done


@njit(cache=True, error_model="numpy")
def advance_rows(all_rows, idx, left, braking, mode, heading, ang_ref, wmax, amax, vmax, s_ref,
                 stop_s, cur_end, speed, used, events):
    """Advance the references of AGVs ``idx`` (ascending; ``all_rows``: every AGV not
    standing instead) by ``left[i]`` seconds each or up to their next event, as
    :func:`.control.run_references` does (``braking[i]``: AGV ``i``'s reference brakes),
    writing ``ang_ref`` / ``s_ref`` / ``speed`` in place, the seconds used to ``used[i]``
    and subtracting them from ``left[i]``. The AGVs that stopped at an event go to
    ``events`` in ascending order; returns how many."""
    k = 0
    n = len(mode) if all_rows else len(idx)
    for r in range(n):
        i = r if all_rows else idx[r]
        if all_rows and mode[i] != TURN and mode[i] != DRIVE:
            continue
        u, ev = _row(i, left[i], braking[i], mode, heading, ang_ref, wmax, amax, vmax, s_ref,
                     stop_s, cur_end, speed)
        used[i] = u
        left[i] -= u
        if ev:
            events[k] = i
            k += 1
    return k


@njit(cache=True, error_model="numpy")
def _wrap(a):
    return (a + math.pi) % _TWO_PI - math.pi


@njit(cache=True, error_model="numpy")
def steer_rows(dt, mode, origin, direction, s_ref, hold_xy, ang_ref, heading, vmax, amax,
               wmax, pos, ang, v_now, ref0, cmd, w, skip):
    """:func:`.control.steer` without the no-slip rows, and :func:`.control.limit_command`,
    for every row but those ``skip`` ((N,) bool; their commands are zero): the commands to
    ``cmd`` (N, 2) and ``w`` (N,)."""
    for i in range(len(mode)):
        if skip[i]:
            cmd[i, 0] = 0.0
            cmd[i, 1] = 0.0
            w[i] = 0.0
            continue
        m = mode[i]
        a = amax[i]
        if m == DRIVE:
            tx = origin[i, 0] + direction[i, 0] * s_ref[i]
            ty = origin[i, 1] + direction[i, 1] * s_ref[i]
        else:
            tx = hold_xy[i, 0]
            ty = hold_xy[i, 1]
        px, py = pos[i, 0], pos[i, 1]
        rx, ry = ref0[i, 0], ref0[i, 1]
        ex = rx - px
        ey = ry - py
        dist = math.sqrt(ex * ex + ey * ey)
        cap = math.sqrt(2 * a * dist)
        if m != DRIVE:
            cap = _mn(cap, HOLD_SPEED)
        if dist / dt > cap:
            f = cap / dist
            vx = (tx - rx) / dt + ex * f
            vy = (ty - ry) / dt + ey * f
        else:
            vx = (tx - px) / dt
            vy = (ty - py) / dt
        want = ang_ref[i] if m == TURN else heading[i]
        w[i] = _clip(_wrap(want - ang[i]) / dt, -wmax[i], wmax[i])
        # limit_command
        vm = vmax[i]
        speed2 = vx * vx + vy * vy
        lim = vm * (1 + 1e-9)
        if speed2 > lim * lim:
            f = vm / math.sqrt(speed2)
            vx *= f
            vy *= f
        nx, ny = v_now[i, 0], v_now[i, 1]
        dvx = vx - nx
        dvy = vy - ny
        step2 = dvx * dvx + dvy * dvy
        room = a * dt
        lim = room * (1 + 1e-9)
        if step2 > lim * lim:
            f = room / math.sqrt(step2)
            vx = nx + dvx * f
            vy = ny + dvy * f
        cmd[i, 0] = vx
        cmd[i, 1] = vy


def warm_up() -> None:
    """Compile (or load from numba's cache) both kernels for the executor's array types."""
    f = np.zeros(1)
    f2 = np.zeros((1, 2))
    one = np.ones(1)
    mode = np.full(1, DRIVE, dtype=np.int8)
    advance_rows(True, np.zeros(0, dtype=np.int64), one.copy(), np.zeros(1, dtype=bool), mode, f.copy(),
                 f.copy(), one, one, one, f.copy(), one.copy(), one.copy(), f.copy(), f.copy(),
                 np.zeros(1, dtype=np.int64))
    steer_rows(0.05, mode, f2, f2, f, f2, f, f, one, one, one, f2, f, f2, f2, f2.copy(), f.copy(),
               np.zeros(1, dtype=np.bool_))
