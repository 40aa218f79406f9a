"""Recorded runs for the replay view: ``trajectories.npz`` (with ``paths.json`` and
``events.jsonl`` beside it), our ``paths.json`` alone, or a Robot Runners output JSON, all
turned into the same arrays: executed poses per sample and the planned ("ghost") pose of each
AGV at the same moments.

``trajectories.npz`` is read with the renderer's :func:`~warerover_phys.render.trajectory.
load_trajectory`; files without a layout take one from a layout / scenario YAML or a MovingAI
``.map`` (``layout_grid``).
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import WareroverError
from ..render.trajectory import _centres, load_trajectory

__all__ = ["ReplayData", "open_replay", "encode_replay", "REPLAY_MAGIC", "MAX_VALUES"]

REPLAY_MAGIC = 0x31525257
"""``b"WRR1"`` little-endian."""
MAX_VALUES = 3_000_000
"""Samples x AGVs sent to the page at most (longer runs are subsampled in time)."""
_HEAD = struct.Struct("<IIII")
"""magic, T samples, N AGVs, flags (1: ghosts follow)."""
# Robot Runners headings: E, S, W, N with y down (row grows to the south).
_RR_DIRS = {"E": 0, "S": 1, "W": 2, "N": 3}
_RR_STEP = ((0, 1), (1, 0), (0, -1), (-1, 0))


@dataclass(eq=False)
class ReplayData:
    """A run ready for the page (arrays (T, N) unless noted; metres, radians, seconds)."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    state: np.ndarray
    loaded: np.ndarray
    grid: np.ndarray
    cell_m: float
    tick_s: float
    footprint: np.ndarray
    body_m: np.ndarray
    gx: np.ndarray | None = None
    gy: np.ndarray | None = None
    corridors: list[dict] = field(default_factory=list)
    source: str = ""
    kind: str = ""

    def header(self) -> dict[str, Any]:
        rows, cols = self.grid.shape
        return {"source": self.source, "kind": self.kind, "samples": int(len(self.t)),
                "agvs": int(self.x.shape[1]), "rows": int(rows), "cols": int(cols),
                "cell_m": self.cell_m, "tick_s": self.tick_s,
                "grid": "".join(str(int(v)) for v in self.grid.ravel()),
                "footprint": [int(k) for k in self.footprint],
                "body_m": [[float(a), float(b)] for a, b in self.body_m],
                "corridors": [{k: c.get(k) for k in ("id", "agv", "open_tick", "close_tick",
                                                     "zone")} for c in self.corridors],
                "ghosts": self.gx is not None, "start_s": float(self.t[0]),
                "end_s": float(self.t[-1])}


def _thin(data: ReplayData) -> ReplayData:
    """Subsample in time so samples x AGVs stays under :data:`MAX_VALUES`."""
    t, n = data.x.shape
    if t * n <= MAX_VALUES or t < 3:
        return data
    keep = np.unique(np.linspace(0, t - 1, max(2, MAX_VALUES // n)).round().astype(int))
    for name in ("x", "y", "heading", "state", "loaded", "gx", "gy"):
        arr = getattr(data, name)
        if arr is not None:
            setattr(data, name, arr[keep])
    data.t = data.t[keep]
    return data


def _ghosts_from_plans(plans: dict[int, list[tuple[int, np.ndarray]]], t: np.ndarray,
                       tick_s: float, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray,
                                                                              np.ndarray]:
    """Where the latest committed plan put each AGV at each sample time (the executed pose
    where no plan covers it). Plans are ``(start tick, (L, 2) points)``: point ``i`` is the
    plan's pose at tick ``start + i``."""
    gx, gy = x.astype(np.float32).copy(), y.astype(np.float32).copy()
    ticks = t / tick_s
    for aid, items in plans.items():
        if aid >= x.shape[1] or not items:
            continue
        starts = np.array([s for s, _ in items], dtype=float)
        which = np.searchsorted(starts, ticks, side="right") - 1
        for p, (start, pts) in enumerate(items):
            sel = np.nonzero(which == p)[0]
            if len(sel) == 0 or len(pts) == 0:
                continue
            f = np.clip(ticks[sel] - start, 0, len(pts) - 1)
            i0 = np.floor(f).astype(int)
            i1 = np.minimum(i0 + 1, len(pts) - 1)
            w = f - i0
            gx[sel, aid] = pts[i0, 0] + w * (pts[i1, 0] - pts[i0, 0])
            gy[sel, aid] = pts[i0, 1] + w * (pts[i1, 1] - pts[i0, 1])
    return gx, gy


def layout_grid(path: Path | None, fallback: np.ndarray | None,
                fallback_cell_m: float = 1.0) -> tuple[np.ndarray, float]:
    """The cell grid of a layout / scenario YAML or a MovingAI ``.map`` (or the fallback)."""
    if path is None:
        if fallback is None:
            raise WareroverError("this file carries no layout: name one (a layout or scenario "
                                 "YAML, or a MovingAI .map)")
        return fallback, fallback_cell_m
    if path.suffix == ".map":
        from ..layout import CellType
        from ..problems.movingai import read_map

        obstacles = read_map(str(path)).obstacles
        return np.where(obstacles, CellType.OBSTACLE, CellType.FLOOR).astype(np.int8), 1.0
    from ..config import LayoutSpec
    from ..layout import build_layout
    from .layout_edit import doc_from_file, layout_dict

    doc = doc_from_file(path)
    lay = build_layout(LayoutSpec.model_validate(layout_dict(doc)), file=str(path))
    return np.asarray(lay.grid), float(lay.cell_m)


def _from_npz(path: Path) -> ReplayData:
    rec = load_trajectory(path)
    gx = gy = None
    if rec.plans:
        gx, gy = _ghosts_from_plans(rec.plans, rec.t, rec.tick_s, rec.x, rec.y)
    return ReplayData(t=rec.t, x=rec.x, y=rec.y, heading=rec.heading, state=rec.state,
                      loaded=rec.loaded, grid=np.asarray(rec.grid), cell_m=rec.cell_m,
                      tick_s=rec.tick_s, footprint=rec.footprint, body_m=rec.body_m,
                      gx=gx, gy=gy, corridors=list(rec.corridors), kind="trajectories.npz")


def _headings(xy: np.ndarray) -> np.ndarray:
    """(T, N) headings from (T, N, 2) centres: the last move's direction, kept while still."""
    t, n = xy.shape[:2]
    out = np.zeros((t, n))
    last = np.zeros(n)
    for i in range(1, t):
        d = xy[i] - xy[i - 1]
        moved = np.abs(d).sum(axis=1) > 1e-9
        last = np.where(moved, np.arctan2(d[:, 1], d[:, 0]), last)
        out[i] = last
    if t > 1:
        out[0] = out[1]
    return out


def _from_paths_json(data: dict, path: Path, grid: np.ndarray, cell_m: float) -> ReplayData:
    actual = data.get("actual")
    if not isinstance(actual, dict) or not actual:
        raise WareroverError(f"{path.name}: no 'actual' paths (not a warerover paths.json)")
    rows, cols = grid.shape
    n = max(int(k) for k in actual) + 1
    agvs = data.get("agvs", {})
    k = np.array([int(agvs.get(str(i), {}).get("footprint", 1)) for i in range(n)])
    ticks = max(len(v) for v in actual.values())
    xy = np.zeros((ticks, n, 2))
    for key, states in actual.items():
        i = int(key)
        arr = np.asarray(states, dtype=np.int64).reshape(-1, 2, 2)
        if arr[..., 0].max() >= rows or arr[..., 1].max() >= cols:
            raise WareroverError(f"{path.name}: AGV {i} leaves the {rows}x{cols} layout; "
                                 "open it with the layout it ran on")
        arr = np.concatenate([arr, np.repeat(arr[-1:], ticks - len(arr), axis=0)])
        nodes = arr[..., 0] * cols + arr[..., 1]
        xy[:, i] = 0.5 * (_centres(nodes[:, 0], k[i], cols, cell_m)
                          + _centres(nodes[:, 1], k[i], cols, cell_m))
    t = np.arange(ticks, dtype=float)
    moving = np.zeros((ticks, n), dtype=np.uint8)
    moving[1:] = (np.abs(np.diff(xy, axis=0)).sum(axis=2) > 1e-9)
    plans: dict[int, list[tuple[int, np.ndarray]]] = {}
    for p in data.get("planned", []):
        aid, states = int(p["agv"]), p["states"]
        if not states or aid >= n:
            continue
        arr = np.asarray(states, dtype=np.int64).reshape(-1, 2, 2)
        nodes = arr[..., 0] * cols + arr[..., 1]
        pts = 0.5 * (_centres(nodes[:, 0], k[aid], cols, cell_m)
                     + _centres(nodes[:, 1], k[aid], cols, cell_m))
        plans.setdefault(aid, []).append((int(p["tick"]), pts))
    for items in plans.values():
        items.sort(key=lambda q: q[0])
    gx = gy = None
    if plans:
        gx, gy = _ghosts_from_plans(plans, t, 1.0, xy[..., 0], xy[..., 1])
    return ReplayData(t=t, x=xy[..., 0], y=xy[..., 1], heading=_headings(xy), state=moving,
                      loaded=np.zeros((ticks, n), np.uint8), grid=grid, cell_m=cell_m,
                      tick_s=1.0, footprint=k, body_m=np.repeat(0.7 * k[:, None] * cell_m, 2, 1),
                      gx=gx, gy=gy, kind="paths.json")


def _rr_poses(start: list, actions: str, ticks: int) -> np.ndarray:
    """(ticks, 3) row, col, direction of one Robot Runners agent."""
    r, c, d = int(start[0]), int(start[1]), _RR_DIRS.get(str(start[2]).upper(), 0)
    out = np.zeros((ticks, 3), dtype=np.int64)
    out[0] = r, c, d
    acts = [a.strip() for a in actions.split(",")] if actions else []
    for i in range(1, ticks):
        a = acts[i - 1] if i - 1 < len(acts) else "W"
        if a == "F":
            r, c = r + _RR_STEP[d][0], c + _RR_STEP[d][1]
        elif a == "R":
            d = (d + 1) % 4
        elif a == "C":
            d = (d + 3) % 4
        out[i] = r, c, d
    return out


def _from_robot_runners(data: dict, path: Path, grid: np.ndarray, cell_m: float) -> ReplayData:
    actual = data.get("actualPaths")
    starts = data.get("start")
    if not isinstance(actual, list) or not isinstance(starts, list):
        raise WareroverError(f"{path.name}: no 'actualPaths' / 'start' (not a Robot Runners "
                             "output)")
    planned = data.get("plannerPaths") or []
    n = len(actual)
    ticks = 1 + max([len([a for a in s.split(",") if a]) for s in actual + planned] + [0])
    rows, cols = grid.shape
    xy = np.zeros((ticks, n, 2))
    heading = np.zeros((ticks, n))
    gxy = np.zeros((ticks, n, 2)) if planned else None
    for i in range(n):
        p = _rr_poses(starts[i], actual[i], ticks)
        if p[:, 0].max() >= rows or p[:, 1].max() >= cols or p[:, :2].min() < 0:
            raise WareroverError(f"{path.name}: agent {i} leaves the {rows}x{cols} map; open "
                                 "it with the map it ran on")
        xy[:, i, 0] = (p[:, 1] + 0.5) * cell_m
        xy[:, i, 1] = (p[:, 0] + 0.5) * cell_m
        heading[:, i] = p[:, 2] * (np.pi / 2)
        if gxy is not None and i < len(planned):
            g = _rr_poses(starts[i], planned[i], ticks)
            gxy[:, i, 0] = (g[:, 1] + 0.5) * cell_m
            gxy[:, i, 1] = (g[:, 0] + 0.5) * cell_m
    moving = np.zeros((ticks, n), dtype=np.uint8)
    moving[1:] = (np.abs(np.diff(xy, axis=0)).sum(axis=2) > 1e-9)
    return ReplayData(t=np.arange(ticks, dtype=float), x=xy[..., 0], y=xy[..., 1],
                      heading=heading, state=moving, loaded=np.zeros((ticks, n), np.uint8),
                      grid=grid, cell_m=cell_m, tick_s=1.0, footprint=np.ones(n, np.int64),
                      body_m=np.full((n, 2), 0.7 * cell_m),
                      gx=None if gxy is None else gxy[..., 0],
                      gy=None if gxy is None else gxy[..., 1], kind="Robot Runners output")


def open_replay(path: Path, layout: Path | None = None, fallback_grid: np.ndarray | None = None,
                fallback_cell_m: float = 1.0) -> ReplayData:
    """Read a recorded run (see the module docstring) into :class:`ReplayData`."""
    if path.is_dir() or path.suffix == ".npz":
        data = _from_npz(path)
    elif path.suffix == ".json":
        from ..errors import ScenarioError
        from ..inputs import read_text

        try:
            raw = json.loads(read_text(path, "replay", 2**30))  # a regular file, <= 1 GiB
        except ScenarioError as err:
            raise WareroverError(f"{path.name}: {err.message}") from None
        except (OSError, json.JSONDecodeError, RecursionError) as err:
            raise WareroverError(f"{path.name}: cannot read JSON ({err})") from None
        if not isinstance(raw, dict):
            raise WareroverError(f"{path.name}: expected a JSON object")
        grid, cell_m = layout_grid(layout, fallback_grid, fallback_cell_m)
        if "actualPaths" in raw:
            data = _from_robot_runners(raw, path, grid, cell_m)
        else:
            data = _from_paths_json(raw, path, grid, cell_m)
    else:
        raise WareroverError(f"{path.name}: replay opens trajectories.npz, paths.json or a "
                             "Robot Runners output .json")
    data.source = path.name
    return _thin(data)


def encode_replay(data: ReplayData) -> bytes:
    """Binary replay body: header (magic, T, N, flags), ``t`` float32 (T), then float32
    ``x``, ``y``, ``heading`` (T x N each, row-major), uint8 ``state``, ``loaded`` (T x N
    each), zero padding to 4 bytes, and (flag 1) float32 ghost ``x``, ``y`` (T x N each)."""
    t, n = data.x.shape
    ghosts = data.gx is not None
    parts = [_HEAD.pack(REPLAY_MAGIC, t, n, 1 if ghosts else 0),
             np.asarray(data.t, "<f4").tobytes()]
    for arr in (data.x, data.y, data.heading):
        parts.append(np.asarray(arr, "<f4").tobytes())
    small = np.concatenate([np.asarray(data.state, np.uint8).ravel(),
                            np.asarray(data.loaded, np.uint8).ravel()]).tobytes()
    parts += [small, b"\0" * ((-len(small)) % 4)]
    if ghosts:
        parts += [np.asarray(data.gx, "<f4").tobytes(), np.asarray(data.gy, "<f4").tobytes()]
    return b"".join(parts)
