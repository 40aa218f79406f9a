"""Swept volumes in space-time ``(x, y, t)``: one convex polyhedron per agent, part (body or
carried shelf) and piece of motion between two samples, built for all agents at once with
numpy.

A piece runs from pose ``(x0, y0, h0)`` at ``t0`` to ``(x1, y1, h1)`` at ``t1``. Its volume is
the convex hull of the rectangle at the start pose (in the plane ``t = t0``) and the
rectangle at the end pose (in the plane ``t = t1``): 8 vertices, 12 triangles. What it
contains, and why that is enough:

- **Translation** (``h0 == h1``): the hull is exactly the set swept by the rectangle moving
  on the straight line at constant speed (a sheared prism), so the check is exact for
  piecewise-linear motion.
- **Rotation**: the straight-line interpolation of the rectangle with a linearly turning
  heading is not convex in ``(x, y, t)``. A turn of ``|dh|`` is split into pieces of at most
  ``max_turn_rad``; each piece's rectangles are enlarged by ``delta = R * d**2 / 8`` per side
  (``d`` the piece's turn, ``R`` the rectangle's half-diagonal). Proof: the hull's slice at
  time ``t(s)`` is the Minkowski combination ``(1 - s) P0 + s P1`` of the two end
  rectangles, whose support function in a direction ``psi`` is ``(1 - s) f'(psi - h0) +
  s f'(psi - h1)``; the enlarged rectangle's ``f'`` is at least ``f + delta``, where ``f(phi)
  = a |cos phi| + b |sin phi| = max_k R cos(phi - beta_k)`` is the body's (a max over its
  corners). Each ``R cos`` term has second derivative ``>= -R`` in the heading, so ``f`` is
  at most ``R s (1 - s) d**2 / 2 <= R d**2 / 8`` above its linear interpolation between
  ``h0`` and ``h1``: the body turned to ``h(s)`` lies inside the slice. So the check is
  conservative for rotations, by at most ``delta`` (2.4 mm for a 0.7 m square with the
  default ``pi / 16`` pieces: two such bodies turning in place side by side on 1 m cells,
  10 mm apart at worst, do not meet).
- A **carried shelf** keeps its orientation (sides along the grid) and only translates: its
  volume is exact; a piece where the shelf is picked or dropped uses the larger outline.
- ``tolerance_m`` shrinks every rectangle by half of it per side, so two outlines that touch
  or overlap by at most ``tolerance_m`` do not meet; ``margin_m`` grows them (e.g. by the
  distance a real path can stray from the chord between two recorded samples).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .motion import TimedPlan

__all__ = ["Volumes", "build_volumes", "rotation_bound_m", "BODY", "SHELF"]

BODY, SHELF = 0, 1
"""Values of :attr:`Volumes.part`."""

_CORNERS = np.array([(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)])
"""Rectangle corners in units of the half extents, counter-clockwise (x right, y up)."""


def rotation_bound_m(half_diag_m: float | np.ndarray, turn_rad: float | np.ndarray):
    """How far (m) per side a rectangle of half-diagonal ``half_diag_m`` turning by
    ``turn_rad`` about its centre must be enlarged for the hull of its two end poses to hold
    it (see the module docstring): ``R * d**2 / 8``."""
    d = np.abs(turn_rad)
    return half_diag_m * d * d / 8.0


@dataclass(frozen=True, eq=False)
class Volumes:
    """Flat arrays, one row per volume: ``agent`` id, ``part`` (:data:`BODY` or
    :data:`SHELF`), times ``t0 < t1``, start and end centres and headings, half extents
    ``hl`` (along the heading) and ``hw`` (enlargements and shrinking included)."""

    agent: np.ndarray
    part: np.ndarray
    t0: np.ndarray
    t1: np.ndarray
    x0: np.ndarray
    y0: np.ndarray
    h0: np.ndarray
    x1: np.ndarray
    y1: np.ndarray
    h1: np.ndarray
    hl: np.ndarray
    hw: np.ndarray
    inner: np.ndarray | None = None
    """Radius of a disk round the interpolated centre that every slice of the volume holds
    (the rectangle's smaller half extent before any turn enlargement)."""
    max_rotation_bound_m: float = 0.0
    """The largest rotation enlargement used (0 without turns)."""

    def __len__(self) -> int:
        return len(self.agent)

    @property
    def radius(self) -> np.ndarray:
        """Half-diagonal of each rectangle: every slice of the volume at time ``t`` lies
        within this distance of the centre interpolated at ``t``."""
        return np.hypot(self.hl, self.hw)

    def extents(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Axis-aligned bounds ``xmin, xmax, ymin, ymax`` of every volume."""
        out = []
        for x, y, h in ((self.x0, self.y0, self.h0), (self.x1, self.y1, self.h1)):
            c, s = np.abs(np.cos(h)), np.abs(np.sin(h))
            ex, ey = c * self.hl + s * self.hw, s * self.hl + c * self.hw
            out.append((x - ex, x + ex, y - ey, y + ey))
        (ax0, ax1, ay0, ay1), (bx0, bx1, by0, by1) = out
        return (np.minimum(ax0, bx0), np.maximum(ax1, bx1), np.minimum(ay0, by0),
                np.maximum(ay1, by1))

    def vertices(self, idx: np.ndarray) -> np.ndarray:
        """``(m, 8, 3)`` vertices of the volumes ``idx``: the start rectangle's 4 corners at
        ``t0``, then the end rectangle's at ``t1``, counter-clockwise."""
        idx = np.asarray(idx)
        loc = _CORNERS[None] * np.stack([self.hl[idx], self.hw[idx]], axis=1)[:, None, :]
        out = np.empty((len(idx), 8, 3))
        for k, (x, y, h, t) in enumerate(((self.x0, self.y0, self.h0, self.t0),
                                          (self.x1, self.y1, self.h1, self.t1))):
            c, s = np.cos(h[idx])[:, None], np.sin(h[idx])[:, None]
            out[:, 4 * k:4 * k + 4, 0] = x[idx][:, None] + c * loc[..., 0] - s * loc[..., 1]
            out[:, 4 * k:4 * k + 4, 1] = y[idx][:, None] + s * loc[..., 0] + c * loc[..., 1]
            out[:, 4 * k:4 * k + 4, 2] = t[idx][:, None]
        return out

    def faces(self, idx: np.ndarray, verts: np.ndarray | None = None) -> np.ndarray:
        """``(m, 12, 3)`` triangles (vertex numbers of :meth:`vertices`) of the convex hulls,
        outward-facing.

        The hull of two convex polygons in parallel planes: the two caps, and a side
        triangle per polygon edge, joining it to the other polygon's vertex that is extreme
        in the edge's outward normal direction. Walking the 8 edges in the order of their
        normal angles, each edge advances its own polygon's extreme vertex by one."""
        idx = np.asarray(idx)
        m = len(idx)
        base = np.arange(4)
        ang = np.concatenate([(self.h0[idx][:, None] + (base + 1) * (np.pi / 2)),
                              (self.h1[idx][:, None] + (base + 1) * (np.pi / 2))], axis=1)
        ang = np.mod(ang, 2 * np.pi)
        order = np.argsort(ang, axis=1, kind="stable")  # (m, 8): ties put the start first
        top = order >= 4                                 # edge of the end polygon
        edge = order % 4
        n_top_before = np.cumsum(top, axis=1) - top
        n_bot_before = np.cumsum(~top, axis=1) - ~top
        # extreme vertex before the first edge of each polygon = that edge's start vertex
        first_bot = np.take_along_axis(edge, np.argmax(~top, axis=1)[:, None], axis=1)
        first_top = np.take_along_axis(edge, np.argmax(top, axis=1)[:, None], axis=1)
        other_top = (first_top + n_top_before) % 4 + 4    # for an edge of the start polygon
        other_bot = (first_bot + n_bot_before) % 4        # for an edge of the end polygon
        own = edge + 4 * top
        nxt = (edge + 1) % 4 + 4 * top
        third = np.where(top, other_bot, other_top)
        sides = np.stack([own, nxt, third], axis=2)       # (m, 8, 3)
        caps = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
        tri = np.concatenate([np.broadcast_to(caps, (m, 4, 3)), sides], axis=1)
        v = self.vertices(idx) if verts is None else verts
        centre = v.mean(axis=1)                          # (m, 3), inside the hull
        p = v[np.arange(m)[:, None, None], tri]          # (m, 12, 3 corners, 3 coords)
        normal = np.cross(p[:, :, 1] - p[:, :, 0], p[:, :, 2] - p[:, :, 0])
        out_dir = np.einsum("mfk,mfk->mf", normal, p[:, :, 0] - centre[:, None, :])
        flip = out_dir < 0
        tri = tri.copy()
        tri[flip] = tri[flip][:, [0, 2, 1]]
        return tri

    def mesh(self, i: int):
        """Volume ``i`` as a :class:`trimesh.Trimesh` (imported here: it costs ~0.2 s)."""
        import trimesh

        return trimesh.Trimesh(self.vertices([i])[0], self.faces([i])[0], process=False)

    def hulls(self, idx: np.ndarray, *, method: str = "numpy", check: bool = True):
        """The volumes ``idx`` as one :class:`trimesh.Trimesh` of ``len(idx)`` convex bodies:
        body ``k`` (volume ``idx[k]``) is vertices ``8k .. 8k+7`` and triangles
        ``12k .. 12k+11``, outward-facing.

        ``method``: ``numpy`` (:meth:`vertices` and :meth:`faces`, all at once: ~20 us a
        volume with the checks) or ``trimesh`` (``trimesh.convex.convex_hull`` of each
        volume's 8 corners, i.e. qhull: ~2 ms a volume). ``check``: make sure, with trimesh, that every body is
        watertight with consistent outward winding and convex (every edge locally convex;
        a closed, locally convex surface bounds a convex body); a ValueError if not (a bug:
        the hull of two rectangles in parallel planes is always such a body)."""
        import trimesh

        idx = np.asarray(idx, dtype=np.int64)
        m = len(idx)
        verts = self.vertices(idx)
        if method == "numpy":
            tris = self.faces(idx, verts)
        elif method == "trimesh":
            tris = np.empty((m, 12, 3), dtype=np.int64)
            for k in range(m):
                hull = trimesh.convex.convex_hull(verts[k])
                if hull.vertices.shape != (8, 3) or hull.faces.shape != (12, 3):
                    raise ValueError(f"volume {int(idx[k])}: its hull has "
                                     f"{len(hull.vertices)} vertices and {len(hull.faces)} "
                                     f"faces, not 8 and 12 (degenerate)")
                verts[k] = hull.vertices
                tris[k] = hull.faces
        else:
            raise ValueError(f"method must be 'numpy' or 'trimesh' (got {method!r})")
        offset = (8 * np.arange(m, dtype=np.int64))[:, None, None]
        mesh = trimesh.Trimesh(verts.reshape(-1, 3), (tris + offset).reshape(-1, 3),
                               process=False, validate=False)
        if check and m:
            _check_hulls(mesh, m)
        return mesh


def _check_hulls(mesh, m: int) -> None:
    """Raise a ValueError unless every body of :meth:`Volumes.hulls`'s mesh is a closed,
    consistently wound, outward-facing convex polyhedron (trimesh's edge bookkeeping)."""
    if not (mesh.is_watertight and mesh.is_winding_consistent):
        raise ValueError("swept volumes: a hull is not watertight or not consistently wound")
    # locally convex at every edge (the vertex of one face lies behind its neighbour's
    # plane), relative to the size of each body
    scale = np.ptp(mesh.vertices.reshape(m, 8, 3), axis=1).max(axis=1)
    body = mesh.face_adjacency[:, 0] // 12
    if np.any(mesh.face_adjacency_projections > 1e-9 * np.maximum(scale[body], 1.0)):
        raise ValueError("swept volumes: a hull is not convex")
    # outward: the signed volume of each body (divergence theorem over its triangles)
    verts = mesh.vertices.reshape(m, 8, 3)
    tri = (verts - verts.mean(axis=1, keepdims=True))[
        np.arange(m)[:, None, None], mesh.faces.reshape(m, 12, 3) % 8]  # (m, 12, 3, 3), centred
    signed = np.einsum("mfk,mfk->m", tri[:, :, 0], np.cross(tri[:, :, 1], tri[:, :, 2]))
    if np.any(signed < -1e-9 * np.maximum(scale, 1.0) ** 3):  # (flat ones round to ~0)
        raise ValueError("swept volumes: a hull's faces point inwards")


def _wrap(dh: np.ndarray) -> np.ndarray:
    """Angle differences into (-pi, pi]."""
    out = np.mod(dh + np.pi, 2 * np.pi) - np.pi
    out[out <= -np.pi] = np.pi
    return out


def _agent_segments(m, end_s: float, shelves: bool):
    """Samples of one agent with waits merged and the last pose held to ``end_s``:
    ``t, x, y, h, shelf (K, 2) or None``."""
    t, x, y, h = m.t_s, m.x_m, m.y_m, m.heading_rad
    shelf = m.shelf_m if shelves and m.shelf_m is not None and np.any(m.shelf_m > 0) else None
    if t[-1] < end_s:
        t = np.append(t, end_s)
        x, y, h = np.append(x, x[-1]), np.append(y, y[-1]), np.append(h, h[-1])
        if shelf is not None:
            shelf = np.vstack([shelf, shelf[-1:]])
    if len(t) > 2:  # drop a sample whose pose equals both neighbours' (a wait goes on)
        same = (x[1:] == x[:-1]) & (y[1:] == y[:-1]) & (h[1:] == h[:-1])
        if shelf is not None:
            same &= (shelf[1:] == shelf[:-1]).all(axis=1)
        keep = np.ones(len(t), dtype=bool)
        keep[1:-1] = ~(same[:-1] & same[1:])
        if not keep.all():
            t, x, y, h = t[keep], x[keep], y[keep], h[keep]
            if shelf is not None:
                shelf = shelf[keep]
    return t, x, y, h, shelf


def _segment_columns(plan: TimedPlan, end_s: float, shelves: bool):
    """The straight segments between every agent's samples, as lists of column arrays: the
    bodies' (``agent, t0, t1, x0, y0, h0, x1, y1, dh, L, W``) and the carried shelves'."""
    cols = {k: [] for k in ("agent", "t0", "t1", "x0", "y0", "h0", "x1", "y1", "dh", "L", "W")}
    sh = {k: [] for k in ("agent", "t0", "t1", "x0", "y0", "x1", "y1", "sx", "sy")}
    for aid, m in plan.agents.items():
        t, x, y, h, shelf = _agent_segments(m, end_s, shelves)
        k = len(t) - 1
        if k <= 0:
            continue
        cols["agent"].append(np.full(k, aid, dtype=np.int64))
        cols["t0"].append(t[:-1])
        cols["t1"].append(t[1:])
        cols["x0"].append(x[:-1])
        cols["y0"].append(y[:-1])
        cols["h0"].append(h[:-1])
        cols["x1"].append(x[1:])
        cols["y1"].append(y[1:])
        cols["dh"].append(_wrap(h[1:] - h[:-1]))
        cols["L"].append(np.full(k, m.body_m[0]))
        cols["W"].append(np.full(k, m.body_m[1]))
        if shelf is not None:
            sx = np.maximum(shelf[:-1, 0], shelf[1:, 0])
            sy = np.maximum(shelf[:-1, 1], shelf[1:, 1])
            on = (sx > 0) & (sy > 0)
            if on.any():
                sh["agent"].append(np.full(int(on.sum()), aid, dtype=np.int64))
                for key, arr in (("t0", t[:-1]), ("t1", t[1:]), ("x0", x[:-1]),
                                 ("y0", y[:-1]), ("x1", x[1:]), ("y1", y[1:]), ("sx", sx),
                                 ("sy", sy)):
                    sh[key].append(arr[on])
    return cols, sh


def build_volumes(plan: TimedPlan, *, tolerance_m: float = 1e-3, margin_m: float = 0.0,
                  max_turn_rad: float = math.pi / 16, shelves: bool = True) -> Volumes:
    """Every agent's swept volumes (see the module docstring). Agents hold their last pose
    until the plan's end; when some agent's only sample is at that end, every agent holds
    it 1 us longer (so a plan of one instant is checked too)."""
    if not (0 < max_turn_rad < math.pi):
        raise ValueError(f"max_turn_rad must be in (0, pi) (got {max_turn_rad})")
    end_s = plan.end_s
    if any(m.t_s[0] >= end_s for m in plan.agents.values()):
        # an agent seen only at the plan's last instant: every agent holds its last pose a
        # moment longer, so that instant has volumes too
        end_s += max(1e-6, 1e-9 * abs(end_s))
    cols, sh = _segment_columns(plan, end_s, shelves)
    if not cols["agent"]:
        z = np.zeros(0)
        return Volumes(np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int8),
                       *([z] * 10), inner=z)
    b = {k: np.concatenate(v) for k, v in cols.items()}
    # split turns into pieces of at most max_turn_rad
    pieces = np.maximum(1, np.ceil(np.abs(b["dh"]) / max_turn_rad - 1e-9)).astype(np.int64)
    r = {k: np.repeat(v, pieces) for k, v in b.items()}  # segment values per piece
    n = r.pop("pieces") if "pieces" in r else np.repeat(pieces, pieces)
    j = np.arange(len(n)) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    s0 = j / n
    s1 = (j + 1) / n
    last = j == n - 1
    s1[last] = 1.0

    def lerp(start: str, stop: str, s: np.ndarray) -> np.ndarray:
        return r[start] + (r[stop] - r[start]) * s

    half_l = r["L"] / 2 + margin_m
    half_w = r["W"] / 2 + margin_m
    delta = rotation_bound_m(np.hypot(half_l, half_w), r["dh"] / n)
    shrink = tolerance_m / 2
    body = dict(agent=r["agent"], t0=lerp("t0", "t1", s0), t1=lerp("t0", "t1", s1),
                x0=lerp("x0", "x1", s0), y0=lerp("y0", "y1", s0),
                h0=r["h0"] + r["dh"] * s0, x1=lerp("x0", "x1", s1), y1=lerp("y0", "y1", s1),
                h1=r["h0"] + r["dh"] * s1,
                hl=np.maximum(half_l + delta - shrink, 1e-9),
                hw=np.maximum(half_w + delta - shrink, 1e-9),
                inner=np.maximum(np.minimum(half_l, half_w) - shrink, 0.0))
    # the last piece ends exactly on the next sample
    body["t1"][last] = r["t1"][last]
    body["x1"][last] = r["x1"][last]
    body["y1"][last] = r["y1"][last]
    parts = [body]
    part_ids = [np.full(len(n), BODY, dtype=np.int8)]
    if sh["agent"]:
        s = {k: np.concatenate(v) for k, v in sh.items()}
        zero = np.zeros(len(s["agent"]))
        parts.append(dict(agent=s["agent"], t0=s["t0"], t1=s["t1"], x0=s["x0"], y0=s["y0"],
                          h0=zero, x1=s["x1"], y1=s["y1"], h1=zero,
                          hl=np.maximum(s["sx"] / 2 + margin_m - shrink, 1e-9),
                          hw=np.maximum(s["sy"] / 2 + margin_m - shrink, 1e-9),
                          inner=np.maximum(np.minimum(s["sx"], s["sy"]) / 2 + margin_m - shrink,
                                           0.0)))
        part_ids.append(np.full(len(s["agent"]), SHELF, dtype=np.int8))
    cat = parts[0] if len(parts) == 1 else \
        {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    return Volumes(part=np.concatenate(part_ids),
                   max_rotation_bound_m=float(delta.max()) if len(delta) else 0.0, **cat)
