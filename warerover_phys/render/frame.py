"""One frame of an episode: a pure function from a state snapshot to a BGR image.

:func:`draw_frame` draws, in this order: the floor (cell types: shelves, stations, parking,
obstacles; grid lines when cells are big enough), the open safety corridors (translucent zone
and outline), the planned path ahead of each AGV (optional), each AGV's planned pose as an outlined
ghost (optional, ``Style.ghosts``: the open-loop gap's video), the AGVs as rotated rectangles
of their true size coloured by status (idle, moving, loaded, failed) with a heading mark, a
cargo marker, a cross when failed and the id, then a heads-up line (simulated time, orders
done / total, throughput, active failures) and a legend. Colours are the Okabe-Ito palette
(distinct for the common colour-vision deficiencies); status is also shown by shape (cargo
square, failure cross), so it does not rest on colour alone.

Large layouts: the map is scaled to fit the frame (or the ``viewport`` cells); details drop
out below a pixel size (ids below ``label_min_px``, heading marks, outlines and cargo below
``detail_min_px``) and bodies are drawn at least ``min_agv_px`` wide so 1000 AGVs on an
industrial floor stay visible.

>>> import numpy as np
>>> scene = Scene(grid=np.zeros((4, 6), np.int8), cell_m=1.0, body_m=np.array([[0.7, 0.7]]),
...               footprint=np.array([1]))
>>> snap = Snapshot(scene=scene, time_s=0.0, tick_s=1.0, x=np.array([1.5]),
...                 y=np.array([1.5]), heading=np.array([0.0]), state=np.array([1]),
...                 loaded=np.array([False]))
>>> draw_frame(snap, Style(size=(320, 240))).shape
(240, 320, 3)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

__all__ = ["Scene", "Snapshot", "Style", "draw_frame", "PALETTE", "status_of", "Geometry",
           "frame_geometry"]


def _bgr(hex_rgb: str) -> tuple[int, int, int]:
    v = int(hex_rgb.lstrip("#"), 16)
    return (v & 255, (v >> 8) & 255, v >> 16)


def _tint(color: tuple[int, int, int], amount: float) -> tuple[int, int, int]:
    """``color`` mixed with white (``amount`` 0 = colour, 1 = white)."""
    return tuple(int(round(c + (255 - c) * amount)) for c in color)  # type: ignore[return-value]


# Okabe-Ito (https://jfly.uni-koeln.de/color/), as BGR for OpenCV.
OKABE_ITO = {"black": _bgr("000000"), "orange": _bgr("E69F00"), "sky": _bgr("56B4E9"),
             "green": _bgr("009E73"), "yellow": _bgr("F0E442"), "blue": _bgr("0072B2"),
             "vermillion": _bgr("D55E00"), "purple": _bgr("CC79A7"), "grey": _bgr("999999")}

PALETTE: dict[str, tuple[int, int, int]] = {
    "floor": (250, 250, 250),
    "grid_line": (222, 222, 222),
    "obstacle": (64, 64, 64),
    "shelf": _tint(OKABE_ITO["sky"], 0.45),
    "station": _tint(OKABE_ITO["green"], 0.35),
    "parking": _tint(OKABE_ITO["yellow"], 0.35),
    "idle": OKABE_ITO["grey"],
    "moving": OKABE_ITO["blue"],
    "loaded": OKABE_ITO["orange"],
    "failed": OKABE_ITO["vermillion"],
    "corridor": OKABE_ITO["purple"],
    "ghost": OKABE_ITO["green"],
    "switch": OKABE_ITO["black"],
    "outline": (30, 30, 30),
    "hud_bg": (38, 38, 38),
    "hud_text": (245, 245, 245),
    "legend_bg": (238, 238, 238),
    "legend_text": (20, 20, 20),
}
"""Colours (BGR) by role; cells use ``floor``/``obstacle``/``shelf``/``station``/``parking``,
AGVs their status (``idle``, ``moving``, ``loaded``, ``failed``)."""

STATUS_NAMES = ("idle", "moving", "loaded", "failed")
_STATUS_BGR = np.array([PALETTE[s] for s in STATUS_NAMES], dtype=np.int32)
_INK = (PALETTE["outline"], (255, 255, 255), PALETTE["outline"], (255, 255, 255))
"""Colour of marks drawn on a body of each status (dark on light bodies, white on dark)."""
_CELL_BGR = np.array([PALETTE["floor"], PALETTE["obstacle"], PALETTE["shelf"],
                      PALETTE["station"], PALETTE["parking"]], dtype=np.uint8)
"""Indexed by ``CellType`` (FLOOR, OBSTACLE, SHELF, STATION, PARKING)."""
FAILED_STATE = 7
SHIFT = 4
"""Sub-pixel bits for OpenCV drawing (coordinates are multiplied by 16)."""
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_AA = cv2.LINE_AA


def status_of(state: np.ndarray, loaded: np.ndarray) -> np.ndarray:
    """Status index per AGV: 0 idle, 1 moving (working, no cargo), 2 loaded, 3 failed."""
    state = np.asarray(state)
    out = np.where(np.asarray(loaded, dtype=bool), 2, np.where(state == 0, 0, 1))
    return np.where(state == FAILED_STATE, 3, out)


@dataclass(frozen=True, eq=False)
class Scene:
    """What stays the same in every frame: the layout and the fleet's bodies."""

    grid: np.ndarray
    """``(rows, cols)`` ``CellType`` codes."""
    cell_m: float
    body_m: np.ndarray
    """``(N, 2)`` body length (along the heading) and width, metres."""
    footprint: np.ndarray
    _cache: dict = field(default_factory=dict, repr=False)
    """Style -> (geometry, background image); filled on first use."""


@dataclass(frozen=True, eq=False)
class Snapshot:
    """The state drawn in one frame. Arrays are per AGV (index = AGV id), metres/radians."""

    scene: Scene
    time_s: float
    tick_s: float
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    state: np.ndarray
    """``AgvState`` codes (7 = failed)."""
    loaded: np.ndarray
    corridors: tuple[dict, ...] = ()
    """Open corridors: ``{"id", "agv", "zone": [[[x, y], ...], ...], ...}`` (metres)."""
    orders_done: int | None = None
    orders_total: int | None = None
    paths: list[np.ndarray | None] | None = None
    """Per AGV, ``(K, 2)`` points (metres) of the path ahead, or None."""
    ghosts: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    """Per AGV, the planned pose ``(x, y, heading)`` at this time (metres, radians; NaN:
    none), drawn as an outlined ghost when ``Style.ghosts`` is on."""
    switches: tuple[dict, ...] = ()
    """Edges of the dependency graph switched a moment ago (``executor.reorder``):
    ``{"first": AGV now passing first, "then": AGV passing after it, "cells": [[row, col],
    ...]}``, drawn when ``Style.switches`` is on."""


@dataclass(frozen=True)
class Style:
    """How to draw. ``size`` in pixels (width, height); ``viewport`` the cells shown,
    ``(row0, col0, row1, col1)`` inclusive (None: the whole layout)."""

    size: tuple[int, int] = (1280, 720)
    viewport: tuple[int, int, int, int] | None = None
    show_paths: bool = True
    path_ticks: int = 8
    """How many planned steps ahead to draw."""
    show_hud: bool = True
    show_legend: bool = True
    label_min_px: float = 16.0
    """AGV ids are drawn when a body is at least this many pixels wide."""
    detail_min_px: float = 7.0
    """Outline, heading mark, cargo marker and failure cross from this body size (pixels)."""
    min_agv_px: float = 3.0
    """Bodies smaller than this on screen are drawn this size."""
    grid_lines_min_px: float = 8.0
    corridor_alpha: float = 0.4
    title: str = ""
    """Shown at the right end of the heads-up line."""
    ghosts: bool = False
    """Draw each AGV's planned pose (``Snapshot.ghosts``) as an outlined ghost, with a line
    to the real body when they are apart (and a legend entry)."""
    switches: bool = False
    """Draw switched edges (``Snapshot.switches``): their cells outlined and an arrow from
    the AGV that now passes first to the one that passes after it (and a legend entry)."""

    def __post_init__(self) -> None:
        w, h = self.size
        if not (16 <= w <= 8192 and 16 <= h <= 8192):
            raise ValueError(f"frame size must be 16..8192 pixels a side (got {w}x{h})")
        if self.viewport is not None:
            r0, c0, r1, c1 = self.viewport
            if r0 < 0 or c0 < 0 or r1 < r0 or c1 < c0:
                raise ValueError(f"viewport must be row0,col0,row1,col1 with row0 <= row1 and "
                                 f"col0 <= col1, all >= 0 (got {self.viewport})")


@dataclass(frozen=True)
class Geometry:
    """Where the map goes in the frame: ``px = ox + (x_m - x0_m) * scale`` (x likewise),
    relative to the map band (rows ``top`` .. ``bottom`` of the frame)."""

    scale: float
    """Pixels per metre."""
    x0_m: float
    y0_m: float
    ox: float
    oy: float
    top: int
    bottom: int
    font: float
    hud_h: int
    legend_h: int

    def to_px(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Frame pixel coordinates (float) of world points."""
        return (self.ox + (np.asarray(x) - self.x0_m) * self.scale,
                self.top + self.oy + (np.asarray(y) - self.y0_m) * self.scale)


def _geometry(scene: Scene, style: Style) -> tuple[Geometry, tuple[int, int, int, int]]:
    rows, cols = scene.grid.shape
    r0, c0, r1, c1 = style.viewport or (0, 0, rows - 1, cols - 1)
    if r0 >= rows or c0 >= cols:
        raise ValueError(f"viewport {style.viewport} starts outside the {rows}x{cols} layout")
    r1, c1 = min(r1, rows - 1), min(c1, cols - 1)
    w, h = style.size
    font = max(0.35, h / 1300)
    hud_h = int(round(32 * font / 0.55)) if style.show_hud else 0
    legend_h = int(round(30 * font / 0.55)) if style.show_legend else 0
    band = h - hud_h - legend_h
    if band < 8:
        raise ValueError(f"frame {w}x{h} is too small for the heads-up line and legend")
    margin = max(2, int(round(h * 0.008)))
    vw, vh = (c1 - c0 + 1) * scene.cell_m, (r1 - r0 + 1) * scene.cell_m
    scale = min((w - 2 * margin) / vw, (band - 2 * margin) / vh)
    ox = round((w - vw * scale) / 2)
    oy = round((band - vh * scale) / 2)
    return (Geometry(scale=scale, x0_m=c0 * scene.cell_m, y0_m=r0 * scene.cell_m, ox=ox, oy=oy,
                     top=hud_h, bottom=h - legend_h, font=font, hud_h=hud_h, legend_h=legend_h),
            (r0, c0, r1, c1))


def frame_geometry(scene: Scene, style: Style) -> Geometry:
    """Where ``scene`` is drawn in frames of ``style`` (world metres -> pixels)."""
    return _background(scene, style)[0]


def _background(scene: Scene, style: Style) -> tuple[Geometry, np.ndarray]:
    """The geometry and the static image (cells, grid lines, legend), cached per style."""
    hit = scene._cache.get(style)
    if hit is not None:
        return hit
    geo, (r0, c0, r1, c1) = _geometry(scene, style)
    w, h = style.size
    img = np.empty((h, w, 3), dtype=np.uint8)
    img[:] = PALETTE["legend_bg"]
    band = img[geo.top:geo.bottom]
    band[:] = (255, 255, 255)
    cells = scene.grid[r0:r1 + 1, c0:c1 + 1]
    codes = np.clip(cells.astype(np.int64), 0, len(_CELL_BGR) - 1)
    small = _CELL_BGR[codes]
    mw = int(round(cells.shape[1] * scene.cell_m * geo.scale))
    mh = int(round(cells.shape[0] * scene.cell_m * geo.scale))
    cell_px = scene.cell_m * geo.scale
    interp = cv2.INTER_NEAREST if cell_px >= 1 else cv2.INTER_AREA
    big = cv2.resize(small, (max(mw, 1), max(mh, 1)), interpolation=interp)
    ox, oy = int(geo.ox), int(geo.oy)
    band[oy:oy + big.shape[0], ox:ox + big.shape[1]] = big[:band.shape[0] - oy,
                                                            :band.shape[1] - ox]
    if cell_px >= style.grid_lines_min_px:
        line = PALETTE["grid_line"]
        for i in range(cells.shape[1] + 1):
            xp = ox + int(round(i * cell_px))
            cv2.line(band, (xp, oy), (xp, oy + mh), line, 1)
        for i in range(cells.shape[0] + 1):
            yp = oy + int(round(i * cell_px))
            cv2.line(band, (ox, yp), (ox + mw, yp), line, 1)
        # Obstacles and shelves keep crisp edges over the lines.
        for code in (1, 2):
            rr, cc = np.nonzero(codes == code)
            if 0 < len(rr) <= 20000:
                for r, c in zip(rr.tolist(), cc.tolist(), strict=True):
                    x0 = ox + int(round(c * cell_px)) + 1
                    y0 = oy + int(round(r * cell_px)) + 1
                    x1 = ox + int(round((c + 1) * cell_px)) - 1
                    y1 = oy + int(round((r + 1) * cell_px)) - 1
                    cv2.rectangle(band, (x0, y0), (x1, y1), tuple(int(v) for v in _CELL_BGR[code]), -1)
    cv2.rectangle(band, (ox - 1, oy - 1), (ox + mw, oy + mh), PALETTE["outline"], 1)
    if style.show_hud:
        img[:geo.top] = PALETTE["hud_bg"]
    if style.show_legend:
        _legend(img, geo, style)
    scene._cache[style] = (geo, img)
    return geo, img


def _legend(img: np.ndarray, geo: Geometry, style: Style) -> None:
    items = [("idle", "idle"), ("moving", "moving"), ("loaded", "loaded"), ("failed", "failed"),
             ("shelf", "shelf"), ("station", "station"), ("parking", "parking"),
             ("obstacle", "obstacle"), ("corridor", "safety corridor")]
    if style.show_paths:
        items.append(("path", "planned path"))
    if style.ghosts:
        items.append(("ghost", "planned pose (ghost)"))
    if style.switches:
        items.append(("switch", "switched edge (first -> then)"))
    w = style.size[0]
    font = geo.font * 0.9
    for _ in range(6):
        box = int(round(geo.legend_h * 0.5))
        widths = [box + 6 + cv2.getTextSize(t, _FONT, font, 1)[0][0] + 16 for _, t in items]
        if sum(widths) <= w - 16 or font < 0.3:
            break
        font *= 0.85
    x = 8
    yc = geo.bottom + geo.legend_h // 2
    for (key, text), width in zip(items, widths, strict=True):
        y0 = yc - box // 2
        if key == "path":
            cv2.line(img, (x, yc), (x + box, yc), PALETTE["moving"], 2, _AA)
        elif key == "ghost":
            cv2.rectangle(img, (x + 1, y0 + 1), (x + box - 1, y0 + box - 1), PALETTE["ghost"], 2)
        elif key == "switch":
            cv2.arrowedLine(img, (x, y0 + box - 1), (x + box, y0 + 1), PALETTE["switch"], 2,
                            _AA, 0, 0.4)
        elif key == "corridor":
            cv2.rectangle(img, (x, y0), (x + box, y0 + box),
                          _blend(PALETTE["floor"], PALETTE["corridor"], style.corridor_alpha), -1)
            cv2.rectangle(img, (x, y0), (x + box, y0 + box), PALETTE["corridor"], 2)
        else:
            cv2.rectangle(img, (x, y0), (x + box, y0 + box), PALETTE[key], -1)
            cv2.rectangle(img, (x, y0), (x + box, y0 + box), PALETTE["outline"], 1)
            if key == "loaded":
                q = box // 4
                cv2.rectangle(img, (x + q, y0 + q), (x + box - q, y0 + box - q),
                              PALETTE["shelf"], -1)
            elif key == "failed":
                cv2.line(img, (x + 2, y0 + 2), (x + box - 2, y0 + box - 2), (255, 255, 255), 1, _AA)
                cv2.line(img, (x + 2, y0 + box - 2), (x + box - 2, y0 + 2), (255, 255, 255), 1, _AA)
        th = cv2.getTextSize(text, _FONT, font, 1)[0][1]
        cv2.putText(img, text, (x + box + 6, yc + th // 2), _FONT, font, PALETTE["legend_text"],
                    1, _AA)
        x += width


def _blend(under: tuple[int, int, int], over: tuple[int, int, int],
           alpha: float) -> tuple[int, int, int]:
    return tuple(int(round(u * (1 - alpha) + o * alpha)) for u, o in zip(under, over, strict=True))  # type: ignore[return-value]


def _fixed(px: np.ndarray) -> np.ndarray:
    """Pixel coordinates as OpenCV fixed-point integers (``SHIFT`` fractional bits)."""
    return np.round(px * (1 << SHIFT)).astype(np.int32)


def _corridors(band: np.ndarray, geo: Geometry, corridors: tuple[dict, ...],
               style: Style) -> None:
    color = PALETTE["corridor"]
    thick = max(1, int(round(geo.scale * 0.06)))
    bh, bw = band.shape[:2]
    for c in corridors:
        rings = [np.asarray(r, dtype=np.float64) for r in c.get("zone") or c.get("polygon") or []
                 if len(r) >= 3]
        if not rings:
            continue
        pts = [np.stack([geo.ox + (r[:, 0] - geo.x0_m) * geo.scale,
                         geo.oy + (r[:, 1] - geo.y0_m) * geo.scale], axis=1) for r in rings]
        allp = np.vstack(pts)
        x0, y0 = np.floor(allp.min(axis=0)).astype(int) - 2
        x1, y1 = np.ceil(allp.max(axis=0)).astype(int) + 2
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, bw), min(y1, bh)
        if x1 <= x0 or y1 <= y0:
            continue
        roi = band[y0:y1, x0:x1]
        overlay = roi.copy()
        local = [_fixed(p - (x0, y0)) for p in pts]
        for poly in local:
            cv2.fillPoly(overlay, [poly], color, _AA, SHIFT)
        cv2.addWeighted(overlay, style.corridor_alpha, roi, 1 - style.corridor_alpha, 0, dst=roi)
        cv2.polylines(roi, local, True, color, thick, _AA, SHIFT)


def _paths(band: np.ndarray, geo: Geometry, snap: Snapshot, status: np.ndarray,
           style: Style) -> None:
    """Planned paths ahead, one polyline call per status colour; a dot at each end."""
    paths = snap.paths or []
    keep = [i for i, p in enumerate(paths) if p is not None and len(p) >= 2 and status[i] != 3]
    if not keep:
        return
    thick = max(1, int(round(geo.scale * 0.07)))
    lengths = [len(paths[i]) for i in keep]
    allp = np.concatenate([paths[i] for i in keep])
    px = np.empty_like(allp)
    px[:, 0] = geo.ox + (allp[:, 0] - geo.x0_m) * geo.scale
    px[:, 1] = geo.oy + (allp[:, 1] - geo.y0_m) * geo.scale
    fixed = np.split(_fixed(px), np.cumsum(lengths)[:-1])
    groups: dict[int, list[np.ndarray]] = {}
    for i, poly in zip(keep, fixed, strict=True):
        groups.setdefault(int(status[i]), []).append(poly)
    dots = geo.scale * float(scene_min_body(snap)) >= style.detail_min_px
    radius = int(round(max(2.0, thick * 1.6) * (1 << SHIFT)))
    for st, polys in groups.items():
        color = PALETTE[STATUS_NAMES[st]]
        cv2.polylines(band, polys, False, color, thick, _AA, SHIFT)
        if dots:
            for poly in polys:
                end = poly[-1]
                cv2.circle(band, (int(end[0]), int(end[1])), radius, color, -1, _AA, SHIFT)


def scene_min_body(snap: Snapshot) -> float:
    """The smallest body side in the fleet (metres)."""
    cache = snap.scene._cache
    if "min_body" not in cache:
        cache["min_body"] = float(snap.scene.body_m.min()) if len(snap.scene.body_m) else 0.0
    return cache["min_body"]


def _agvs(band: np.ndarray, geo: Geometry, snap: Snapshot, style: Style,
          status: np.ndarray) -> None:
    scene = snap.scene
    n = len(snap.x)
    if n == 0:
        return
    s = geo.scale
    half = np.maximum(scene.body_m * s, style.min_agv_px) / 2          # (N, 2) px
    cx = geo.ox + (snap.x - geo.x0_m) * s
    cy = geo.oy + (snap.y - geo.y0_m) * s
    bh, bw = band.shape[:2]
    reach = half.max(axis=1) * 1.5
    visible = np.flatnonzero((cx + reach >= 0) & (cx - reach < bw) &
                             (cy + reach >= 0) & (cy - reach < bh))
    if len(visible) == 0:
        return
    c, si = np.cos(snap.heading), np.sin(snap.heading)
    ux = np.stack([c, si], axis=1)                                      # forward
    uy = np.stack([-si, c], axis=1)                                     # left-hand side (y down)
    centre = np.stack([cx, cy], axis=1)
    sx = np.array([1, -1, -1, 1])[None, :, None]
    sy = np.array([1, 1, -1, -1])[None, :, None]
    corners = (centre[:, None, :] + sx * half[:, None, 0:1] * ux[:, None, :]
               + sy * half[:, None, 1:2] * uy[:, None, :])              # (N, 4, 2)
    fixed = _fixed(corners)
    size_px = 2 * half.min(axis=1)
    detail = (size_px >= style.detail_min_px).tolist()
    labels = (size_px >= style.label_min_px).tolist()
    colors = [tuple(c) for c in _STATUS_BGR[status].tolist()]
    st_list = status.tolist()
    outline = PALETTE["outline"]
    # Marks, all AGVs at once: heading triangle, cargo square, failure cross.
    c3 = centre[:, None, :]
    f3, l3 = (ux * half[:, 0:1])[:, None, :], (uy * half[:, 1:2])[:, None, :]
    nose = _fixed(c3 + f3 * np.array([0.92, 0.58, 0.58])[None, :, None]
                  + l3 * np.array([0.0, 0.3, -0.3])[None, :, None])
    cargo = _fixed(corners * 0.5 + c3 * 0.5)
    down = np.flatnonzero(status == 3)
    cross = dict(zip(down.tolist(), _fixed(corners[down] * 0.8 + c3[down] * 0.2).tolist(),
                     strict=True))
    cross_t = np.maximum(1, np.round(size_px / 14)).astype(int).tolist()
    shelf = PALETTE["shelf"]
    for i in visible.tolist():
        cv2.fillConvexPoly(band, fixed[i], colors[i], _AA, SHIFT)
        if not detail[i]:
            continue
        st = st_list[i]
        ink = _INK[st]
        cv2.polylines(band, [fixed[i]], True, outline, 1, _AA, SHIFT)
        if st == 2:           # cargo: a shelf-coloured square in the middle
            cv2.fillConvexPoly(band, cargo[i], shelf, _AA, SHIFT)
            cv2.polylines(band, [cargo[i]], True, outline, 1, _AA, SHIFT)
        elif st == 3:         # failed: a cross corner to corner
            k = cross[i]
            cv2.line(band, k[0], k[2], ink, cross_t[i], _AA, SHIFT)
            cv2.line(band, k[1], k[3], ink, cross_t[i], _AA, SHIFT)
        cv2.fillConvexPoly(band, nose[i], ink, _AA, SHIFT)
        if labels[i]:
            text = str(i)
            fs = min(1.2, float(size_px[i]) / 60)
            th = 1 if fs < 0.7 else 2
            (tw, tht), _ = cv2.getTextSize(text, _FONT, fs, th)
            fit = 0.6 * float(size_px[i]) / tw    # keep clear of the heading mark
            if fit < 1:
                fs *= fit
                (tw, tht), _ = cv2.getTextSize(text, _FONT, fs, th)
            if fs < 0.28:
                continue
            cx_i, cy_i = float(cx[i]), float(cy[i])
            cv2.putText(band, text, (int(cx_i - tw / 2), int(cy_i + tht / 2)), _FONT, fs,
                        outline if st in (0, 2) else (255, 255, 255), th, _AA)


def _ghosts(band: np.ndarray, geo: Geometry, snap: Snapshot, style: Style) -> None:
    """Each AGV's planned pose as an outline of its body in the ``ghost`` colour, and a
    line from it to the real body's centre when they are more than a body apart / 4."""
    gx, gy, gh = (np.asarray(a, dtype=np.float64) for a in snap.ghosts)
    body = snap.scene.body_m
    keep = np.flatnonzero(np.isfinite(gx) & np.isfinite(gy) & np.isfinite(gh))
    if len(keep) == 0:
        return
    s = geo.scale
    half = np.maximum(body[keep] * s, style.min_agv_px) / 2
    cx = geo.ox + (gx[keep] - geo.x0_m) * s
    cy = geo.oy + (gy[keep] - geo.y0_m) * s
    c, si = np.cos(gh[keep]), np.sin(gh[keep])
    ux, uy = np.stack([c, si], axis=1), np.stack([-si, c], axis=1)
    centre = np.stack([cx, cy], axis=1)
    sx = np.array([1, -1, -1, 1])[None, :, None]
    sy = np.array([1, 1, -1, -1])[None, :, None]
    corners = (centre[:, None, :] + sx * half[:, None, 0:1] * ux[:, None, :]
               + sy * half[:, None, 1:2] * uy[:, None, :])
    color = PALETTE["ghost"]
    thick = max(2, int(round(float(half.min()) * 0.2)))
    cv2.polylines(band, list(_fixed(corners)), True, color, thick, _AA, SHIFT)
    rx = geo.ox + (np.asarray(snap.x, dtype=np.float64)[keep] - geo.x0_m) * s
    ry = geo.oy + (np.asarray(snap.y, dtype=np.float64)[keep] - geo.y0_m) * s
    apart = np.hypot(rx - cx, ry - cy) > half.min(axis=1) / 2
    for j in np.flatnonzero(apart).tolist():
        a = _fixed(np.array([cx[j], cy[j]]))
        b = _fixed(np.array([rx[j], ry[j]]))
        cv2.line(band, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), color,
                 max(1, thick // 2), _AA, SHIFT)


def _switches(band: np.ndarray, geo: Geometry, snap: Snapshot) -> None:
    """Switched edges: each cell outlined, an arrow from the AGV passing first to the AGV
    passing after it."""
    s = geo.scale
    cell_px = snap.scene.cell_m * s
    color = PALETTE["switch"]
    thick = max(1, int(round(cell_px * 0.06)))
    n = len(snap.x)
    for sw in snap.switches:
        for r, c in sw["cells"]:
            x0 = geo.ox + (c * snap.scene.cell_m - geo.x0_m) * s
            y0 = geo.oy + (r * snap.scene.cell_m - geo.y0_m) * s
            cv2.rectangle(band, (int(x0), int(y0)), (int(x0 + cell_px), int(y0 + cell_px)),
                          color, thick, _AA)
        a, b = int(sw["first"]), int(sw["then"])
        if 0 <= a < n and 0 <= b < n:
            p = (int(geo.ox + (snap.x[a] - geo.x0_m) * s), int(geo.oy + (snap.y[a] - geo.y0_m) * s))
            q = (int(geo.ox + (snap.x[b] - geo.x0_m) * s), int(geo.oy + (snap.y[b] - geo.y0_m) * s))
            cv2.arrowedLine(band, p, q, color, thick, _AA, 0, 0.15)


def _hud(img: np.ndarray, geo: Geometry, snap: Snapshot, style: Style, failures: int) -> None:
    tick = snap.time_s / snap.tick_s if snap.tick_s > 0 else 0.0
    parts = [f"t {snap.time_s:.1f} s", f"tick {int(math.floor(tick + 1e-9))}"]
    if snap.orders_done is not None:
        tp = snap.orders_done / tick if tick > 0 else 0.0
        parts += [f"orders {snap.orders_done}/{snap.orders_total}", f"TP {tp:.3f}/tick"]
    parts += [f"failures {failures}", f"AGVs {len(snap.x)}"]
    text = "   ".join(parts)
    th = max(1, int(round(geo.font * 1.6)))
    (_, h), _ = cv2.getTextSize(text, _FONT, geo.font, th)
    y = geo.hud_h // 2 + h // 2
    cv2.putText(img, text, (10, y), _FONT, geo.font, PALETTE["hud_text"], th, _AA)
    if style.title:
        (tw, _), _ = cv2.getTextSize(style.title, _FONT, geo.font, 1)
        cv2.putText(img, style.title, (style.size[0] - tw - 10, y), _FONT, geo.font,
                    PALETTE["hud_text"], 1, _AA)


def draw_frame(snapshot: Snapshot, style: Style | None = None) -> np.ndarray:
    """Draw ``snapshot`` as a ``(height, width, 3)`` BGR uint8 image (a new array)."""
    style = style or Style()
    geo, background = _background(snapshot.scene, style)
    img = background.copy()
    band = img[geo.top:geo.bottom]
    status = status_of(snapshot.state, snapshot.loaded)
    if snapshot.corridors:
        _corridors(band, geo, snapshot.corridors, style)
    if style.show_paths and snapshot.paths:
        _paths(band, geo, snapshot, status, style)
    if style.ghosts and snapshot.ghosts is not None:
        _ghosts(band, geo, snapshot, style)
    _agvs(band, geo, snapshot, style, status)
    if style.switches and snapshot.switches:
        _switches(band, geo, snapshot)
    if style.show_hud:
        _hud(img, geo, snapshot, style, int((status == 3).sum()))
    return img
