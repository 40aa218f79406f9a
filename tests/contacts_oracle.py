"""Contacts recomputed from recorded poses with shapely, without the executor's code.

Shared by the contact tests. The input is what ``trajectories.npz`` holds (poses ``x``,
``y``, ``heading`` per sample and AGV, ``loaded``, the carried shelf's size ``shelf_m``,
``body_m``) and the layout (obstacle cells, shelves, map size). The model, written out here:

- an AGV is its body rectangle (``body_m``: length along its heading, width across) and,
  while loaded, its shelf: a square of side ``shelf_m`` about the same centre, sides along
  the grid (the drive unit turns under the shelf);
- static things are the obstacle cells (squares), the map's edge (anything outside
  ``[0, cols] x [0, rows]`` cells) and, for a *loaded* AGV, every shelf it does not carry at
  its home: a square of side ``SHELF_SIDE x size x cell_m`` about the home's centre (an
  unloaded AGV drives under shelves);
- the shelf an AGV carries is the one whose home holds its centre when it becomes loaded.

Recorded every physics step (``executor.trajectory_hz = 1 / dt_s``), the samples are the
poses at which the physics engine looks for contacts, so every contact it counts is an
overlap here and the reverse.
"""

from __future__ import annotations

import numpy as np
import shapely

SHELF_SIDE = 0.9
"""A shelf's side over its footprint (the physics model's ``bodies.SHELF_SIDE``)."""


def agv_parts(traj: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T, N) shapely body rectangles and carried-shelf squares of every AGV at every
    sample, and the (T, N) loaded flags (a shelf square counts only where loaded)."""
    x, y, th = (np.asarray(traj[k], dtype=float) for k in ("x", "y", "heading"))
    half = np.asarray(traj["body_m"], dtype=float) / 2  # (N, 2)
    c, s = np.cos(th), np.sin(th)
    corners = []
    for sx, sy in ((1, 1), (-1, 1), (-1, -1), (1, -1)):
        u, v = sx * half[:, 0], sy * half[:, 1]
        corners.append(np.stack([x + c * u - s * v, y + s * u + c * v], axis=-1))
    body = shapely.polygons(np.stack(corners, axis=-2))
    side = np.asarray(traj["shelf_m"], dtype=float)
    shelf = shapely.box(x - side[..., 0] / 2, y - side[..., 1] / 2,
                        x + side[..., 0] / 2, y + side[..., 1] / 2)
    return body, shelf, np.asarray(traj["loaded"], dtype=bool)


def reach(traj: dict) -> np.ndarray:
    """(T, N) radius about each AGV's centre that holds all of it."""
    body = np.hypot(*np.asarray(traj["body_m"], dtype=float).T) / 2
    shelf = np.hypot(*np.moveaxis(np.asarray(traj["shelf_m"], dtype=float), -1, 0)) / 2
    return np.maximum(body[None, :], np.where(traj["loaded"], shelf, 0.0))


def shelf_boxes(layout) -> np.ndarray:
    m = layout.cell_m
    boxes = []
    for sh in layout.shelves:
        r, c = sh.anchor
        cx, cy, h = (c + sh.size / 2) * m, (r + sh.size / 2) * m, SHELF_SIDE * sh.size * m / 2
        boxes.append(shapely.box(cx - h, cy - h, cx + h, cy + h))
    return np.array(boxes, dtype=object)


def carried_shelves(traj: dict, layout) -> np.ndarray:
    """(T, N) id of the shelf each AGV carries (-1: none)."""
    loaded = np.asarray(traj["loaded"], dtype=bool)
    x, y = np.asarray(traj["x"], dtype=float), np.asarray(traj["y"], dtype=float)
    boxes = shelf_boxes(layout)
    out = np.full(loaded.shape, -1, dtype=np.int64)
    for i in range(loaded.shape[1]):
        held = -1
        for t in range(loaded.shape[0]):
            if loaded[t, i] and held < 0:
                (hit,) = np.nonzero(shapely.contains_xy(boxes, x[t, i], y[t, i]))
                assert len(hit) == 1, (t, i, hit)
                held = int(hit[0])
            elif not loaded[t, i]:
                held = -1
            out[t, i] = held
    return out


def static_overlaps(traj: dict, layout) -> list[tuple[int, int, str]]:
    """``(sample, agv, thing)`` for every sample at which an AGV overlaps (or touches) a
    static thing: ``"edge"``, ``"obstacle r,c"`` or ``"shelf k"``."""
    body, shelf, loaded = agv_parts(traj)
    # the loaded AGVs' shelf squares join their bodies: (sample, agv) of each shape
    shapes = np.concatenate([body.ravel(), shelf[loaded]])
    who = np.concatenate([np.argwhere(np.ones(body.shape, dtype=bool)), np.argwhere(loaded)])
    m = layout.cell_m
    found: set[tuple[int, int, str]] = set()
    lo_x, lo_y, hi_x, hi_y = shapely.bounds(shapes).T
    out = (lo_x <= 0) | (lo_y <= 0) | (hi_x >= layout.cols * m) | (hi_y >= layout.rows * m)
    found |= {(int(t), int(i), "edge") for t, i in who[out]}
    cells = np.argwhere(layout.obstacles)
    if len(cells):
        walls = shapely.box(cells[:, 1] * m, cells[:, 0] * m, (cells[:, 1] + 1) * m,
                            (cells[:, 0] + 1) * m)
        for g, w in shapely.STRtree(walls).query(shapes, predicate="intersects").T:
            r, c = cells[w]
            found.add((int(who[g, 0]), int(who[g, 1]), f"obstacle {r},{c}"))
    if loaded.any():
        carried = carried_shelves(traj, layout)
        # only loaded AGVs meet shelves (an unloaded one drives under them)
        idx = np.flatnonzero(np.concatenate([loaded.ravel(), np.ones(loaded.sum(), bool)]))
        for g, k in shapely.STRtree(shelf_boxes(layout)).query(shapes[idx],
                                                                predicate="intersects").T:
            t, i = who[idx[g]]
            if carried[t, i] != k:
                found.add((int(t), int(i), f"shelf {k}"))
    return sorted(found)


def _pair_distances(traj: dict, a: int, b: int, samples: np.ndarray,
                    parts: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """Distance between AGVs ``a`` and ``b`` (bodies, and shelves where loaded) at
    ``samples``."""
    body, shelf, loaded = parts
    d = shapely.distance(body[samples, a], body[samples, b])
    for i, j in ((a, b), (b, a)):
        with_shelf = samples[loaded[samples, i]]
        if len(with_shelf):
            d2 = shapely.distance(shelf[with_shelf, i], body[with_shelf, j])
            both = loaded[with_shelf, j]
            d2[both] = np.minimum(d2[both], shapely.distance(shelf[with_shelf[both], i],
                                                             shelf[with_shelf[both], j]))
            d[loaded[samples, i]] = np.minimum(d[loaded[samples, i]], d2)
    return d


def agv_distances(traj: dict, within: float) -> list[tuple[int, int, int, float]]:
    """``(sample, a, b, distance)`` (a < b) wherever two AGVs come within ``within`` metres
    of each other (0: touching or overlapping)."""
    parts = agv_parts(traj)
    x, y = np.asarray(traj["x"], dtype=float), np.asarray(traj["y"], dtype=float)
    r = reach(traj)
    found = []
    n = x.shape[1]
    for a in range(n):
        for b in range(a + 1, n):
            gap = np.hypot(x[:, a] - x[:, b], y[:, a] - y[:, b]) - r[:, a] - r[:, b]
            near = np.flatnonzero(gap <= within)  # the exact distance is >= gap
            if len(near):
                d = _pair_distances(traj, a, b, near, parts)
                found += [(int(t), a, b, float(v)) for t, v in zip(near, d, strict=True)
                          if v <= within]
    return found


def agv_overlaps(traj: dict) -> list[tuple[int, int, int]]:
    """``(sample, a, b)`` (a < b) for every sample at which two AGVs overlap or touch."""
    return sorted((t, a, b) for t, a, b, _ in agv_distances(traj, 0.0))


def min_agv_clearance(traj: dict, upto: float = 0.5) -> float:
    """Smallest distance between any two AGVs over every sample (0: touching or
    overlapping; inf: none came within ``upto`` metres)."""
    return min((d for *_, d in agv_distances(traj, upto)), default=np.inf)


def run_starts(overlaps: list[tuple]) -> list[tuple]:
    """The samples at which each overlap begins: ``(sample, *who)`` for the first sample of
    every run of consecutive samples with the same ``who`` (AGV and thing, or AGV pair)."""
    seen: dict[tuple, int] = {}
    starts = []
    for t, *who in sorted(overlaps):
        key = tuple(who)
        if seen.get(key) != t - 1:
            starts.append((t, *key))
        seen[key] = t
    return starts
