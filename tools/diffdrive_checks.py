"""Independent checks of an executed trajectory (``trajectories.npz``), sharing no code with
the executor: body overlaps between AGVs and with walls (shapely), and the peaks of speed,
acceleration, turn rate, wheel speed and lateral speed recomputed from the poses alone.

Used by ``tools/diffdrive_table.py`` (issue 37). Only what ``trajectories.npz`` documents is
read: ``t``, ``x``, ``y``, ``heading`` (T, N), ``loaded``, ``body_m``, ``grid``, ``cell_m``,
the ``limit_*`` arrays and, for the wheels, ``wheel_base_m`` / ``limit_wheel_speed_mps``.

- **AGV-AGV**: each body is its rectangle (length along the heading); pairs whose centres
  are within the sum of their circumradii plus :data:`NEAR_M` are measured with
  ``shapely.distance``; an overlap is an intersection of positive area (> 1e-9 m^2).
- **Static**: the grid's obstacle cells (``grid == 1``) and the map's border (everything
  outside ``[0, cols x cell_m] x [0, rows x cell_m]``) as boxes in an STRtree; an overlap
  is a body intersecting one with positive area; the clearance is the nearest box.
- **Peaks** (finite differences of consecutive samples, so only meaningful when every
  physics step is recorded: ``executor.trajectory_hz = 1 / dt_s``): speed ``|dp| / dt``,
  acceleration ``|dv| / dt`` (against the loaded limit where the middle sample is loaded),
  turn rate ``|wrap(d heading)| / dt``, lateral speed ``|v x h(mid)|`` with ``mid`` the
  heading halfway through the step, wheel speed ``|v . h(mid)| + |turn rate| b / 2``.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from scipy.spatial import cKDTree

NEAR_M = 0.5
"""Pairs whose circumscribed circles are farther apart than this are not measured."""
AREA_EPS = 1e-9
"""An intersection must be larger than this (m^2) to count as an overlap."""

__all__ = ["NEAR_M", "AREA_EPS", "body_polygons", "agv_overlaps", "static_overlaps", "peaks",
           "check_npz"]


def body_polygons(x: np.ndarray, y: np.ndarray, heading: np.ndarray,
                  body: np.ndarray) -> np.ndarray:
    """Body rectangles of samples ``x``, ``y``, ``heading`` (T, N) as shapely polygons
    (T, N); ``body`` (N, 2): length and width."""
    hl, hw = body[:, 0] / 2, body[:, 1] / 2
    c, s = np.cos(heading), np.sin(heading)
    corners = [np.stack([x + sl * hl * c - sw * hw * s, y + sl * hl * s + sw * hw * c], -1)
               for sl, sw in ((1, 1), (-1, 1), (-1, -1), (1, -1))]
    rings = np.stack(corners, axis=-2)  # (T, N, 4, 2)
    t, n = x.shape
    return shapely.polygons(rings.reshape(t * n, 4, 2)).reshape(t, n)


def agv_overlaps(polys: np.ndarray, x: np.ndarray, y: np.ndarray,
                 body: np.ndarray) -> dict:
    """Samples with two overlapping bodies, the overlapping pairs (a set), the smallest
    clearance between bodies and where it was (sample index, AGV pair)."""
    radius = np.hypot(body[:, 0], body[:, 1]) / 2
    reach = 2 * float(radius.max()) + NEAR_M
    rows, ai, bi = [], [], []
    for k in range(x.shape[0]):
        pairs = cKDTree(np.column_stack([x[k], y[k]])).query_pairs(reach, output_type="ndarray")
        if len(pairs):
            rows.append(np.full(len(pairs), k))
            ai.append(pairs[:, 0])
            bi.append(pairs[:, 1])
    out = {"agv_overlap_samples": 0, "pairs": set(), "min_agv_clearance_m": None,
           "min_agv_clearance_at": None}
    if not rows:
        return out
    k, a, b = np.concatenate(rows), np.concatenate(ai), np.concatenate(bi)
    ga, gb = polys[k, a], polys[k, b]
    dist = shapely.distance(ga, gb)
    hit = dist <= 0.0
    if hit.any():
        area = shapely.area(shapely.intersection(ga[hit], gb[hit]))
        real = np.zeros_like(hit)
        real[np.flatnonzero(hit)[area > AREA_EPS]] = True
        out["agv_overlap_samples"] = int(len(np.unique(k[real])))
        out["pairs"] = {(int(p), int(q)) for p, q in zip(a[real], b[real], strict=True)}
    m = int(np.argmin(dist))
    out["min_agv_clearance_m"] = float(dist[m])
    out["min_agv_clearance_at"] = [int(k[m]), int(a[m]), int(b[m])]
    return out


def wall_boxes(grid: np.ndarray, cell_m: float) -> np.ndarray:
    """The obstacle cells (one box per horizontal run) and four boxes around the map."""
    rows, cols = grid.shape
    boxes = []
    for r in range(rows):
        c = 0
        while c < cols:
            if grid[r, c] != 1:
                c += 1
                continue
            c0 = c
            while c < cols and grid[r, c] == 1:
                c += 1
            boxes.append(shapely.box(c0 * cell_m, r * cell_m, c * cell_m, (r + 1) * cell_m))
    w, h, f = cols * cell_m, rows * cell_m, 10.0
    boxes += [shapely.box(-f, -f, w + f, 0.0), shapely.box(-f, h, w + f, h + f),
              shapely.box(-f, -f, 0.0, h + f), shapely.box(w, -f, w + f, h + f)]
    return np.array(boxes, dtype=object)


def static_overlaps(polys: np.ndarray, grid: np.ndarray, cell_m: float) -> dict:
    """Samples with a body overlapping a wall, the AGVs that did, and the smallest
    body-to-wall clearance."""
    walls = wall_boxes(grid, cell_m)
    tree = shapely.STRtree(walls)
    flat = polys.ravel()
    idx, dist = tree.query_nearest(flat, return_distance=True, all_matches=False)
    out = {"static_overlap_samples": 0, "static_overlap_agvs": [],
           "min_static_clearance_m": float(dist.min()) if len(dist) else None}
    pairs = tree.query(flat, predicate="intersects")
    if pairs.shape[1]:
        area = shapely.area(shapely.intersection(flat[pairs[0]], walls[pairs[1]]))
        real = pairs[0][area > AREA_EPS]
        n = polys.shape[1]
        out["static_overlap_samples"] = int(len(np.unique(real // n)))
        out["static_overlap_agvs"] = sorted({int(i) for i in real % n})
    return out


def peaks(d, diff: np.ndarray) -> dict:
    """Peak ratios to the limits (speed, acceleration, turn rate, wheel speed) and the peak
    lateral speed of the differential-drive AGVs ``diff`` ((N,) bool), from the poses."""
    t = np.asarray(d["t"], dtype=float)
    x, y = np.asarray(d["x"], dtype=float), np.asarray(d["y"], dtype=float)
    h = np.asarray(d["heading"], dtype=float)
    out = {"peak_speed_ratio": 0.0, "peak_accel_ratio": 0.0, "peak_turn_rate_ratio": 0.0,
           "peak_wheel_speed_ratio": None, "peak_lateral_speed_mps": 0.0}
    keep = np.concatenate([[True], np.diff(t) > 0])  # a final sample may repeat a time
    t, x, y, h = t[keep], x[keep], y[keep], h[keep]
    if len(t) < 3:
        return out
    dt = np.diff(t)[:, None]
    vx, vy = np.diff(x, axis=0) / dt, np.diff(y, axis=0) / dt
    dh = (np.diff(h, axis=0) + math.pi) % (2 * math.pi) - math.pi
    turn = np.abs(dh) / dt
    mid = h[:-1] + 0.5 * dh
    along = vx * np.cos(mid) + vy * np.sin(mid)
    lateral = np.abs(vy * np.cos(mid) - vx * np.sin(mid))
    acc = np.hypot(np.diff(vx, axis=0), np.diff(vy, axis=0)) / dt[1:]
    amax = np.broadcast_to(np.asarray(d["limit_accel_mps2"], dtype=float), acc.shape)
    if "limit_accel_loaded_mps2" in d and "loaded" in d:  # (d: a dict of the arrays)
        loaded = np.asarray(d["loaded"], dtype=bool)[keep]
        amax = np.where(loaded[1:-1], np.asarray(d["limit_accel_loaded_mps2"], dtype=float),
                        amax)
    out["peak_speed_ratio"] = float((np.hypot(vx, vy) / np.asarray(d["limit_speed_mps"])).max())
    out["peak_accel_ratio"] = float((acc / amax).max())
    out["peak_turn_rate_ratio"] = float((turn / np.asarray(d["limit_turn_rate_radps"])).max())
    if diff.any():
        out["peak_lateral_speed_mps"] = float(lateral[:, diff].max())
    if "limit_wheel_speed_mps" in d:
        lim = np.asarray(d["limit_wheel_speed_mps"], dtype=float)
        has = np.isfinite(lim)
        if has.any():
            b = np.asarray(d["wheel_base_m"], dtype=float)
            wheel = np.abs(along) + turn * b / 2
            out["peak_wheel_speed_ratio"] = float((wheel[:, has] / lim[has]).max())
    return out


def _merge(total: dict, part: dict, offset: int) -> None:
    """Add one chunk's overlap figures to the totals."""
    for key in ("agv_overlap_samples", "static_overlap_samples"):
        total[key] = total.get(key, 0) + part.get(key, 0)
    total.setdefault("pairs", set()).update(part.pop("pairs", set()))
    total.setdefault("static_overlap_agvs", set()).update(part.get("static_overlap_agvs", []))
    for key, at in (("min_agv_clearance_m", "min_agv_clearance_at"),
                    ("min_static_clearance_m", None)):
        v = part.get(key)
        if v is not None and (total.get(key) is None or v < total[key]):
            total[key] = v
            if at is not None:
                k, a, b = part[at]
                total[at] = [k + offset, a, b]


def check_npz(d, diff: np.ndarray, walls: bool = True, max_polygons: int = 1_000_000,
              overlap_stride: int = 1) -> dict:
    """Every check on one ``trajectories.npz`` (a mapping of its arrays; ``diff``: the
    no-slip AGVs), in chunks of samples of at most ``max_polygons`` bodies. The peaks use
    every sample; the overlaps every ``overlap_stride``-th (1: all), which bounds the cost
    of the shapely checks when every physics step of a large fleet is recorded."""
    x, y = np.asarray(d["x"], dtype=float), np.asarray(d["y"], dtype=float)
    heading = np.asarray(d["heading"], dtype=float)
    body = np.asarray(d["body_m"], dtype=float)
    t_count, n = x.shape
    chunk = max(3, max_polygons * overlap_stride // max(n, 1))
    chunk += -chunk % overlap_stride  # every chunk starts on a checked sample
    total: dict = {"min_agv_clearance_m": None, "min_agv_clearance_at": None,
                   "min_static_clearance_m": None}
    worst: dict = {}
    for k0 in range(0, t_count, chunk):
        sl = slice(k0, min(t_count, k0 + chunk), overlap_stride)
        polys = body_polygons(x[sl], y[sl], heading[sl], body)
        part = agv_overlaps(polys, x[sl], y[sl], body)
        if walls:
            part.update(static_overlaps(polys, np.asarray(d["grid"]), float(d["cell_m"])))
        if part.get("min_agv_clearance_at") is not None:  # a sample index of the chunk
            part["min_agv_clearance_at"][0] *= overlap_stride
        _merge(total, part, k0)
        del polys
        # peaks over the chunk and the two samples after it (the differences across)
        ext = slice(k0, min(t_count, k0 + chunk + 2))
        sub = {k: d[k] for k in d if k not in ("t", "x", "y", "heading", "loaded")}
        sub.update(t=np.asarray(d["t"])[ext], x=x[ext], y=y[ext], heading=heading[ext])
        if "loaded" in d:
            sub["loaded"] = np.asarray(d["loaded"])[ext]
        for key, v in peaks(sub, diff).items():
            if v is not None:
                worst[key] = max(worst.get(key, v), v)
    total["agv_overlap_pairs"] = len(total.pop("pairs", set()))
    total["static_overlap_agvs"] = sorted(total.get("static_overlap_agvs", set()))
    if not walls:
        for key in ("static_overlap_samples", "static_overlap_agvs", "min_static_clearance_m"):
            total.pop(key, None)
    worst.setdefault("peak_wheel_speed_ratio", None)
    return {"samples": int(t_count), "overlap_samples": len(range(0, t_count, overlap_stride)),
            **total, **worst}
