"""Find the swept volumes of two agents that meet: broad phase, two exact filters (one that
rules pairs out, one that rules them in), then python-fcl on trimesh hulls of the rest.

1. **Broad phase** (``broad_phase="grid"``, default): every volume goes into the cells of an
   ``(x, y)`` hash grid its bounding box touches (cell side: the 95th percentile of the
   boxes' sides); within a cell, volumes sorted by start time pair with every later one
   that starts before they end (sort and sweep over time, numpy throughout). Pairs of one
   agent are dropped, duplicates removed, then boxes compared on all three axes.
   ``broad_phase="fcl"`` registers every volume as an ``fcl.Convex`` (a solid) in one
   ``DynamicAABBTreeCollisionManager`` instead (slower: a Python object per volume; kept to
   cross-check the grid and the narrow phase's BVH models).
2. **Bounding circles**: over the two volumes' common time span, each slice lies within its
   half-diagonal of its linearly moving centre; a pair whose centres never come closer than
   the two half-diagonals cannot meet (closed form, vectorised).
3. **Sure hits**: every slice also holds a disk round its centre (the smaller half extent);
   a pair whose centres come closer than the two disks' radii meets for certain.
4. **Narrow phase**: for the rest, the volumes become ``trimesh.Trimesh`` hulls
   (:meth:`Volumes.hulls`: checked watertight, outward and convex) whose vertices and
   triangles feed python-fcl ``BVHModel`` s; ``fcl.collide`` finds hulls whose surfaces
   meet, and a vertex-in-hull test (face planes) the pairs where one hull lies wholly
   inside the other, which a surface model does not see.

Colliding volume pairs of the same two agents whose time spans touch or overlap are merged
into one :class:`SpacetimeConflict`.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from .motion import TimedPlan
from .volumes import Volumes, build_volumes

__all__ = ["SpacetimeConflict", "SpacetimeResult", "validate_spacetime", "candidate_pairs",
           "DEFAULT_TOLERANCE_M", "DEFAULT_MAX_TURN_RAD"]

DEFAULT_TOLERANCE_M = 1e-3
"""Outlines that touch or overlap by at most this much (m) do not conflict."""
DEFAULT_MAX_TURN_RAD = math.pi / 16
"""Largest turn (rad) one volume covers; longer turns are split (see ``volumes``)."""


@dataclass(frozen=True, slots=True)
class SpacetimeConflict:
    """Two agents whose swept volumes meet.

    ``t_start_s`` .. ``t_end_s``: the span of the colliding volume pairs (the contact lies
    within it); ``x_m``, ``y_m``, ``t_s``: the midpoint of the two centres where they come
    closest in it; ``cell``: that point's cell (when the plan knows ``cell_m``);
    ``t_contact_s``: the first contact, found by bisection; ``parts``:
    ``body-body``, ``body-shelf``, ``shelf-body`` or ``shelf-shelf`` (first agent's part
    first); ``pairs``: colliding volume pairs merged into it."""

    agvs: tuple[int, int]
    t_start_s: float
    t_end_s: float
    x_m: float
    y_m: float
    t_s: float
    parts: str
    pairs: int = 1
    cell: tuple[int, int] | None = None
    t_contact_s: float | None = None
    """When the two outlines first overlap by more than the tolerance (to within
    ``contact_resolution_s`` and never early for moves; during a turn the volumes' turn
    enlargement may make it early); None when not refined."""

    def __str__(self) -> str:
        where = f" in cell {self.cell}" if self.cell is not None else ""
        first = f", first contact at t={self.t_contact_s:.3f} s" \
            if self.t_contact_s is not None else ""
        return (f"space-time conflict between AGVs {self.agvs} ({self.parts}) during "
                f"{self.t_start_s:g}-{self.t_end_s:g} s{first}, closest at t={self.t_s:.3f} s "
                f"near ({self.x_m:.3f}, {self.y_m:.3f}) m{where}")


@dataclass
class SpacetimeResult:
    """What :func:`validate_spacetime` found, with counts and wall times (s) per stage."""

    conflicts: list[SpacetimeConflict]
    agents: int
    samples: int
    volumes: int
    broad_pairs: int
    """Pairs of volumes of different agents whose bounding boxes meet."""
    circle_pairs: int
    """Of those, pairs that pass the bounding-circle test."""
    fcl_pairs: int
    """Of those, pairs fcl decided (the others meet for sure: their centres come closer
    than the two disks every slice holds)."""
    colliding_pairs: int
    """Of those, pairs fcl found colliding."""
    truncated: bool
    """True when more conflicts exist than ``max_conflicts``."""
    tolerance_m: float
    margin_m: float
    max_rotation_bound_m: float
    timings_s: dict[str, float] = field(default_factory=dict)
    """Wall seconds: ``build``, ``broad``, ``circle``, ``narrow``, ``merge`` (with the
    first-contact bisection), ``total``."""

    @property
    def ok(self) -> bool:
        return not self.conflicts

    def summary(self) -> dict:
        """JSON-ready figures (conflicts as dicts)."""
        out = {k: v for k, v in asdict(self).items() if k != "conflicts"}
        out["ok"] = self.ok
        out["conflicts"] = [asdict(c) for c in self.conflicts]
        return out


def _bounds(vol: Volumes):
    xmin, xmax, ymin, ymax = vol.extents()
    return xmin, xmax, ymin, ymax, vol.t0, vol.t1


def candidate_pairs(vol: Volumes) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``(a, b)``, ``a < b``, of volumes of different agents whose bounding boxes in
    ``(x, y, t)`` meet (touching in space included), by the hash grid and time sweep.

    Their time spans must overlap: two volumes that share only an instant ``T`` are left out,
    as each agent also has a volume starting at ``T`` (every agent holds its pose to the plan's
    end) and those two overlap in time and hold the same slices at ``T``.

    A volume goes into every grid cell its box touches; a pair is kept only in the cell that
    holds the low corner of the two boxes' intersection (found there exactly once: no
    deduplication pass)."""
    n = len(vol)
    if n < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    xmin, xmax, ymin, ymax, t0, t1 = _bounds(vol)
    side = float(np.percentile(np.maximum(xmax - xmin, ymax - ymin), 95))
    side = max(side, 1e-6)
    ox, oy = float(xmin.min()), float(ymin.min())
    gx0 = np.floor((xmin - ox) / side).astype(np.int64)
    gx1 = np.floor((xmax - ox) / side).astype(np.int64)
    gy0 = np.floor((ymin - oy) / side).astype(np.int64)
    gy1 = np.floor((ymax - oy) / side).astype(np.int64)
    ny = gy1 - gy0 + 1
    count = (gx1 - gx0 + 1) * ny
    owner = np.repeat(np.arange(n), count)
    k = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
    cx = gx0[owner] + k // ny[owner]
    cy = gy0[owner] + k % ny[owner]
    key = cx * (int(gy1.max()) + 1) + cy
    base = float(t0.min())
    span = float(t1.max() - base) * 2.0 + 1.0
    # times offset by their grid cell's number: one sorted array, cells never interleave
    # (float rounding of these keys is ~1e-8 s at most: a pair overlapping in time by less
    # than that may be left out; bodies move far less than the tolerance in it)
    start = (t0[owner] - base) + key * span
    order = np.argsort(start, kind="stable")
    owner, cx, cy, start = owner[order], cx[order], cy[order], start[order]
    stop = (t1[owner] - base) + key[order] * span
    end = np.searchsorted(start, stop, side="left")  # first entry starting when we stop
    pos = np.arange(len(owner))
    m = np.maximum(end - pos - 1, 0)
    left = np.repeat(pos, m)
    right = left + 1 + (np.arange(len(left)) - np.repeat(np.cumsum(m) - m, m))
    a, b = owner[left], owner[right]
    keep = ((vol.agent[a] != vol.agent[b]) & (xmin[a] <= xmax[b]) & (xmin[b] <= xmax[a]) &
            (ymin[a] <= ymax[b]) & (ymin[b] <= ymax[a]) & (t0[a] < t1[b]) & (t0[b] < t1[a]))
    a, b, left = a[keep], b[keep], left[keep]
    home_x = np.floor((np.maximum(xmin[a], xmin[b]) - ox) / side).astype(np.int64)
    home_y = np.floor((np.maximum(ymin[a], ymin[b]) - oy) / side).astype(np.int64)
    home = (home_x == cx[left]) & (home_y == cy[left])
    a, b = a[home], b[home]
    return np.minimum(a, b), np.maximum(a, b)


def _closest(vol: Volumes, a: np.ndarray, b: np.ndarray):
    """Over each pair's common time span: the smallest centre distance, when, and where
    (the midpoint of the centres)."""
    ta = np.maximum(vol.t0[a], vol.t0[b])
    tb = np.minimum(vol.t1[a], vol.t1[b])

    def centre(i: np.ndarray, t: np.ndarray):
        s = (t - vol.t0[i]) / (vol.t1[i] - vol.t0[i])
        return (vol.x0[i] + (vol.x1[i] - vol.x0[i]) * s,
                vol.y0[i] + (vol.y1[i] - vol.y0[i]) * s)

    pax, pay = centre(a, ta)
    pbx, pby = centre(b, ta)
    qax, qay = centre(a, tb)
    qbx, qby = centre(b, tb)
    d0x, d0y = pbx - pax, pby - pay
    ex, ey = (qbx - qax) - d0x, (qby - qay) - d0y
    ee = ex * ex + ey * ey
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(ee > 0, -(d0x * ex + d0y * ey) / ee, 0.0)
    s = np.clip(s, 0.0, 1.0)
    dist = np.hypot(d0x + s * ex, d0y + s * ey)
    t = ta + s * (tb - ta)
    mx = (pax + pbx) / 2 + s * ((qax + qbx) - (pax + pbx)) / 2
    my = (pay + pby) / 2 + s * ((qay + qby) - (pay + pby)) / 2
    return dist, t, mx, my, ta, tb


def _fcl_geoms(vol: Volumes, idx: np.ndarray) -> dict[int, object]:
    """``fcl.Convex`` hulls of the volumes ``idx`` (about 60 us each)."""
    import fcl

    out = {}
    if not len(idx):
        return out
    verts = vol.vertices(idx)
    tris = vol.faces(idx, verts)
    flat = np.concatenate([np.full((len(idx), 12, 1), 3, dtype=np.int64), tris],
                          axis=2).reshape(len(idx), -1)
    for k, i in enumerate(idx.tolist()):
        out[i] = fcl.Convex(verts[k], 12, flat[k])
    return out


class _Hulls:
    """Volumes as trimesh hulls (:meth:`Volumes.hulls`, checked watertight and convex) fed
    to python-fcl, one collision object per volume, made at once for all ``idx``.

    ``narrow="bvh"``: a ``BVHModel`` of the hull's triangles (an OBBRSS tree; ~45 us a
    volume to build). A BVH model is a surface: fcl finds two colliding when their
    triangles intersect, not when one hull lies wholly inside the other. Two convex bodies
    whose surfaces do not meet are disjoint or one holds the other, so :meth:`meet` also
    tests one vertex of each against the other's face planes (with trimesh's outward face
    normals). ``narrow="convex"``: an ``fcl.Convex`` of the same vertices and faces (a
    solid, GJK; ~25 us a volume)."""

    def __init__(self, vol: Volumes, idx: np.ndarray, method: str = "numpy",
                 narrow: str = "bvh") -> None:
        import fcl

        self.row = {i: k for k, i in enumerate(idx.tolist())}
        mesh = vol.hulls(idx, method=method)
        m = len(idx)
        self.verts = np.ascontiguousarray(mesh.vertices, dtype=np.float64).reshape(m, 8, 3)
        faces = (np.asarray(mesh.faces).reshape(m, 12, 3)
                 - (8 * np.arange(m))[:, None, None]).astype(np.int32)
        self.normals = np.asarray(mesh.face_normals).reshape(m, 12, 3)
        self.anchor = self.verts[np.arange(m)[:, None], faces[:, :, 0]]  # a point per face
        self.solid = narrow == "convex"
        objs = self.objs = []
        verts = self.verts
        if self.solid:
            flat = np.concatenate([np.full((m, 12, 1), 3, dtype=np.int64), faces],
                                  axis=2).reshape(m, -1)
            for k in range(m):
                objs.append(fcl.CollisionObject(fcl.Convex(verts[k], 12, flat[k])))
            return
        bvh, obj = fcl.BVHModel, fcl.CollisionObject
        for k in range(m):
            model = bvh()
            model.beginModel(8, 12)
            model.addSubModel(verts[k], faces[k])
            model.endModel()
            objs.append(obj(model))

    def inside(self, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Does the first vertex of hull ``p[k]`` lie inside hull ``q[k]`` (rows)?"""
        pts = self.verts[p, 0]
        side = np.einsum("mfk,mfk->mf", self.normals[q], pts[:, None, :] - self.anchor[q])
        return (side <= 0).all(axis=1)

    def meet(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """For volume pairs ``(a[k], b[k])``: a boolean mask of those whose hulls meet."""
        import fcl

        row = self.row
        p = np.array([row[i] for i in a.tolist()], dtype=np.int64)
        q = np.array([row[j] for j in b.tolist()], dtype=np.int64)
        hit = np.zeros(len(p), dtype=bool) if self.solid else \
            self.inside(p, q) | self.inside(q, p)
        req, res, collide = fcl.CollisionRequest(), fcl.CollisionResult, fcl.collide
        objs = self.objs
        for k in np.flatnonzero(~hit).tolist():
            hit[k] = collide(objs[p[k]], objs[q[k]], req, res()) > 0
        return hit


def _narrow(vol: Volumes, a: np.ndarray, b: np.ndarray, method: str = "numpy",
            narrow: str = "bvh") -> np.ndarray:
    """fcl on every pair (see :class:`_Hulls`); a boolean mask of the colliding ones."""
    if not len(a):
        return np.zeros(0, dtype=bool)
    return _Hulls(vol, np.unique(np.concatenate([a, b])), method, narrow).meet(a, b)


def _fcl_broad(vol: Volumes) -> tuple[np.ndarray, np.ndarray]:
    """Colliding pairs of different agents found by an fcl DynamicAABBTreeCollisionManager
    over all volumes (the manager runs the narrow phase itself). Contacts name the
    geometries that were registered, so a geometry's ``id`` gives its volume."""
    import fcl

    geoms = _fcl_geoms(vol, np.arange(len(vol)))
    index = {id(g): i for i, g in geoms.items()}
    manager = fcl.DynamicAABBTreeCollisionManager()
    manager.registerObjects([fcl.CollisionObject(g) for g in geoms.values()])
    manager.setup()
    data = fcl.CollisionData(request=fcl.CollisionRequest(num_max_contacts=2 ** 31 - 1,
                                                          enable_contact=True))
    manager.collide(data, fcl.defaultCollisionCallback)
    pairs = set()
    for c in data.result.contacts:
        i, j = index[id(c.o1)], index[id(c.o2)]
        if vol.agent[i] != vol.agent[j]:
            pairs.add((min(i, j), max(i, j)))
    if not pairs:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    arr = np.array(sorted(pairs), dtype=np.int64)
    return arr[:, 0], arr[:, 1]


def _merge(vol: Volumes, a: np.ndarray, b: np.ndarray, cell_m: float | None,
           max_conflicts: int, resolution_s: float | None,
           ) -> tuple[list[SpacetimeConflict], bool]:
    """Colliding volume pairs -> conflicts per agent pair and touching time span (numpy: a
    run of pairs of the same agents whose spans touch or overlap is one conflict)."""
    if not len(a):
        return [], False
    swap = vol.agent[a] > vol.agent[b]
    a, b = np.where(swap, b, a), np.where(swap, a, b)
    dist, t, mx, my, ta, tb = _closest(vol, a, b)
    pa, pb = vol.agent[a], vol.agent[b]
    order = np.lexsort((ta, pb, pa))
    a, b, pa, pb = a[order], b[order], pa[order], pb[order]
    dist, t, mx, my, ta, tb = (v[order] for v in (dist, t, mx, my, ta, tb))
    new_pair = np.empty(len(a), dtype=bool)
    new_pair[0] = True
    new_pair[1:] = (pa[1:] != pa[:-1]) | (pb[1:] != pb[:-1])
    # latest end so far within each agent pair (pairs offset so the running max restarts)
    pair_no = np.cumsum(new_pair) - 1
    lo, hi = float(ta.min()), float(tb.max())
    offset = pair_no * ((hi - lo) * 2.0 + 1.0)
    reach = np.maximum.accumulate((tb - lo) + offset) - offset + lo
    start = new_pair.copy()
    start[1:] |= ta[1:] > reach[:-1] + 1e-9
    first = np.flatnonzero(start)
    count = np.diff(np.append(first, len(a)))
    group = np.repeat(np.arange(len(first)), count)
    t_hi = np.maximum.reduceat(tb, first)
    # the closest approach in each group
    best = np.lexsort((dist, group))
    best = best[np.searchsorted(group[best], np.arange(len(first)))]
    part = np.array(["body", "shelf"])  # by BODY, SHELF
    out = []
    for g, k in enumerate(best.tolist()):
        cell = None
        if cell_m:
            cell = (int(math.floor(my[k] / cell_m)), int(math.floor(mx[k] / cell_m)))
        out.append(SpacetimeConflict(
            (int(pa[k]), int(pb[k])), float(ta[first[g]]), float(t_hi[g]), float(mx[k]),
            float(my[k]), float(t[k]), f"{part[vol.part[a[k]]]}-{part[vol.part[b[k]]]}",
            int(count[g]), cell))
    keep = sorted(range(len(out)), key=lambda g: (out[g].t_start_s, out[g].agvs))
    truncated = len(keep) > max_conflicts
    keep = keep[:max_conflicts]
    if resolution_s is not None:
        for g in keep:
            lo, hi = first[g], first[g] + count[g]
            out[g] = replace(out[g], t_contact_s=_first_contact(
                vol, a[lo:hi], b[lo:hi], ta[lo:hi], tb[lo:hi], resolution_s))
    return [out[g] for g in keep], truncated


def _restricted(vol: Volumes, idx: list[int], spans: list[tuple[float, float]]) -> Volumes:
    """The volumes ``idx`` cut to the time spans ``spans`` (poses interpolated linearly;
    the same half extents: a turn's enlargement covers any part of it)."""
    i = np.asarray(idx)
    lo = np.array([s[0] for s in spans])
    hi = np.array([s[1] for s in spans])
    dur = vol.t1[i] - vol.t0[i]

    def at(t: np.ndarray, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
        return start[i] + (stop[i] - start[i]) * ((t - vol.t0[i]) / dur)

    return Volumes(vol.agent[i], vol.part[i], lo, hi, at(lo, vol.x0, vol.x1),
                   at(lo, vol.y0, vol.y1), at(lo, vol.h0, vol.h1), at(hi, vol.x0, vol.x1),
                   at(hi, vol.y0, vol.y1), at(hi, vol.h0, vol.h1), vol.hl[i], vol.hw[i],
                   inner=vol.inner[i])


def _meet(vol: Volumes, i: int, j: int, lo: float, hi: float) -> bool:
    """Do volumes i and j, cut to ``[lo, hi]``, meet? (A probe of the first-contact
    bisection: fcl.Convex solids of the numpy hulls, the same answer as the narrow phase's
    BVH models without a trimesh mesh per probe, which costs milliseconds.)"""
    import fcl

    sub = _restricted(vol, [i, j], [(lo, hi), (lo, hi)])
    g = _fcl_geoms(sub, np.arange(2))
    return fcl.collide(fcl.CollisionObject(g[0]), fcl.CollisionObject(g[1]),
                       fcl.CollisionRequest(), fcl.CollisionResult()) > 0


def _first_contact(vol: Volumes, a: np.ndarray, b: np.ndarray, ta: np.ndarray,
                   tb: np.ndarray, resolution_s: float) -> float:
    """The earliest time any of these colliding volume pairs meets: per pair, bisection on
    the prefix ``[ta, t]`` of its common span (meeting is monotone in ``t``), pairs taken in
    order of ``ta`` until one starts after the best found."""
    best = math.inf
    for i, j, lo0, hi0 in zip(a.tolist(), b.tolist(), ta.tolist(), tb.tolist(), strict=True):
        if lo0 >= best:
            break
        lo, hi = lo0, min(hi0, best)
        if hi < hi0 and not _meet(vol, i, j, lo0, hi):
            continue
        while hi - lo > resolution_s:
            mid = (lo + hi) / 2
            if _meet(vol, i, j, lo0, mid):
                hi = mid
            else:
                lo = mid
        best = min(best, hi)
    return best


def validate_spacetime(plan: TimedPlan, *, tolerance_m: float = DEFAULT_TOLERANCE_M,
                       margin_m: float = 0.0, max_turn_rad: float = DEFAULT_MAX_TURN_RAD,
                       shelves: bool = True, broad_phase: str = "grid",
                       max_conflicts: int = 100,
                       contact_resolution_s: float | None = 1e-3,
                       hulls: str = "numpy", narrow: str = "bvh") -> SpacetimeResult:
    """Check that no two agents' swept volumes in ``(x, y, t)`` meet.

    ``tolerance_m``: outlines may touch or overlap by this much (m); ``margin_m``: grow every
    outline by this much (m); ``max_turn_rad``: turn covered by one volume (longer turns are
    split; the check is exact for translations and conservative for turns, see
    :mod:`warerover_phys.spacetime.volumes`); ``shelves``: include carried shelves;
    ``broad_phase``: ``grid`` (numpy hash grid + time sweep) or ``fcl`` (fcl's dynamic AABB
    tree over all volumes; slower); ``max_conflicts``: conflicts reported at most (the
    earliest); ``contact_resolution_s``: find each reported conflict's first contact to
    within this (s) by bisection (None: don't); ``hulls``: how the narrow phase's hulls
    are built (:meth:`Volumes.hulls`: ``numpy``, or ``trimesh``'s ``convex_hull`` per volume,
    the same hulls ~90x slower); ``narrow``: the fcl objects of the narrow phase,
    ``bvh`` (``BVHModel`` s plus a containment test) or ``convex`` (``fcl.Convex`` solids;
    faster to build, the same answers).

    >>> from warerover_phys.spacetime import from_schedule
    >>> swap = from_schedule({0: [((0, 0), 0.0), ((0, 1), 1.0)],
    ...                       1: [((0, 1), 0.0), ((0, 0), 1.0)]})
    >>> res = validate_spacetime(swap)
    >>> res.ok, res.conflicts[0].agvs, res.conflicts[0].t_s
    (False, (0, 1), 0.5)
    """
    if not (math.isfinite(tolerance_m) and tolerance_m >= 0):
        raise ValueError(f"tolerance_m must be >= 0 (got {tolerance_m})")
    if not (math.isfinite(margin_m) and margin_m >= 0):
        raise ValueError(f"margin_m must be >= 0 (got {margin_m})")
    if contact_resolution_s is not None and not contact_resolution_s > 0:
        raise ValueError(f"contact_resolution_s must be > 0 (got {contact_resolution_s})")
    if broad_phase not in ("grid", "fcl"):
        raise ValueError(f"broad_phase must be 'grid' or 'fcl' (got {broad_phase!r})")
    if hulls not in ("numpy", "trimesh"):
        raise ValueError(f"hulls must be 'numpy' or 'trimesh' (got {hulls!r})")
    if narrow not in ("bvh", "convex"):
        raise ValueError(f"narrow must be 'bvh' or 'convex' (got {narrow!r})")
    clock = time.perf_counter
    t_start = clock()
    vol = build_volumes(plan, tolerance_m=tolerance_m, margin_m=margin_m,
                        max_turn_rad=max_turn_rad, shelves=shelves)
    t_built = clock()
    if broad_phase == "grid":
        a, b = candidate_pairs(vol)
        broad = len(a)
        t_broad = clock()
        sure = np.zeros(0, dtype=bool)
        if len(a):
            dist = _closest(vol, a, b)[0]
            near = dist < vol.radius[a] + vol.radius[b]
            a, b, dist = a[near], b[near], dist[near]
            sure = dist < vol.inner[a] + vol.inner[b]
        circle = len(a)
        t_circle = clock()
        fcl_pairs = int((~sure).sum())
        hit = sure.copy()
        hit[~sure] = _narrow(vol, a[~sure], b[~sure], hulls, narrow)
        a, b = a[hit], b[hit]
    else:
        a, b = _fcl_broad(vol)
        broad = circle = fcl_pairs = len(a)
        t_broad = t_circle = clock()
    t_narrow = clock()
    conflicts, truncated = _merge(vol, a, b, plan.cell_m, max_conflicts,
                                  contact_resolution_s)
    t_end = clock()
    return SpacetimeResult(
        conflicts=conflicts, agents=len(plan.agents), samples=plan.samples, volumes=len(vol),
        broad_pairs=broad, circle_pairs=circle, fcl_pairs=fcl_pairs, colliding_pairs=len(a), truncated=truncated,
        tolerance_m=tolerance_m, margin_m=margin_m,
        max_rotation_bound_m=vol.max_rotation_bound_m,
        timings_s={"build": t_built - t_start, "broad": t_broad - t_built,
                   "circle": t_circle - t_broad, "narrow": t_narrow - t_circle,
                   "merge": t_end - t_narrow, "total": t_end - t_start})
