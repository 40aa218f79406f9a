"""What the bodies actually did, measured at every physics step from their poses.

- :class:`ClearanceMonitor`: the true minimum clearance between AGVs, edge to edge between
  their rectangles (body, and the carried shelf while one is carried), signed: negative is
  the penetration depth of an overlap. Broad phase first: a neighbour list (Verlet list)
  from a k-d tree over the centres, rebuilt only when some AGV has moved more than half the
  list's skin; then, per step, a bound from axis-aligned boxes over the listed pairs; the
  exact rectangle-rectangle distance (:func:`rect_distance`) only for pairs whose bound is
  below the smallest clearance seen so far.
- :class:`LimitMonitor`: per AGV the peak speed, acceleration and turn rate, from finite
  differences of the poses at consecutive physics steps, and the limit violations: every
  time a measured value goes above the limit in force (a loaded AGV's acceleration limit
  may be lower, ``executor.payload``) by more than :data:`LIMIT_TOLERANCE`; also the peak
  lateral speed (velocity across the heading: how much a body slips sideways).

Both take ``engine="numpy"`` (the code here, the reference) or ``engine="numba"`` (the
same steps compiled, :mod:`.step_kernels`; bit for bit the same figures; the neighbour list
then comes from a cell grid instead of a k-d tree: the same pairs).

Example: two unit squares 0.5 m apart edge to edge, and the same with one turned 45 degrees
(its corner then reaches ``sqrt(0.5) - 0.5`` m further)::

    >>> import numpy as np
    >>> h = np.array([[0.5, 0.5]])
    >>> float(rect_distance(np.zeros((1, 2)), np.zeros(1), h,
    ...                     np.array([[1.5, 0.0]]), np.zeros(1), h)[0])
    0.5
    >>> d = rect_distance(np.zeros((1, 2)), np.array([np.pi / 4]), h,
    ...                   np.array([[1.5, 0.0]]), np.zeros(1), h)
    >>> round(float(d[0]), 6)
    0.292893
"""

from __future__ import annotations

import math

import numpy as np

from .step_kernels import clearance_candidates, clearance_moved, limit_step

__all__ = ["CLEARANCE_HORIZON_M", "ENGINES", "LIMIT_TOLERANCE", "ClearanceMonitor", "LimitMonitor",
           "rect_distance"]

CLEARANCE_HORIZON_M = 1.0
"""Pairs farther apart than this (edge to edge, bounded through the circumscribed circles)
are not listed; a fleet in which no two AGVs ever came this close reports no clearance."""
SKIN_M = 0.4
"""Extra reach of the neighbour list; it is rebuilt once an AGV has moved half of it."""
LIMIT_TOLERANCE = 0.05
"""A measured speed, acceleration or turn rate more than 5% above its limit is a
violation."""

_CORNERS = np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, -1.0], [-1.0, 1.0]])


ENGINES = ("numpy", "numba")
"""How the monitors run a step: ``numpy`` (the reference) or ``numba``
(:mod:`.step_kernels`, the same figures)."""


def _engine(engine: str) -> str:
    if engine not in ENGINES:
        raise ValueError(f"engine {engine!r}: expected one of {', '.join(ENGINES)}")
    return engine


def _rot(angle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.cos(angle), np.sin(angle)


def _corners(c: np.ndarray, angle: np.ndarray, half: np.ndarray) -> np.ndarray:
    """(P, 4, 2) corners of rectangles centred at ``c`` turned by ``angle``."""
    cos, sin = _rot(angle)
    local = _CORNERS[None, :, :] * half[:, None, :]
    x = cos[:, None] * local[:, :, 0] - sin[:, None] * local[:, :, 1]
    y = sin[:, None] * local[:, :, 0] + cos[:, None] * local[:, :, 1]
    return np.stack([x, y], axis=2) + c[:, None, :]


def _points_to_rect(p: np.ndarray, c: np.ndarray, angle: np.ndarray,
                    half: np.ndarray) -> np.ndarray:
    """(P, 4) distances from points ``p`` (P, 4, 2) to filled rectangles (0 inside)."""
    cos, sin = _rot(angle)
    rel = p - c[:, None, :]
    lx = np.abs(cos[:, None] * rel[:, :, 0] + sin[:, None] * rel[:, :, 1]) - half[:, 0:1]
    ly = np.abs(-sin[:, None] * rel[:, :, 0] + cos[:, None] * rel[:, :, 1]) - half[:, 1:2]
    return np.hypot(np.maximum(lx, 0.0), np.maximum(ly, 0.0))


def rect_distance(c1: np.ndarray, a1: np.ndarray, h1: np.ndarray, c2: np.ndarray,
                  a2: np.ndarray, h2: np.ndarray) -> np.ndarray:
    """Signed distance between pairs of rectangles (centres (P, 2), angles (P,), half sizes
    (P, 2)): the gap edge to edge if they are apart, minus the penetration depth (the
    shortest push that separates them) if they overlap.

    Apart: the nearest points of two disjoint convex polygons include a corner of one of
    them, so the gap is the smallest corner-to-rectangle distance either way. Overlap
    (separating-axis test on the four edge normals): the depth is the smallest overlap of
    the projections on those normals, which for convex polygons in the plane is exact."""
    cos1, sin1 = _rot(a1)
    cos2, sin2 = _rot(a2)
    axes = np.stack([np.stack([cos1, sin1], 1), np.stack([-sin1, cos1], 1),
                     np.stack([cos2, sin2], 1), np.stack([-sin2, cos2], 1)], axis=1)  # (P,4,2)
    ax1, ay1 = axes[:, 0:1], axes[:, 1:2]
    ax2, ay2 = axes[:, 2:3], axes[:, 3:4]

    def radius(ax: np.ndarray, ay: np.ndarray, h: np.ndarray) -> np.ndarray:
        return (h[:, 0:1] * np.abs((axes * ax).sum(2)) + h[:, 1:2] * np.abs((axes * ay).sum(2)))

    d = c2 - c1
    centre_gap = np.abs((axes * d[:, None, :]).sum(2))
    overlap = radius(ax1, ay1, h1) + radius(ax2, ay2, h2) - centre_gap      # (P, 4)
    depth = overlap.min(axis=1)
    gap = np.minimum(_points_to_rect(_corners(c1, a1, h1), c2, a2, h2).min(axis=1),
                     _points_to_rect(_corners(c2, a2, h2), c1, a1, h1).min(axis=1))
    return np.where(depth > 0.0, -depth, gap)


def _aabb_half(angle: np.ndarray, half: np.ndarray) -> np.ndarray:
    """(N, 2) half extents of the axis-aligned boxes around turned rectangles."""
    c, s = np.abs(np.cos(angle)), np.abs(np.sin(angle))
    return np.stack([half[:, 0] * c + half[:, 1] * s, half[:, 0] * s + half[:, 1] * c], 1)


class ClearanceMonitor:
    """Smallest signed clearance between any two AGVs over every measured pose.

    Each AGV is its body rectangle and, while it carries one, its shelf rectangle: same
    centre, sides parallel to the grid whatever the AGV's heading (the drive unit turns
    under the shelf, as Kiva-type robots counter-rotate their turntable); the clearance of
    a pair is the smallest over those parts."""

    def __init__(self, body_half: np.ndarray, engine: str = "numpy") -> None:
        self.body_half = np.ascontiguousarray(body_half, dtype=float)
        self.n = len(self.body_half)
        self.engine = _engine(engine)
        self.shelf_half = np.zeros_like(self.body_half)
        self.min_m = math.inf
        """Smallest clearance so far (metres; inf until a pair comes within reach)."""
        self.at_s: float | None = None
        self.agvs: tuple[int, int] | None = None
        self._pairs = np.zeros((0, 2), dtype=np.intp)
        self._ends = np.zeros(0, dtype=np.intp)
        self._built_at: np.ndarray | None = None
        self._radius = np.zeros(self.n)
        self._t = -math.inf
        self._prev: tuple[np.ndarray, np.ndarray] | None = None
        """Poses at the last measured time."""
        if self.engine == "numba":  # the kernels' buffers (see _measure_numba)
            n = self.n
            self._prev_pos, self._prev_ang = np.full((n, 2), np.nan), np.full(n, np.nan)
            self._moved = np.zeros(n, dtype=bool)
            self._ext, self._stamp = np.zeros((n, 2)), np.full(n, -1, dtype=np.int64)
            self._out = np.zeros(0, dtype=np.intp)
            self._step = 0

    def set_shelves(self, shelf_half: np.ndarray) -> None:
        """Half sizes (N, 2) of the shelves carried now (zeros: none)."""
        shelf_half = np.asarray(shelf_half, dtype=float)
        if not np.array_equal(shelf_half, self.shelf_half):
            self.shelf_half = np.ascontiguousarray(shelf_half).copy()
            self._built_at = None  # reaches changed: rebuild the list

    def measure(self, pos: np.ndarray, ang: np.ndarray, t: float) -> None:
        """Take the poses at simulated time ``t`` into account (once per time)."""
        if self.n < 2 or t <= self._t:
            return
        self._t = t
        if self.engine == "numba":
            self._measure_numba(np.ascontiguousarray(pos), np.ascontiguousarray(ang), t)
            return
        prev = self._prev
        self._prev = (pos.copy(), ang.copy())
        pairs, ends = self._pairs, self._ends
        if self._built_at is None or float(
                np.abs(pos - self._built_at).max()) > SKIN_M / 2:
            self._build(pos)
            pairs, ends = self._pairs, self._ends
        elif prev is not None and len(pairs):
            # The list has not changed since the last poses, all of whose pairs were
            # checked then: a pair neither of whose AGVs has moved since (parked AGVs do
            # not move at all) keeps its clearance, which cannot be below the minimum.
            moved = (pos != prev[0]).any(axis=1) | (ang != prev[1])
            keep = np.flatnonzero(moved[pairs[:, 0]] | moved[pairs[:, 1]])
            if len(keep) < len(pairs):
                pairs = pairs[keep]
                ends = np.concatenate([pairs[:, 0], pairs[:, 1]])
        p = len(pairs)
        if p == 0:
            return
        # One gather per array for both ends of every pair (rows 0..p-1: i, p..2p-1: j).
        ext = np.maximum(_aabb_half(ang, self.body_half), self.shelf_half)
        x, e = pos[ends], ext[ends]
        g = np.abs(x[:p] - x[p:])
        g -= e[:p]
        g -= e[p:]
        best = self.min_m
        if best > 0.0:
            np.maximum(g, 0.0, out=g)
            near = np.einsum("ij,ij->i", g, g) < best * best
        else:
            near = g.max(axis=1) < best
        self._exact_min(pos, ang, t, pairs, np.flatnonzero(near))

    def _measure_numba(self, pos: np.ndarray, ang: np.ndarray, t: float) -> None:
        """:meth:`measure` through :mod:`.step_kernels`: the same pairs, bounds and exact
        distances, with one loop over the fleet and one over the listed pairs."""
        had_prev = self._prev is not None
        self._prev = (self._prev_pos, self._prev_ang)
        built = self._built_at
        far = clearance_moved(pos, ang, self._prev_pos, self._prev_ang,
                              pos if built is None else built, self._moved)
        rebuild = built is None or far > SKIN_M / 2
        if rebuild:
            self._build(pos)
        if len(self._pairs) == 0:
            return
        self._step += 1
        cnt = clearance_candidates(pos, ang, self.body_half, self.shelf_half, self._pairs,
                                   self._moved, had_prev and not rebuild, self.min_m,
                                   self._ext, self._stamp, self._step, self._out)
        if cnt:
            self._exact_min(pos, ang, t, self._pairs, self._out[:cnt])

    def _exact_min(self, pos: np.ndarray, ang: np.ndarray, t: float, pairs: np.ndarray,
                   k: np.ndarray) -> None:
        """Exact clearances of ``pairs[k]``; a new minimum is kept with its time."""
        if len(k) == 0:
            return
        i, j = pairs[k, 0], pairs[k, 1]
        d = self._exact(pos, ang, i, j)
        m = int(np.argmin(d))
        if d[m] < self.min_m:
            self.min_m = float(d[m])
            self.at_s = t
            self.agvs = (int(i[m]), int(j[m]))

    def _exact(self, pos: np.ndarray, ang: np.ndarray, i: np.ndarray,
               j: np.ndarray) -> np.ndarray:
        d = rect_distance(pos[i], ang[i], self.body_half[i], pos[j], ang[j], self.body_half[j])
        si = self.shelf_half[i, 0] > 0
        sj = self.shelf_half[j, 0] > 0
        flat = np.zeros(self.n)
        body, shelf = (ang, self.body_half), (flat, self.shelf_half)
        for use, (aa, ha), (ab, hb) in ((si, shelf, body), (sj, body, shelf),
                                        (si & sj, shelf, shelf)):
            if use.any():
                u = np.flatnonzero(use)
                a, b = i[u], j[u]
                d[u] = np.minimum(d[u], rect_distance(pos[a], aa[a], ha[a], pos[b], ab[b],
                                                      hb[b]))
        return d

    def _build(self, pos: np.ndarray) -> None:
        self._built_at = pos.copy()
        self._radius = np.hypot(*np.maximum(self.body_half, self.shelf_half).T)
        # Pairs farther apart than the smallest clearance so far cannot lower it: once one
        # is known the list needs only pairs within it (plus the skin).
        horizon = min(CLEARANCE_HORIZON_M, max(self.min_m, 0.0)) + SKIN_M
        reach = 2 * float(self._radius.max()) + horizon
        if self.engine == "numba":
            from .step_kernels import near_pairs

            self._pairs = near_pairs(pos, self._radius, horizon, reach)
            self._ends = np.zeros(0, dtype=np.intp)  # unused by the kernels
            if len(self._out) < len(self._pairs):
                self._out = np.zeros(len(self._pairs), dtype=np.intp)
            return
        from scipy.spatial import cKDTree

        pairs = cKDTree(pos).query_pairs(reach, output_type="ndarray")
        if len(pairs):
            # Only pairs whose circumscribed circles come within the horizon plus the skin.
            gap = np.linalg.norm(pos[pairs[:, 0]] - pos[pairs[:, 1]], axis=1) - (
                self._radius[pairs[:, 0]] + self._radius[pairs[:, 1]])
            pairs = pairs[gap < horizon]
        self._pairs = pairs.astype(np.intp).reshape(-1, 2)
        self._ends = np.concatenate([self._pairs[:, 0], self._pairs[:, 1]])


class LimitMonitor:
    """Per-AGV peak speed (m/s), acceleration (m/s^2) and turn rate (rad/s), measured from
    poses at consecutive physics steps, and the count of limit violations (each time a
    value rises above ``limit x (1 + LIMIT_TOLERANCE)``)."""

    KINDS = ("speed", "accel", "turn_rate")

    def __init__(self, vmax: np.ndarray, amax: np.ndarray, wmax: np.ndarray,
                 engine: str = "numpy") -> None:
        n = len(vmax)
        self.engine = _engine(engine)
        self.limits = {"speed": np.asarray(vmax, float), "accel": np.asarray(amax, float),
                       "turn_rate": np.asarray(wmax, float)}
        # Per-kind arrays are rows of (3, N) arrays (row = index in KINDS), for the kernel.
        self._peak_a = np.zeros((3, n))
        self._peak = {k: self._peak_a[r] for r, k in enumerate(self.KINDS)}
        """Peaks, speed and acceleration squared."""
        self._bound_a = np.zeros((3, n))
        self._bound: dict[str, np.ndarray] = {}
        for kind in self.KINDS:
            self._set_bound(kind)
        self.violations = 0
        self._over = {k: np.zeros(n, dtype=bool) for k in self.KINDS}
        self._any_over = dict.fromkeys(self.KINDS, False)
        self._ratio_a = np.zeros((3, n))
        self._lim_p = np.zeros((3, n))
        self._use_ratio = np.zeros(3, dtype=bool)
        self._ratio: dict[str, np.ndarray] = {}
        """Peak measured / limit in force, per kind whose limit has changed (squared for
        speed and acceleration); the other kinds' ratios are their peak / fixed limit."""
        self.lateral = np.zeros(n)
        """Per-AGV peak lateral speed (m/s): the body's velocity across its heading."""
        self._pos: np.ndarray | None = None
        self._ang: np.ndarray | None = None
        self._vel: np.ndarray | None = None
        self._moved = np.zeros(n, dtype=bool)
        """AGVs whose pose changed between the last two measured times."""
        self._t = -math.inf
        if self.engine == "numba":  # the kernel's buffers (see _measure_numba)
            self._pos, self._ang = np.zeros((n, 2)), np.zeros(n)
            self._vel_b = np.zeros((n, 2))
            self._over_a = np.zeros((3, n), dtype=bool)
            self._new_val = np.full((3, n), np.nan)
            self._started = self._have_vel = False

    def _set_bound(self, kind: str) -> None:
        r = self.KINDS.index(kind)
        self._bound_a[r] = (self.limits[kind] * (1 + LIMIT_TOLERANCE)) ** (
            1 if kind == "turn_rate" else 2)
        self._bound[kind] = self._bound_a[r]

    def set_limit(self, kind: str, limit: np.ndarray) -> None:
        """A new per-AGV limit of ``kind`` from now on (a payload picked up or put down):
        later values are checked against it, and the peak ratio is taken against the limit
        in force when each value was measured."""
        old = self.limits[kind]
        r = self.KINDS.index(kind)
        p = 1 if kind == "turn_rate" else 2
        if kind not in self._ratio:
            peak = self._peak[kind]
            self._ratio_a[r] = np.divide(peak, old ** p, out=np.zeros_like(peak),
                                         where=old > 0)
            self._ratio[kind] = self._ratio_a[r]
            self._use_ratio[r] = True
        self.limits[kind] = np.asarray(limit, dtype=float).copy()
        self._lim_p[r] = self.limits[kind] ** p
        self._set_bound(kind)

    def measure(self, pos: np.ndarray, ang: np.ndarray, t: float) -> list[tuple[str, dict]]:
        """Take the poses at simulated time ``t`` (once per time); returns
        ``limit_violation`` events for values that just went over their limits."""
        if t <= self._t:
            return []
        dt = t - self._t
        self._t = t
        if self.engine == "numba":
            return self._measure_numba(np.ascontiguousarray(pos), np.ascontiguousarray(ang),
                                       t, dt)
        prev_pos, prev_ang, prev_vel = self._pos, self._ang, self._vel
        self._pos, self._ang = pos.copy(), ang.copy()
        if prev_pos is None:
            return []
        vel = (pos - prev_pos) / dt
        self._vel = vel
        # Only AGVs whose pose changed in this step or the one before: the others measure
        # zero speed, acceleration, turn rate and lateral speed, which lowers no peak and
        # is over no limit (parked AGVs do not move at all).
        moved = (pos != prev_pos).any(axis=1) | (ang != prev_ang)
        act = moved | self._moved if prev_vel is not None else np.ones_like(moved)
        self._moved = moved
        idx = np.flatnonzero(act)
        if len(idx) == 0:
            for kind in self.KINDS:
                if self._any_over[kind]:
                    self._over[kind] = np.zeros_like(moved)
                    self._any_over[kind] = False
            return []
        v, a1, a0 = vel[idx], ang[idx], prev_ang[idx]
        # Squared speed and acceleration: no square roots per step (peaks are kept squared).
        now = {"speed": np.einsum("ij,ij->i", v, v),
               "turn_rate": np.abs((a1 - a0 + math.pi) % (2 * math.pi) - math.pi) / dt}
        if prev_vel is not None:
            dv = v - prev_vel[idx]
            now["accel"] = np.einsum("ij,ij->i", dv, dv) / (dt * dt)
        # Lateral speed: the velocity across the heading at the middle of the step (the
        # direction of the chord a body turning while it drives moves along).
        mid = a0 + 0.5 * ((a1 - a0 + math.pi) % (2 * math.pi) - math.pi)
        lat = np.abs(v[:, 1] * np.cos(mid) - v[:, 0] * np.sin(mid))
        self.lateral[idx] = np.maximum(self.lateral[idx], lat)
        events: list[tuple[str, dict]] = []
        for kind, value in now.items():
            peak = self._peak[kind]
            peak[idx] = np.maximum(peak[idx], value)
            if kind in self._ratio:
                lim = self._lim_p[self.KINDS.index(kind)][idx]
                ratio = self._ratio[kind]
                ratio[idx] = np.maximum(ratio[idx], np.divide(
                    value, lim, out=np.zeros_like(value), where=lim > 0))
            over_now = value > self._bound[kind][idx]
            if not over_now.any() and not self._any_over[kind]:
                continue
            over = np.zeros_like(moved)
            over[idx] = over_now
            new = over_now & ~self._over[kind][idx]
            self._over[kind] = over
            self._any_over[kind] = bool(over_now.any())
            if new.any():
                value = np.sqrt(value) if kind != "turn_rate" else value
                for r in np.flatnonzero(new):
                    i = int(idx[r])
                    self.violations += 1
                    events.append(("limit_violation", {
                        "agv": i, "kind": kind, "value": round(float(value[r]), 4),
                        "limit": float(self.limits[kind][i]), "t_s": round(t, 4)}))
        return events

    def _measure_numba(self, pos: np.ndarray, ang: np.ndarray, t: float,
                       dt: float) -> list[tuple[str, dict]]:
        """:meth:`measure` through :func:`.step_kernels.limit_step`: the same values,
        peaks, ratios and violations, in one loop over the fleet."""
        if not self._started:
            self._pos[:], self._ang[:] = pos, ang
            self._started = True
            return []
        new = limit_step(pos, ang, self._pos, self._ang, self._vel_b, self._moved,
                         self._have_vel, dt, self._peak_a, self._bound_a, self._over_a,
                         self.lateral, self._use_ratio, self._lim_p, self._ratio_a,
                         self._new_val)
        self._have_vel = True
        if not new:
            return []
        events: list[tuple[str, dict]] = []
        for kind in ("speed", "turn_rate", "accel"):  # the reference's order
            row = self._new_val[self.KINDS.index(kind)]
            for i in np.flatnonzero(~np.isnan(row)):
                value = float(row[i]) if kind == "turn_rate" else math.sqrt(row[i])
                row[i] = np.nan
                self.violations += 1
                events.append(("limit_violation", {
                    "agv": int(i), "kind": kind, "value": round(value, 4),
                    "limit": float(self.limits[kind][i]), "t_s": round(t, 4)}))
        return events

    @property
    def peak(self) -> dict[str, np.ndarray]:
        """Per-AGV peaks: ``speed`` (m/s), ``accel`` (m/s^2), ``turn_rate`` (rad/s)."""
        return {k: (v if k == "turn_rate" else np.sqrt(v)) for k, v in self._peak.items()}

    def ratios(self) -> dict[str, float]:
        """Highest peak / limit over the fleet, per kind (0.0 with no AGV)."""
        out = {}
        peak = self.peak
        for kind in self.KINDS:
            if kind in self._ratio:
                r = self._ratio[kind] if kind == "turn_rate" else np.sqrt(self._ratio[kind])
            else:
                lim = self.limits[kind]
                r = np.divide(peak[kind], lim, out=np.zeros_like(lim), where=lim > 0)
            out[kind] = float(r.max()) if len(r) else 0.0
        return out

    def peak_ratio(self, kind: str) -> np.ndarray:
        """Per-AGV highest measured value / the limit in force at the time, of ``kind``."""
        if kind in self._ratio:
            return self._ratio[kind] if kind == "turn_rate" else np.sqrt(self._ratio[kind])
        lim = self.limits[kind]
        return np.divide(self.peak[kind], lim, out=np.zeros_like(lim), where=lim > 0)
