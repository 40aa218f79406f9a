"""Corridor intrusions: which AGV bodies reach into an open safety corridor, and how deep.

Bodies are rectangles (half length ``hx`` along the heading, half width ``hy``) posed at
``(x, y, heading)`` in world metres / radians. A corridor is a union of axis-aligned
rectangles (:attr:`Corridor.rects <warerover_phys.faults.corridors.Corridor.rects>`) with a
margin ``m = margin_m``.

**Depth.** The signed distance of a body ``B`` to a corridor ``C`` is
``sd(B, C) = min over the rectangles R of C of sd(B, R)``, where ``sd(B, R)`` is the
Euclidean distance between ``B`` and ``R`` when they are apart and minus their penetration
depth (the shortest translation that separates them) when they overlap. For a body outside
the person's space, ``sd`` is exactly its distance to ``Corridor.polygon``. A body intrudes
when ``sd < m``; its depth is ``depth_m = m - sd > 0``:

- ``0 < depth_m <= m``: the body is within the margin but outside the person's space;
- ``depth_m > m``: the body overlaps the person's space.

:class:`IntrusionChecker` answers with python-fcl (two dynamic AABB trees, exact box-box
narrow phase); :func:`intrusions_shapely` is an independent shapely reference (STRtree
``dwithin`` candidates, signed distance from the Minkowski difference) for tests.
"""

from __future__ import annotations

import sys
from collections.abc import Collection, Sequence
from dataclasses import dataclass

import fcl
import numpy as np
import shapely

from .corridors import Corridor

__all__ = ["Intrusion", "IntrusionChecker", "agv_boxes", "intrusions_shapely"]

_REACH_EPS_M = 1e-6
"""Slack on the broad-phase search distance, so that a zero margin still finds overlaps."""


@dataclass(frozen=True, slots=True)
class Intrusion:
    """AGV ``agv`` reaches ``depth_m`` metres into corridor ``corridor``'s zone
    (``depth_m = margin_m - signed distance``, see the module docstring)."""

    agv: int
    corridor: int
    depth_m: float


class IntrusionChecker:
    """Finds AGV bodies within the margin of open corridors, with python-fcl.

    The AGV boxes are created once and kept in a dynamic AABB tree whose transforms are
    refreshed on each :meth:`check` (only for AGVs whose pose changed); the corridor
    rectangles sit in a second tree rebuilt by :meth:`set_corridors`. A broad-phase
    distance query between the trees, cut off at the largest margin, yields candidate
    pairs; the narrow phase is fcl's signed box-box distance. The 2D shapes are boxes in
    the z = 0 plane, thick enough that no xy penetration exceeds their z overlap (the
    bodies are rebuilt thicker when wider corridors need it).

    >>> import numpy as np
    >>> from warerover_phys.config import LayoutSpec
    >>> from warerover_phys.layout import build_layout
    >>> from warerover_phys.faults import plan_corridor
    >>> lay = build_layout(LayoutSpec(grid=["#####", "#..S#", "#...A", "#R..#", "#####"]))
    >>> cor = plan_corridor(lay, 0, agv=0, footprint_cells=[11], width_m=1.0, margin_m=0.3)
    >>> chk = IntrusionChecker(np.array([[0.4, 0.3], [0.4, 0.3], [0.4, 0.3]]))
    >>> chk.set_corridors([cor])
    >>> # AGV 0 failed; AGV 1 is 0.2 m from the walkway (margin 0.3 m), AGV 2 1.2 m away
    >>> poses = np.array([[1.5, 2.5, 0.0], [3.0, 1.5, 0.0], [3.0, 0.5, 0.0]])
    >>> [(i.agv, i.corridor, round(i.depth_m, 9)) for i in chk.check(poses, skip={0})]
    [(1, 0, 0.1)]
    """

    def __init__(self, half_sizes: np.ndarray) -> None:
        """``half_sizes``: ``(N, 2)`` half length and half width of each AGV body (m)."""
        hs = np.asarray(half_sizes, dtype=float)
        if hs.ndim != 2 or hs.shape[1] != 2 or not (hs > 0).all():
            raise ValueError(f"half_sizes must be (N, 2) and positive, got shape {hs.shape}")
        self.half_sizes = hs
        self.n = len(hs)
        self._radius = float(np.hypot(hs[:, 0], hs[:, 1]).max()) if self.n else 0.0
        self._thick = 0.0
        self._build_bodies(2.0 * (self._radius + 1.0))
        self._request = fcl.DistanceRequest(enable_signed_distance=True)
        self._corridor_ids: list[int] = []
        self._margins: list[float] = []
        self._rect_of: dict[int, int] = {}
        self._cor_geoms: list = []
        self._cor_objs: list = []
        self._cor_mgr = fcl.DynamicAABBTreeCollisionManager()
        self._reach = 0.0

    def set_corridors(self, corridors: Sequence[Corridor]) -> None:
        """Replace the open corridors: one ``fcl.Box`` per rectangle of each corridor."""
        # A penetration is at most half a rectangle's short side plus a body's radius; the
        # z overlap of two boxes (their thickness) must stay above it.
        short = max((min(x1 - x0, y1 - y0) for cor in corridors for x0, y0, x1, y1 in cor.rects),
                    default=0.0)
        need = short / 2 + self._radius + 1.0
        if need > self._thick:
            self._build_bodies(2 * need)
        geoms, objs, rect_of = [], [], {}
        for k, cor in enumerate(corridors):
            for x0, y0, x1, y1 in cor.rects:
                g = fcl.Box(x1 - x0, y1 - y0, self._thick)
                tf = fcl.Transform(np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0]))
                geoms.append(g)
                objs.append(fcl.CollisionObject(g, tf))
                rect_of[id(g)] = k
        mgr = fcl.DynamicAABBTreeCollisionManager()
        if objs:
            mgr.registerObjects(objs)
            mgr.setup()
        self._cor_geoms, self._cor_objs, self._cor_mgr = geoms, objs, mgr
        self._rect_of = rect_of
        self._corridor_ids = [cor.id for cor in corridors]
        self._margins = [float(cor.margin_m) for cor in corridors]
        self._reach = max(self._margins, default=0.0) + _REACH_EPS_M

    def check(self, poses: np.ndarray, skip: Collection[int] = ()) -> list[Intrusion]:
        """Intrusions of the AGVs at ``poses`` (``(N, 3)``: x m, y m, heading rad) into the
        open corridors, one per (AGV, corridor) with its largest depth, sorted by
        (agv, corridor). AGVs in ``skip`` (e.g. the failed ones) are left out."""
        poses = np.asarray(poses, dtype=float)
        if poses.shape != (self.n, 3):
            raise ValueError(f"poses must be ({self.n}, 3), got {poses.shape}")
        if not self._cor_objs:
            return []
        self._pose_bodies(poses)
        skip = frozenset(skip)
        agv_of, rect_of, margins = self._agv_of, self._rect_of, self._margins
        request, reach = self._request, self._reach
        best: dict[tuple[int, int], float] = {}
        fmax = sys.float_info.max

        def on_pair(o1, o2, _data):
            # Callbacks get fresh wrapper objects: the geometries say who is who.
            result = fcl.DistanceResult(fmax)
            sd = fcl.distance(o1, o2, request, result)
            a = agv_of.get(id(result.o1))
            k = rect_of.get(id(result.o2)) if a is not None else rect_of.get(id(result.o1))
            if a is None:
                a = agv_of[id(result.o2)]
            if sd < margins[k] and a not in skip:
                key = (a, k)
                if sd < best.get(key, fmax):
                    best[key] = sd
            return False, reach

        self._agv_mgr.distance(self._cor_mgr, None, on_pair)
        ids = self._corridor_ids
        return sorted((Intrusion(a, ids[k], margins[k] - sd) for (a, k), sd in best.items()),
                      key=lambda i: (i.agv, i.corridor))

    def _build_bodies(self, thick: float) -> None:
        """(Re)create the AGV boxes, ``thick`` metres thick in z (unposed)."""
        self._thick = thick
        self._agv_geoms = [fcl.Box(2 * hx, 2 * hy, thick) for hx, hy in self.half_sizes.tolist()]
        self._agv_objs = [fcl.CollisionObject(g) for g in self._agv_geoms]
        self._agv_of = {id(g): i for i, g in enumerate(self._agv_geoms)}
        self._agv_mgr = fcl.DynamicAABBTreeCollisionManager()
        if self._agv_objs:
            self._agv_mgr.registerObjects(self._agv_objs)
            self._agv_mgr.setup()
        self._posed = np.full((self.n, 3), np.nan)

    def _pose_bodies(self, poses: np.ndarray) -> None:
        """Move the fcl boxes of the AGVs whose pose changed, then refit the tree."""
        moved = np.flatnonzero((poses != self._posed).any(axis=1))
        if not len(moved):
            return
        half = poses[moved, 2] / 2
        quat = np.zeros((len(moved), 4))
        quat[:, 0], quat[:, 3] = np.cos(half), np.sin(half)
        trans = np.zeros((len(moved), 3))
        trans[:, :2] = poses[moved, :2]
        objs = self._agv_objs
        for i, q, t in zip(moved.tolist(), quat, trans, strict=True):
            objs[i].setTranslation(t)
            objs[i].setQuatRotation(q)
        self._posed[moved] = poses[moved]
        self._agv_mgr.update()


# ------------------------------------------------------------------------------ reference


def agv_boxes(poses: np.ndarray, half_sizes: np.ndarray) -> np.ndarray:
    """Shapely polygons of the AGV bodies (``(N,)`` object array), poses ``(N, 3)``:
    x m, y m, heading rad; half sizes ``(N, 2)`` m."""
    return shapely.polygons(_corners(poses, half_sizes))


def intrusions_shapely(poses: np.ndarray, half_sizes: np.ndarray,
                       corridors: Sequence[Corridor],
                       skip: Collection[int] = ()) -> list[Intrusion]:
    """Reference for :meth:`IntrusionChecker.check` with shapely alone (slow, for tests).

    Candidates come from an STRtree of the corridor rectangles queried with
    ``dwithin`` at the largest margin; the signed distance of a body to a rectangle is the
    signed distance of the origin to the boundary of their Minkowski difference (convex
    hull of the corner differences): positive outside, negative inside.
    """
    poses = np.asarray(poses, dtype=float)
    rects = [(k, r) for k, cor in enumerate(corridors) for r in cor.rects]
    if not rects or not len(poses):
        return []
    corners = _corners(poses, half_sizes)
    bodies = shapely.polygons(corners)
    rect_geoms = shapely.box(*np.array([r for _, r in rects]).T)
    owner = np.array([k for k, _ in rects])
    margins = np.array([cor.margin_m for cor in corridors])
    body_idx, rect_idx = shapely.STRtree(rect_geoms).query(
        bodies, predicate="dwithin", distance=float(margins.max()))
    if not len(body_idx):
        return []
    rx0, ry0, rx1, ry1 = np.array([r for _, r in rects]).T
    rect_corners = np.stack([np.stack([rx0, ry0], -1), np.stack([rx1, ry0], -1),
                             np.stack([rx1, ry1], -1), np.stack([rx0, ry1], -1)], axis=1)
    diffs = corners[body_idx][:, :, None, :] - rect_corners[rect_idx][:, None, :, :]
    hulls = shapely.convex_hull(shapely.multipoints(diffs.reshape(len(body_idx), 16, 2)))
    origin = shapely.points(0.0, 0.0)
    dist = shapely.distance(shapely.boundary(hulls), origin)
    sd = np.where(shapely.contains(hulls, origin), -dist, dist)
    best: dict[tuple[int, int], float] = {}
    skip = frozenset(skip)
    for a, k, d in zip(body_idx.tolist(), owner[rect_idx].tolist(), sd.tolist(), strict=True):
        if a in skip or not d < margins[k]:
            continue
        if d < best.get((a, k), np.inf):
            best[(a, k)] = d
    return sorted((Intrusion(a, corridors[k].id, float(margins[k] - d))
                   for (a, k), d in best.items()), key=lambda i: (i.agv, i.corridor))


def _corners(poses: np.ndarray, half_sizes: np.ndarray) -> np.ndarray:
    """``(N, 4, 2)`` corners of the bodies, counter-clockwise in body frame."""
    poses = np.asarray(poses, dtype=float)
    hs = np.asarray(half_sizes, dtype=float)
    sign = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    local = sign[None] * hs[:, None, :]
    c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
    x = poses[:, 0:1] + c * local[..., 0] - s * local[..., 1]
    y = poses[:, 1:2] + s * local[..., 0] + c * local[..., 1]
    return np.stack([x, y], axis=-1)
