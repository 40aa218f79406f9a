"""The physics executor's per-step accounting loops compiled with numba: the same figures.

At 1,000 AGVs a physics step's accounting was some twenty numpy calls over the whole fleet
(limit monitor, clearance bound, delay shares, cause labels), a cost set by the number of
calls, not by the few AGVs that move. Here each part is one loop over the fleet (or over the
listed pairs), compiled with ``numba.njit(cache=True)``. Every value is computed with the
same float operations in the same order as the numpy reference it replaces
(:class:`~.measured.ClearanceMonitor`, :class:`~.measured.LimitMonitor`,
:class:`~.causes.CauseRecorder`, :meth:`~.accounting.Accounting.after_step` with
``engine="numpy"``), without fused multiply-adds (numba's default), so results are bit for
bit the same (``tests/executors/test_step_kernels.py``).

``_npmax`` is ``np.maximum`` (a NaN on either side wins). Compile time: the first process
without numba's cache compiles (seconds); later ones load the machine code from
``__pycache__``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["body_rows", "clearance_candidates", "clearance_moved", "gather_bodies", "limit_step", "near_pairs",
           "obstacle_reach", "scatter_commands", "settled", "step_prelude", "step_shares"]

_HOLD, _TURN, _DRIVE = 0, 1, 2  # as .fleet_state
# label codes, as .causes.LABELS
_DWELL, _FAILED, _INJECTED, _DRIVE_L, _TURN_L, _DEPENDENCY, _CONTROL = range(7)


@njit(cache=True, inline="always")
def _npmax(a, b):
    if b > a or b != b:
        return b
    return a


@njit(cache=True)
def step_shares(mode, waiting, injected, pending, failed, has_next, hold_until, last_finish,
                mid, dt, dep_wait, injected_s, turn_time, act_injected, counts, was_waiting,
                wait_run, look_all, look):
    """One physics step's delay shares (``Accounting.after_step``) and cause labels
    (``CauseRecorder.step``) in one pass. Fills ``look`` with the AGVs whose blocker is to
    be looked up (they start to wait, or all waiting ones if ``look_all``) and adds the
    step to ``wait_run`` for the other waiting ones (the caller adds it for the looked-up
    ones after the look-up). Returns (AGVs not holding, AGVs to look up)."""
    n = len(mode)
    active = 0
    nl = 0
    for i in range(n):
        m = mode[i]
        w = waiting[i]
        inj = injected[i]
        if w:
            dep_wait[i] += dt
        if inj and (m != _HOLD or w or pending[i]):
            injected_s[i] += dt
        if m == _TURN:
            turn_time[i] += dt
        if m != _HOLD:
            active += 1
        if (inj or failed[i]) and m == _DRIVE:
            act_injected[i] += dt
        # labels: the highest priority wins
        if hold_until[i] > mid and last_finish[i] <= mid:
            lab = _DWELL
        elif failed[i]:
            lab = _FAILED
        elif inj and (m != _HOLD or has_next[i]):
            lab = _INJECTED
        elif m == _DRIVE:
            lab = _DRIVE_L
        elif m == _TURN:
            lab = _TURN_L
        elif w:
            lab = _DEPENDENCY
        else:
            lab = _CONTROL
        counts[i, lab] += 1
        dep = lab == _DEPENDENCY
        if dep:
            if look_all or not was_waiting[i]:
                look[nl] = i
                nl += 1
            else:
                wait_run[i] += 1
        was_waiting[i] = dep
    return active, nl


@njit(cache=True)
def limit_step(pos, ang, prev_pos, prev_ang, vel, moved, have_vel, dt, peak, bound, over,
               lateral, use_ratio, lim_p, ratio, new_val):
    """One step of ``LimitMonitor.measure`` over the AGVs whose pose changed in this step
    or the one before (all of them while ``have_vel`` is False: no velocity yet). Kinds are
    rows 0 speed (squared), 1 accel (squared), 2 turn_rate. Updates the previous poses,
    velocities, ``moved``, peaks, lateral peaks, ratios and over-limit flags in place; a
    value that has just gone over its bound is written to ``new_val[kind, agv]`` (others
    are left NaN). Returns the number of such new violations."""
    n = len(ang)
    two_pi = 2 * math.pi
    dt2 = dt * dt
    new = 0
    for i in range(n):
        x0, y0 = pos[i, 0], pos[i, 1]
        a1, a0 = ang[i], prev_ang[i]
        mv = x0 != prev_pos[i, 0] or y0 != prev_pos[i, 1] or a1 != a0
        act = mv or moved[i] or not have_vel
        moved[i] = mv
        vx = (x0 - prev_pos[i, 0]) / dt
        vy = (y0 - prev_pos[i, 1]) / dt
        pvx, pvy = vel[i, 0], vel[i, 1]
        vel[i, 0], vel[i, 1] = vx, vy
        prev_pos[i, 0], prev_pos[i, 1], prev_ang[i] = x0, y0, a1
        if not act:
            over[0, i] = over[1, i] = over[2, i] = False
            continue
        wrapped = (a1 - a0 + math.pi) % two_pi - math.pi
        mid = a0 + 0.5 * wrapped
        lat = abs(vy * math.cos(mid) - vx * math.sin(mid))
        lateral[i] = _npmax(lateral[i], lat)
        for k in range(3):
            if k == 0:
                value = vx * vx + vy * vy
            elif k == 1:
                if not have_vel:
                    continue
                dvx, dvy = vx - pvx, vy - pvy
                value = (dvx * dvx + dvy * dvy) / dt2
            else:
                value = abs(wrapped) / dt
            peak[k, i] = _npmax(peak[k, i], value)
            if use_ratio[k]:
                lim = lim_p[k, i]
                ratio[k, i] = _npmax(ratio[k, i], value / lim if lim > 0 else 0.0)
            o = value > bound[k, i]
            if o and not over[k, i]:
                new_val[k, i] = value
                new += 1
            over[k, i] = o
    return new


@njit(cache=True)
def clearance_moved(pos, ang, prev_pos, prev_ang, built_at, moved):
    """``moved[i]``: AGV ``i``'s pose differs from ``prev``; ``prev`` becomes the poses.
    Returns the largest coordinate change since ``built_at`` (NaN if any is NaN)."""
    far = 0.0
    nan = False
    for i in range(len(ang)):
        x, y, a = pos[i, 0], pos[i, 1], ang[i]
        moved[i] = x != prev_pos[i, 0] or y != prev_pos[i, 1] or a != prev_ang[i]
        prev_pos[i, 0], prev_pos[i, 1], prev_ang[i] = x, y, a
        dx = abs(x - built_at[i, 0])
        dy = abs(y - built_at[i, 1])
        if dx != dx or dy != dy:
            nan = True
        far = max(far, dx, dy)
    return math.nan if nan else far


@njit(cache=True)
def clearance_candidates(pos, ang, body_half, shelf_half, pairs, moved, use_moved, best,
                         ext, stamp, step, out):
    """Indices of the listed pairs (only those with an end in ``moved`` if ``use_moved``)
    whose axis-aligned box gap is below ``best`` (``ClearanceMonitor.measure``'s bound);
    ``ext`` caches each AGV's box half extents for the step ``stamp == step``."""
    cnt = 0
    sq = best > 0.0
    best2 = best * best
    for k in range(len(pairs)):
        i, j = pairs[k, 0], pairs[k, 1]
        if use_moved and not (moved[i] or moved[j]):
            continue
        for r in (i, j):
            if stamp[r] != step:
                stamp[r] = step
                c, s = abs(math.cos(ang[r])), abs(math.sin(ang[r]))
                h0, h1 = body_half[r, 0], body_half[r, 1]
                ext[r, 0] = _npmax(h0 * c + h1 * s, shelf_half[r, 0])
                ext[r, 1] = _npmax(h0 * s + h1 * c, shelf_half[r, 1])
        gx = abs(pos[i, 0] - pos[j, 0])
        gx -= ext[i, 0]
        gx -= ext[j, 0]
        gy = abs(pos[i, 1] - pos[j, 1])
        gy -= ext[i, 1]
        gy -= ext[j, 1]
        if sq:
            gx = _npmax(gx, 0.0)
            gy = _npmax(gy, 0.0)
            near = gx * gx + gy * gy < best2
        else:
            near = _npmax(gx, gy) < best
        if near:
            out[cnt] = k
            cnt += 1
    return cnt


@njit(cache=True)
def near_pairs(pos, radius, horizon, cell):
    """(P, 2) pairs ``i < j``, in increasing order, whose circumscribed circles
    (``radius``) come within ``horizon`` (``|c_i - c_j| - (r_i + r_j) < horizon``), from
    a grid of square cells of side ``cell`` (at least the largest reach
    ``2 max(r) + horizon``)."""
    n = len(radius)
    if n < 2:
        return np.zeros((0, 2), dtype=np.intp)
    x0, y0 = math.inf, math.inf
    for i in range(n):
        x0 = min(x0, pos[i, 0])
        y0 = min(y0, pos[i, 1])
    key = np.empty(n, dtype=np.int64)
    cy = np.empty(n, dtype=np.int64)
    w, wy = 0, 0
    for i in range(n):
        key[i] = int(math.floor((pos[i, 0] - x0) / cell))
        cy[i] = int(math.floor((pos[i, 1] - y0) / cell))
        w, wy = max(w, key[i]), max(wy, cy[i])
    w += 3  # a free column and row around the occupied cells: no bounds checks
    nk = (wy + 3) * w
    start = np.zeros(nk + 1, dtype=np.int64)
    for i in range(n):
        key[i] = (cy[i] + 1) * w + key[i] + 1
        start[key[i] + 1] += 1
    for k in range(nk):
        start[k + 1] += start[k]
    fill = start.copy()
    order = np.empty(n, dtype=np.int64)  # AGVs by cell (a counting sort)
    for i in range(n):
        order[fill[key[i]]] = i
        fill[key[i]] += 1
    out_i = np.empty(16 * n + 16, dtype=np.intp)
    out_j = np.empty(16 * n + 16, dtype=np.intp)
    cnt = 0
    buf = np.empty(n, dtype=np.intp)
    for i in range(n):
        nb = 0
        for d in range(9):
            k = key[i] + (d // 3 - 1) * w + (d % 3 - 1)
            for q in range(start[k], start[k + 1]):
                j = order[q]
                if j <= i:
                    continue
                ddx = pos[i, 0] - pos[j, 0]
                ddy = pos[i, 1] - pos[j, 1]
                if math.sqrt(ddx * ddx + ddy * ddy) - (radius[i] + radius[j]) < horizon:
                    q2 = nb  # insertion: the neighbours in increasing order
                    while q2 > 0 and buf[q2 - 1] > j:
                        buf[q2] = buf[q2 - 1]
                        q2 -= 1
                    buf[q2] = j
                    nb += 1
        if cnt + nb > len(out_i):
            out_i = np.concatenate((out_i, np.empty(len(out_i) + nb, dtype=np.intp)))
            out_j = np.concatenate((out_j, np.empty(len(out_j) + nb, dtype=np.intp)))
        for q in range(nb):
            out_i[cnt] = i
            out_j[cnt] = buf[q]
            cnt += 1
    out = np.empty((cnt, 2), dtype=np.intp)
    for q in range(cnt):
        out[q, 0] = out_i[q]
        out[q, 1] = out_j[q]
    return out


@njit(cache=True)
def obstacle_reach(pos, ang, half, shelf_half, margin, skip, sat, cell_m, rows, cols, want):
    """``want[i]``: whether AGV ``i``'s axis-aligned box (its body turned by ``ang[i]``, or
    its carried shelf if wider), grown by ``margin[i]``, overlaps an obstacle cell or leaves
    the map; ``skip[i]`` rows get False. ``sat``: the summed-area table of
    :class:`~.bodies.ObstacleReach` (obstacles padded by a ring of obstacle cells)."""
    for i in range(len(want)):
        if skip[i]:
            want[i] = False
            continue
        c, s = abs(math.cos(ang[i])), abs(math.sin(ang[i]))
        ex = max(half[i, 0] * c + half[i, 1] * s, shelf_half[i, 0]) + margin[i]
        ey = max(half[i, 0] * s + half[i, 1] * c, shelf_half[i, 1]) + margin[i]
        c0 = min(max(math.floor((pos[i, 0] - ex) / cell_m) + 1, 0), cols + 1)
        c1 = min(max(math.floor((pos[i, 0] + ex) / cell_m) + 1, 0), cols + 1) + 1
        r0 = min(max(math.floor((pos[i, 1] - ey) / cell_m) + 1, 0), rows + 1)
        r1 = min(max(math.floor((pos[i, 1] + ey) / cell_m) + 1, 0), rows + 1) + 1
        want[i] = sat[r1, c1] - sat[r0, c1] - sat[r1, c0] + sat[r0, c0] > 0
    return want


@njit(cache=True)
def step_prelude(pos, mode, s_ref, origin, direction, hold_xy, delayed_until, failed,
                 contact_until, t, dt, off_m, injected, delayed, off, ref0):
    """The start of a physics step, per AGV, as :meth:`.physics.PhysicsExecutor.
    _physics_step` computed it with numpy: ``injected`` (an injected delay holds it in
    the step from ``t`` to ``t + dt``, :func:`.delays.held`),
    ``off`` (driving, more than ``off_m`` behind its reference along the run:
    ``s_ref - along``), ``delayed`` (injected, failed, braking after a contact, or off)
    and ``ref0`` (:meth:`.fleet_state.FleetState.ref_xy`)."""
    for i in range(len(mode)):
        inj = delayed_until[i] > t + 0.5 * dt
        injected[i] = inj
        along = (pos[i, 0] - origin[i, 0]) * direction[i, 0] \
            + (pos[i, 1] - origin[i, 1]) * direction[i, 1]
        drive = mode[i] == _DRIVE
        o = drive and s_ref[i] - along > off_m
        off[i] = o
        delayed[i] = inj or failed[i] or contact_until[i] > t or o
        if drive:
            ref0[i, 0] = origin[i, 0] + direction[i, 0] * s_ref[i]
            ref0[i, 1] = origin[i, 1] + direction[i, 1] * s_ref[i]
        else:
            ref0[i, 0] = hold_xy[i, 0]
            ref0[i, 1] = hold_xy[i, 1]


@njit(cache=True)
def settled(mode, parked, hold_xy, pos, vel, w, heading, ang, speed, eps_m, eps_speed,
            eps_rad, out):
    """Standing (``mode`` HOLD), not parked AGVs whose bodies have settled on their hold
    points, as :meth:`.physics.PhysicsExecutor._park_settled` tests it with numpy: within
    ``eps_m`` of the point, slower than ``eps_speed`` (m/s and rad/s), facing ``heading``
    to within ``eps_rad``, reference speed 0. Writes their ids, in order, to ``out``;
    returns how many."""
    k = 0
    two_pi = 2 * math.pi
    for i in range(len(mode)):
        if mode[i] != _HOLD or parked[i]:
            continue
        ex = hold_xy[i, 0] - pos[i, 0]
        ey = hold_xy[i, 1] - pos[i, 1]
        if not ex * ex + ey * ey < eps_m ** 2:
            continue
        if not vel[i, 0] * vel[i, 0] + vel[i, 1] * vel[i, 1] < eps_speed ** 2:
            continue
        if not abs(w[i]) < eps_speed:
            continue
        if not abs((heading[i] - ang[i] + math.pi) % two_pi - math.pi) < eps_rad:
            continue
        if speed[i] != 0.0:
            continue
        out[k] = i
        k += 1
    return k


@njit(cache=True)
def gather_bodies(data, rows, still, pos, ang, vel, w):
    """:class:`~.bodies.BodyIO`'s read: per AGV ``i`` the batch row ``rows[i]`` of ``data``
    ((R, 6): x, y, angle, vx, vy, w per body in the space), or ``still[i]`` where
    ``rows[i] < 0`` (out of the space), into the contiguous ``pos`` (N, 2), ``ang`` (N,),
    ``vel`` (N, 2) and ``w`` (N,)."""
    for i in range(len(rows)):
        src, r = (still, i) if rows[i] < 0 else (data, rows[i])
        pos[i, 0] = src[r, 0]
        pos[i, 1] = src[r, 1]
        ang[i] = src[r, 2]
        vel[i, 0] = src[r, 3]
        vel[i, 1] = src[r, 4]
        w[i] = src[r, 5]


@njit(cache=True)
def scatter_commands(data, body_rows, ctrl_rows, velocity, angular, bodies, out):
    """:class:`~.bodies.BodyIO`'s write: ``out`` (R, 3) gets every body's velocity and
    angular velocity as read (``data`` (R, 6)), then AGV ``i``'s command on its control
    body's row ``ctrl_rows[i]``, and on its body's row ``body_rows[i]`` where
    ``bodies[i]`` (rows < 0: out of the space, left out)."""
    for r in range(out.shape[0]):
        out[r, 0] = data[r, 3]
        out[r, 1] = data[r, 4]
        out[r, 2] = data[r, 5]
    for i in range(len(ctrl_rows)):
        c = ctrl_rows[i]
        if c < 0:
            continue
        out[c, 0] = velocity[i, 0]
        out[c, 1] = velocity[i, 1]
        out[c, 2] = angular[i]
        if bodies[i]:
            b = body_rows[i]
            out[b, 0] = velocity[i, 0]
            out[b, 1] = velocity[i, 1]
            out[b, 2] = angular[i]


@njit(cache=True)
def body_rows(ids, known, known_agv, known_ctrl, rows, ctrl):
    """:class:`~.bodies.BodyIO`'s row map: ``ids`` are the space's body ids in batch order;
    ``known`` (sorted) the ids of every AGV body and control body, ``known_agv`` /
    ``known_ctrl`` whose each is (AGV, and whether a control body). Per AGV ``i`` the
    batch rows of its body and control body go to ``rows[i]`` / ``ctrl[i]``, -1 for
    bodies not in the space (other bodies in it are left out)."""
    rows[:] = -1
    ctrl[:] = -1
    m = len(known)
    for r in range(len(ids)):
        j = np.searchsorted(known, ids[r])
        if j < m and known[j] == ids[r]:
            if known_ctrl[j]:
                ctrl[known_agv[j]] = r
            else:
                rows[known_agv[j]] = r
