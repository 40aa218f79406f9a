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

:class:`IntrusionChecker` answers in closed form with numpy (:func:`box_rect_signed_distance`:
separating-axis overlap for the depth, vertex-to-box distances for the gap), after an
axis-aligned bounding-box broad phase; :func:`intrusions_shapely` is an independent shapely
reference (STRtree ``dwithin`` candidates, signed distance from the Minkowski difference)
for tests.

Why the closed form decides, and python-fcl only proposes: fcl's signed distance runs
libccd's GJK/EPA, which aborts the whole process (``std::logic_error`` from
``validateNearestFeatureOfPolytopeBeingEdge``, SIGABRT) on deep, near-symmetric overlaps
such as an AGV box standing centred on a corridor rectangle: the failed AGV on its own
footprint rectangle did exactly that (issue 13, fault 1). The closed form has no iteration
and no failure mode: any finite input gives a finite answer, degenerate boxes (zero length
or width) and touching or collinear edges included.
:class:`~warerover_phys.faults.intrusion_fcl.FclIntrusionChecker` (``faults.checker:
fcl``) finds the candidate pairs with fcl's boolean box-box collide (never GJK/EPA) and
measures them here; :func:`~warerover_phys.faults.checker.make_checker` builds either.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass

import numpy as np
import shapely

from .corridors import Corridor

__all__ = ["Intrusion", "IntrusionChecker", "agv_boxes", "box_rect_signed_distance",
           "intrusions_shapely"]

_REACH_EPS_M = 1e-6
"""Slack on the broad-phase search distance, so that a zero margin still finds overlaps."""


def box_rect_signed_distance(centre: np.ndarray, angle: np.ndarray, half: np.ndarray,
                             rect: np.ndarray) -> np.ndarray:
    """Signed distance (m) between rotated boxes and axis-aligned rectangles, pairwise.

    Args:
        centre: ``(M, 2)`` box centres, metres.
        angle: ``(M,)`` box headings, radians.
        half: ``(M, 2)`` half length (along the heading) and half width, metres, ``>= 0``.
        rect: ``(M, 4)`` rectangles ``(xmin, ymin, xmax, ymax)``, metres, ``max >= min``.

    Returns ``(M,)``: the Euclidean distance where a pair is apart, minus the penetration
    depth (shortest separating translation) where it overlaps, 0 where it touches. Exact
    for convex polygons: the depth is the smallest overlap over the four edge normals
    (separating-axis theorem), the gap the smallest distance from a vertex of one shape to
    the other (the closest points of two disjoint convex polygons include a vertex).
    Zero-length or zero-width boxes and zero-area rectangles are handled as the segments
    or points they are. Non-finite inputs give NaN, never an exception.

    >>> import numpy as np
    >>> box_rect_signed_distance(np.array([[0.0, 0.0], [3.0, 0.0]]), np.zeros(2),
    ...                          np.array([[0.5, 0.5], [0.5, 0.5]]),
    ...                          np.array([[-1.0, -1.0, 1.0, 1.0], [-1.0, -1.0, 1.0, 1.0]]))
    array([-1.5,  1.5])
    """
    angle = np.asarray(angle, dtype=float).reshape(-1)
    with np.errstate(invalid="ignore"):
        return _signed_distance(centre, np.cos(angle), np.sin(angle), half, rect)


def _signed_distance(centre: np.ndarray, cs: np.ndarray, sn: np.ndarray, half: np.ndarray,
                     rect: np.ndarray) -> np.ndarray:
    """:func:`box_rect_signed_distance` with the headings given by their cosines ``cs`` and
    sines ``sn`` (both checkers take them from one ``cos`` / ``sin`` of every AGV's
    heading, so a pair's figure never depends on which other pairs share the batch)."""
    centre = np.asarray(centre, dtype=float).reshape(-1, 2)
    cs = np.asarray(cs, dtype=float).reshape(-1)
    sn = np.asarray(sn, dtype=float).reshape(-1)
    half = np.abs(np.asarray(half, dtype=float).reshape(-1, 2))
    rect = np.asarray(rect, dtype=float).reshape(-1, 4)
    with np.errstate(invalid="ignore", over="ignore"):
        rc = np.column_stack([(rect[:, 0] + rect[:, 2]) / 2, (rect[:, 1] + rect[:, 3]) / 2])
        rh = np.abs(np.column_stack([rect[:, 2] - rect[:, 0], rect[:, 3] - rect[:, 1]])) / 2
        d = centre - rc
        c, s = np.abs(cs), np.abs(sn)
        # Separation along each axis (positive: a gap on that axis).
        sep_x = np.abs(d[:, 0]) - rh[:, 0] - (half[:, 0] * c + half[:, 1] * s)
        sep_y = np.abs(d[:, 1]) - rh[:, 1] - (half[:, 0] * s + half[:, 1] * c)
        du = np.abs(d[:, 0] * cs + d[:, 1] * sn)
        dv = np.abs(-d[:, 0] * sn + d[:, 1] * cs)
        sep_u = du - half[:, 0] - (rh[:, 0] * c + rh[:, 1] * s)
        sep_v = dv - half[:, 1] - (rh[:, 0] * s + rh[:, 1] * c)
        sep = np.max(np.column_stack([sep_x, sep_y, sep_u, sep_v]), axis=1)
        # Gap: box vertices to the rectangle, rectangle vertices to the box.
        sign = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
        lx = sign[None, :, 0] * half[:, None, 0]
        ly = sign[None, :, 1] * half[:, None, 1]
        bx = d[:, None, 0] + cs[:, None] * lx - sn[:, None] * ly  # relative to rect centre
        by = d[:, None, 1] + sn[:, None] * lx + cs[:, None] * ly
        gx = np.maximum(np.abs(bx) - rh[:, None, 0], 0.0)
        gy = np.maximum(np.abs(by) - rh[:, None, 1], 0.0)
        gap_b = np.hypot(gx, gy).min(axis=1)
        rx = -d[:, None, 0] + sign[None, :, 0] * rh[:, None, 0]  # relative to box centre
        ry = -d[:, None, 1] + sign[None, :, 1] * rh[:, None, 1]
        ru = np.abs(cs[:, None] * rx + sn[:, None] * ry) - half[:, None, 0]
        rv = np.abs(-sn[:, None] * rx + cs[:, None] * ry) - half[:, None, 1]
        gap_r = np.hypot(np.maximum(ru, 0.0), np.maximum(rv, 0.0)).min(axis=1)
        gap = np.minimum(gap_b, gap_r)
        out = np.where(sep > 0, gap, sep)
    bad = ~(np.isfinite(centre).all(axis=1) & np.isfinite(cs) & np.isfinite(sn)
            & np.isfinite(half).all(axis=1) & np.isfinite(rect).all(axis=1))
    out[bad] = np.nan
    return out


@dataclass(frozen=True, slots=True)
class Intrusion:
    """AGV ``agv`` reaches ``depth_m`` metres into corridor ``corridor``'s zone
    (``depth_m = margin_m - signed distance``, see the module docstring)."""

    agv: int
    corridor: int
    depth_m: float


class IntrusionChecker:
    """Finds AGV bodies within the margin of open corridors (``faults.checker: numpy``).

    :meth:`set_corridors` keeps the open corridors' rectangles as arrays; each
    :meth:`check` compares every AGV's axis-aligned bounding box with every rectangle grown
    by its corridor's margin (broad phase, one numpy comparison) and measures the candidate
    pairs in closed form (:func:`box_rect_signed_distance`). Nothing is handed to a
    collision library, so no pose can make it abort.
    :class:`~warerover_phys.faults.intrusion_fcl.FclIntrusionChecker` (``faults.checker:
    fcl``) finds the candidate pairs with python-fcl instead and measures them here, so
    both checkers give the same intrusions, depths to the bit.

    **Boundary rule**: a pair intrudes when its closed-form signed distance is strictly
    below the margin (``sd < margin_m``): with a zero margin, a body touching the person's
    space along an edge or at a corner is not an intrusion, one overlapping it by any amount
    is. Only the closed form decides; a broad phase just has to find every such pair.

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

    name = "numpy"

    def __init__(self, half_sizes: np.ndarray) -> None:
        """``half_sizes``: ``(N, 2)`` half length and half width of each AGV body (m;
        zero is allowed: the body is then the segment or point it is)."""
        hs = np.asarray(half_sizes, dtype=float)
        if hs.ndim != 2 or hs.shape[1] != 2 or not (np.isfinite(hs).all() and (hs >= 0).all()):
            raise ValueError(f"half_sizes must be (N, 2), finite and >= 0, got shape "
                             f"{hs.shape}")
        self.half_sizes = hs
        self.n = len(hs)
        self._corridor_ids: list[int] = []
        self._margins = np.zeros(0)
        self._rects = np.zeros((0, 4))
        self._owner = np.zeros(0, dtype=np.int64)
        """Index into ``_corridor_ids`` of each rectangle."""

    def set_corridors(self, corridors: Sequence[Corridor]) -> None:
        """Replace the open corridors (their rectangles, margins and ids)."""
        rects, owner = [], []
        for k, cor in enumerate(corridors):
            for r in cor.rects:
                rects.append(r)
                owner.append(k)
        rects_a = np.array(rects, dtype=float).reshape(-1, 4)
        margins = np.array([float(cor.margin_m) for cor in corridors])
        if not np.isfinite(rects_a).all() or (rects_a[:, 2:] < rects_a[:, :2]).any():
            raise ValueError(f"corridor rectangles must be finite (xmin, ymin, xmax, ymax) "
                             f"with max >= min, got {rects_a.tolist()}")
        if not (np.isfinite(margins).all() and (margins >= 0).all()):
            raise ValueError(f"corridor margins must be finite and >= 0, got {margins.tolist()}")
        self._rects = rects_a
        self._owner = np.array(owner, dtype=np.int64)
        self._corridor_ids = [cor.id for cor in corridors]
        self._margins = margins

    def check(self, poses: np.ndarray, skip: Collection[int] = ()) -> list[Intrusion]:
        """Intrusions of the AGVs at ``poses`` (``(N, 3)``: x m, y m, heading rad) into the
        open corridors, one per (AGV, corridor) with its largest depth, sorted by
        (agv, corridor). AGVs in ``skip`` (e.g. the failed ones) are left out.

        Raises:
            ValueError: ``poses`` has the wrong shape, or an AGV not in ``skip`` has a
                non-finite pose (named in the message).
        """
        poses = np.asarray(poses, dtype=float)
        if poses.shape != (self.n, 3):
            raise ValueError(f"poses must be ({self.n}, 3), got {poses.shape}")
        if not len(self._rects) or not self.n:
            return []
        live = np.ones(self.n, dtype=bool)
        for a in skip:
            if 0 <= a < self.n:
                live[a] = False
        bad = np.flatnonzero(live & ~np.isfinite(poses).all(axis=1))
        if len(bad):
            raise ValueError(f"AGV pose not finite: AGV {int(bad[0])} at "
                             f"{poses[bad[0]].tolist()} ({len(bad)} AGVs in all)")
        agv, rect = self._candidates(poses, live)
        return self._measure(poses, agv, rect)

    def _candidates(self, poses: np.ndarray, live: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(agv, rectangle)`` index pairs that may intrude (live AGVs only): every pair
        with ``sd < margin`` and maybe more. Here: bounding boxes against rectangles grown by
        margin + eps, one numpy comparison of every AGV with every rectangle."""
        hs = self.half_sizes
        c, s = np.abs(np.cos(poses[:, 2])), np.abs(np.sin(poses[:, 2]))
        ex = hs[:, 0] * c + hs[:, 1] * s
        ey = hs[:, 0] * s + hs[:, 1] * c
        grow = self._margins[self._owner] + _REACH_EPS_M
        r = self._rects
        with np.errstate(invalid="ignore"):  # skipped AGVs may stand nowhere (NaN)
            near = ((poses[:, None, 0] + ex[:, None] > r[None, :, 0] - grow[None])
                    & (poses[:, None, 0] - ex[:, None] < r[None, :, 2] + grow[None])
                    & (poses[:, None, 1] + ey[:, None] > r[None, :, 1] - grow[None])
                    & (poses[:, None, 1] - ey[:, None] < r[None, :, 3] + grow[None])
                    & live[:, None])
        return np.nonzero(near)

    def _measure(self, poses: np.ndarray, agv: np.ndarray, rect: np.ndarray) -> list[Intrusion]:
        """The narrow phase, in closed form, of the candidate pairs ``(agv[i], rect[i])``:
        the intrusions among them, one per (AGV, corridor) with its largest depth."""
        if not len(agv):
            return []
        with np.errstate(invalid="ignore"):  # skipped AGVs may stand nowhere (NaN)
            cs, sn = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        sd = _signed_distance(poses[agv, :2], cs[agv], sn[agv], self.half_sizes[agv],
                              self._rects[rect])
        k = self._owner[rect]
        hit = sd < self._margins[k]
        best: dict[tuple[int, int], float] = {}
        for a, kk, d in zip(agv[hit].tolist(), k[hit].tolist(), sd[hit].tolist(), strict=True):
            if d < best.get((a, kk), np.inf):
                best[(a, kk)] = d
        ids, margins = self._corridor_ids, self._margins
        return sorted((Intrusion(a, ids[kk], float(margins[kk] - d))
                       for (a, kk), d in best.items()), key=lambda i: (i.agv, i.corridor))


# ------------------------------------------------------------------------------ reference


def agv_boxes(poses: np.ndarray, half_sizes: np.ndarray) -> np.ndarray:
    """Shapely polygons of the AGV bodies (``(N,)`` object array), poses ``(N, 3)``:
    x m, y m, heading rad; half sizes ``(N, 2)`` m."""
    return shapely.polygons(_corners(poses, half_sizes))


def intrusions_shapely(poses: np.ndarray, half_sizes: np.ndarray,
                       corridors: Sequence[Corridor],
                       skip: Collection[int] = ()) -> list[Intrusion]:
    """Reference for :meth:`IntrusionChecker.check` with shapely alone (slow, for tests).

    Candidates come from an STRtree of the corridor rectangles queried with the bodies'
    envelopes grown by the largest margin; the signed distance of a body to a rectangle is the
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
    # Candidates: envelopes grown by the largest margin (a ``dwithin`` query finds nothing
    # for a zero-size body: GEOS skips its empty-area envelope).
    grow = float(margins.max()) + _REACH_EPS_M
    env = shapely.bounds(bodies)
    body_idx, rect_idx = shapely.STRtree(rect_geoms).query(shapely.box(
        env[:, 0] - grow, env[:, 1] - grow, env[:, 2] + grow, env[:, 3] + grow))
    if not len(body_idx):
        return []
    rx0, ry0, rx1, ry1 = np.array([r for _, r in rects]).T
    rect_corners = np.stack([np.stack([rx0, ry0], -1), np.stack([rx1, ry0], -1),
                             np.stack([rx1, ry1], -1), np.stack([rx0, ry1], -1)], axis=1)
    diffs = corners[body_idx][:, :, None, :] - rect_corners[rect_idx][:, None, :, :]
    hulls = shapely.convex_hull(shapely.multipoints(diffs.reshape(len(body_idx), 16, 2)))
    origin = shapely.points(0.0, 0.0)
    # Inside: minus the distance to the boundary. Outside (or a hull with no area: a
    # segment or point, when both shapes are degenerate): the distance to the hull.
    sd = np.where((shapely.area(hulls) > 0) & shapely.contains(hulls, origin),
                  -shapely.distance(shapely.boundary(hulls), origin),
                  shapely.distance(hulls, origin))
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
