"""One frame of an episode: a pure function from a state snapshot to a BGR image.

:func:`draw_frame` draws, in this order: the floor (cell types: shelves, stations, parking,
obstacles; grid lines when cells are big enough; drawn once per style and copied), the open
safety corridors (translucent zone and outline), the path still ahead of each AGV from its
own progress in its plan (optional), each AGV's planned pose as an outlined ghost (optional,
``Style.ghosts``), the AGVs as rotated rectangles of their true size coloured by what they
are doing (the recording's ``exec_state``: driving, turning, waiting on a dependency,
held by an injected delay, failed, finished, working, standing; recordings without it: by
task status, idle / moving / loaded / failed) with a heading mark, a cargo marker, a cross
when failed and the id, a thin arrow from each AGV waiting on a dependency to its blocker,
then a heads-up line and a legend. The heads-up line of a plan execution gives the time,
AGVs finished / total, planned vs executed makespan so far and the AGV-seconds lost so far;
a run with orders gives orders done / total and throughput. Colours are the Okabe-Ito
palette (distinct for the common colour-vision deficiencies); failure and cargo are also
shown by shape (cross, square), so they do not rest on colour alone. The per-frame layers
are drawn in batches (:mod:`.layers`, bodies in one compiled pass: :mod:`.raster`).

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

import cv2
import numpy as np

from ..executors.recording import EXEC_STATES, FAILED, WAITING
from .layers import (
    SHIFT,
    corridor_key,
    corridor_layer,
    draw_arrows,
    draw_bodies,
    draw_ghosts,
    draw_paths,
)
from .plans import PathSet
from .raster import draw_lines
from .scene import (  # noqa: F401
    _AA,
    _CELL_BGR,
    _CELL_NAMES,
    _EXEC_BGR,
    _FONT,
    _STATUS_BGR,
    EXEC_LABELS,
    FAILED_STATE,
    OKABE_ITO,
    PALETTE,
    STATUS_NAMES,
    Geometry,
    Scene,
    Snapshot,
    Style,
    _bgr,
    _tint,
    status_of,
)

__all__ = ["Scene", "Snapshot", "Style", "draw_frame", "PALETTE", "status_of", "Geometry",
           "frame_geometry", "EXEC_LABELS"]


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
                     top=hud_h, bottom=h - legend_h, font=font, hud_h=hud_h, legend_h=legend_h,
                     map_w=int(round(vw * scale)), map_h=int(round(vh * scale))),
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
        _legend(img, geo, scene, style)
    scene._cache[style] = (geo, img)
    return geo, img


def _legend_items(scene: Scene, style: Style) -> list[tuple[str, str]]:
    if scene.states is None:
        items = [(s, s) for s in STATUS_NAMES]
    else:
        items = [(EXEC_STATES[c], EXEC_LABELS[EXEC_STATES[c]]) for c in scene.states]
        if style.arrows and WAITING in scene.states:
            items.append(("arrow", "to blocker"))
    present = set(np.unique(scene.grid).tolist())
    items += [(name, name) for code, name in enumerate(_CELL_NAMES) if code and code in present]
    if scene.corridors:
        items.append(("corridor", "safety corridor"))
    if style.show_paths:
        items.append(("path", "path ahead"))
    if style.ghosts:
        items.append(("ghost", "planned pose (ghost)"))
    if style.switches:
        items.append(("switch", "switched edge (first -> then)"))
    return items


def _legend(img: np.ndarray, geo: Geometry, scene: Scene, style: Style) -> None:
    items = _legend_items(scene, style)
    w = style.size[0]
    font = geo.font * 0.9
    for _ in range(8):
        box = int(round(geo.legend_h * 0.5))
        widths = [box + 6 + cv2.getTextSize(t, _FONT, font, 1)[0][0] + 14 for _, t in items]
        if sum(widths) <= w - 16 or font < 0.3:
            break
        font *= 0.88
    x = 8
    yc = geo.bottom + geo.legend_h // 2
    for (key, text), width in zip(items, widths, strict=True):
        _legend_mark(img, key, x, yc, box, style)
        th = cv2.getTextSize(text, _FONT, font, 1)[0][1]
        cv2.putText(img, text, (x + box + 6, yc + th // 2), _FONT, font, PALETTE["legend_text"],
                    1, _AA)
        x += width


def _legend_mark(img: np.ndarray, key: str, x: int, yc: int, box: int, style: Style) -> None:
    y0 = yc - box // 2
    if key == "path":
        cv2.line(img, (x, yc), (x + box, yc), PALETTE["driving"], 2, _AA)
    elif key == "arrow":
        cv2.arrowedLine(img, (x, yc), (x + box, yc), PALETTE["arrow"], 1, _AA, 0, 0.4)
    elif key == "ghost":
        cv2.rectangle(img, (x + 1, y0 + 1), (x + box - 1, y0 + box - 1), PALETTE["ghost"], 2)
    elif key == "switch":
        cv2.arrowedLine(img, (x, y0 + box - 1), (x + box, y0 + 1), PALETTE["switch"], 2, _AA,
                        0, 0.4)
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


def _blend(under: tuple[int, int, int], over: tuple[int, int, int],
           alpha: float) -> tuple[int, int, int]:
    return tuple(int(round(u * (1 - alpha) + o * alpha)) for u, o in zip(under, over, strict=True))  # type: ignore[return-value]


def _tinted(scene: Scene, style: Style, band: np.ndarray) -> np.ndarray:
    """The floor band as seen through a corridor (the corridor colour blended over it at
    ``corridor_alpha``), made once per style."""
    key = ("tint", style)
    hit = scene._cache.get(key)
    if hit is None:
        solid = np.empty_like(band)
        solid[:] = PALETTE["corridor"]
        hit = scene._cache[key] = cv2.addWeighted(band, 1 - style.corridor_alpha, solid,
                                                  style.corridor_alpha, 0)
    return hit


def _corridors(band: np.ndarray, geo: Geometry, snap: Snapshot, style: Style) -> None:
    """Every open corridor's zone: the tinted floor copied through the zones' mask and the
    outlines drawn in one call. Corridors are the first layer over the floor."""
    rings = [np.asarray(r, dtype=np.float64) for c in snap.corridors
             for r in (c.get("zone") or c.get("polygon") or []) if len(r) >= 3]
    if not rings:
        return
    cache, digest = snap.scene._cache, corridor_key(rings)
    hit = cache.get(("corridors", style))
    if hit is None or hit[0] != digest:      # corridors stay open for many frames
        pts = np.vstack(rings)
        pts = np.stack(_to_band(geo, pts[:, 0], pts[:, 1]), axis=1)
        hit = cache[("corridors", style)] = (digest, corridor_layer(
            band.shape, pts, [len(r) for r in rings], max(1, int(round(geo.scale * 0.06)))))
    layer = hit[1]
    if layer is None:
        return
    y0, y1, x0, x1, mask, outlines = layer
    roi = band[y0:y1, x0:x1]
    cv2.copyTo(_tinted(snap.scene, style, band)[y0:y1, x0:x1], mask, roi)
    if isinstance(outlines, list):
        cv2.polylines(roi, outlines, True, PALETTE["corridor"],
                      max(1, int(round(geo.scale * 0.06))), _AA, SHIFT)
    else:
        draw_lines(band, outlines, np.broadcast_to(np.array(PALETTE["corridor"], np.uint8),
                                                   (len(outlines), 3)))


def _colors(snap: Snapshot) -> tuple[np.ndarray, np.ndarray]:
    """Each AGV's body colour (N, 3 BGR) and whether it is failed."""
    if snap.exec_state is not None:
        code = np.clip(np.asarray(snap.exec_state, dtype=np.int64), 0, len(EXEC_STATES) - 1)
        return _EXEC_BGR[code], code == FAILED
    status = status_of(snap.state, snap.loaded)
    return _STATUS_BGR[status], status == 3


def _path_layer(band: np.ndarray, geo: Geometry, snap: Snapshot, colors: np.ndarray,
                failed: np.ndarray, style: Style) -> None:
    paths = snap.paths
    if paths is None:
        return
    if not isinstance(paths, PathSet):     # per AGV (K, 2) arrays or None
        rows = [(i, np.asarray(p, dtype=np.float64)) for i, p in enumerate(paths)
                if p is not None and len(p) >= 2]
        width = max((len(p) for _, p in rows), default=0)
        pts = np.array([np.concatenate([p, np.repeat(p[-1:], width - len(p), axis=0)])
                        for _, p in rows]).reshape(-1, max(width, 2), 2)
        paths = PathSet(np.array([i for i, _ in rows], dtype=np.int64), pts)
    keep = ~failed[paths.agv]
    agv, pts = paths.agv[keep], paths.points[keep]
    if len(agv) == 0:
        return
    px = np.empty_like(pts)
    px[..., 0], px[..., 1] = _to_band(geo, pts[..., 0], pts[..., 1])
    thick = max(1, int(round(geo.scale * 0.07)))
    dots = geo.scale * _min_body(snap.scene) >= style.detail_min_px
    draw_paths(band, px, colors[agv], thick, dots)


def _min_body(scene: Scene) -> float:
    """The smallest body side in the fleet (metres)."""
    cache = scene._cache
    if "min_body" not in cache:
        cache["min_body"] = float(scene.body_m.min()) if len(scene.body_m) else 0.0
    return cache["min_body"]


def _to_band(geo: Geometry, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates inside the map band (frame y minus the heads-up line)."""
    return (geo.ox + (np.asarray(x) - geo.x0_m) * geo.scale,
            geo.oy + (np.asarray(y) - geo.y0_m) * geo.scale)


def _half_px(scene: Scene, geo: Geometry, style: Style) -> np.ndarray:
    """(N, 2) half body sizes on screen (pixels), at least ``min_agv_px`` wide."""
    key = ("half", geo.scale, style.min_agv_px)
    hit = scene._cache.get(key)
    if hit is None:
        hit = scene._cache[key] = np.maximum(scene.body_m * geo.scale, style.min_agv_px) / 2
    return hit


def _arrow_layer(band: np.ndarray, geo: Geometry, snap: Snapshot, cx: np.ndarray,
                 cy: np.ndarray, half: np.ndarray) -> None:
    b = np.asarray(snap.blocker)
    n = len(cx)
    who = np.flatnonzero((b >= 0) & (b < n) & (b != np.arange(n)))
    if len(who) == 0:
        return
    to = b[who]
    start = np.stack([cx[who], cy[who]], axis=1)
    end = np.stack([cx[to], cy[to]], axis=1)
    head = max(3.0, 0.3 * geo.scale * snap.scene.cell_m)
    draw_arrows(band, start, end, half[to].max(axis=1), PALETTE["arrow"], head)


def _wipe_margins(band: np.ndarray, floor: np.ndarray, geo: Geometry) -> None:
    """Put the floor image back outside the map's rectangle (and its outline)."""
    x0, y0 = max(int(geo.ox) - 1, 0), max(int(geo.oy) - 1, 0)
    x1, y1 = int(geo.ox) + geo.map_w + 1, int(geo.oy) + geo.map_h + 1
    band[:y0] = floor[:y0]
    band[y1:] = floor[y1:]
    band[y0:y1, :x0] = floor[y0:y1, :x0]
    band[y0:y1, x1:] = floor[y0:y1, x1:]


def _hud_text(snap: Snapshot, failures: int) -> str:
    tick = snap.time_s / snap.tick_s if snap.tick_s > 0 else 0.0
    parts = [f"t {snap.time_s:.1f} s"]
    p = snap.progress
    if p is not None:
        ex = f"{p.executed_makespan_s:.0f} s" + (
            f" ({p.executed_makespan_s / p.planned_makespan_s:.2f}x)"
            if p.done and p.planned_makespan_s > 0 else "+")
        parts += [f"finished {p.finished}/{p.agvs}",
                  f"makespan planned {p.planned_makespan_s:.0f} s, executed {ex}",
                  f"lost {p.lost_s:,.0f} AGV-s"]
    else:
        parts.append(f"tick {int(math.floor(tick + 1e-9))}")
        if snap.orders_total:
            tp = (snap.orders_done or 0) / tick if tick > 0 else 0.0
            parts += [f"orders {snap.orders_done}/{snap.orders_total}", f"TP {tp:.3f}/tick"]
    if snap.exec_state is not None:
        counts = np.bincount(np.clip(np.asarray(snap.exec_state, dtype=np.int64), 0,
                                     len(EXEC_STATES) - 1), minlength=len(EXEC_STATES))
        parts.append(f"waiting {counts[WAITING]}")
    parts += [f"failures {failures}", f"AGVs {len(snap.x)}"]
    return "   ".join(parts)


def _switches(band: np.ndarray, geo: Geometry, snap: Snapshot, cx: np.ndarray,
              cy: np.ndarray) -> None:
    """Switched edges: each cell outlined, an arrow from the AGV passing first to the AGV
    passing after it."""
    cell_m = snap.scene.cell_m
    cell_px = cell_m * geo.scale
    color = PALETTE["switch"]
    thick = max(1, int(round(cell_px * 0.06)))
    n = len(cx)
    for sw in snap.switches:
        for r, c in sw["cells"]:
            x0, y0 = _to_band(geo, c * cell_m, r * cell_m)
            cv2.rectangle(band, (int(x0), int(y0)), (int(x0 + cell_px), int(y0 + cell_px)),
                          color, thick, _AA)
        a, b = int(sw["first"]), int(sw["then"])
        if 0 <= a < n and 0 <= b < n:
            cv2.arrowedLine(band, (int(cx[a]), int(cy[a])), (int(cx[b]), int(cy[b])), color,
                            thick, _AA, 0, 0.15)


def _hud(img: np.ndarray, geo: Geometry, snap: Snapshot, style: Style, failures: int) -> None:
    text = _hud_text(snap, failures)
    font = geo.font
    th = max(1, int(round(font * 1.6)))
    room = style.size[0] - 20 - (cv2.getTextSize(style.title, _FONT, font, 1)[0][0] + 20
                                 if style.title else 0)
    (tw, h), _ = cv2.getTextSize(text, _FONT, font, th)
    if tw > room:                        # shrink to fit rather than run off the frame
        font *= max(0.5, room / tw)
        (tw, h), _ = cv2.getTextSize(text, _FONT, font, th)
    y = geo.hud_h // 2 + h // 2
    cv2.putText(img, text, (10, y), _FONT, font, PALETTE["hud_text"], th, _AA)
    if style.title:
        (tw, _), _ = cv2.getTextSize(style.title, _FONT, geo.font, 1)
        cv2.putText(img, style.title, (style.size[0] - tw - 10, y), _FONT, geo.font,
                    PALETTE["hud_text"], 1, _AA)


def draw_frame(snapshot: Snapshot, style: Style | None = None) -> np.ndarray:
    """Draw ``snapshot`` as a ``(height, width, 3)`` BGR uint8 image (a new array)."""
    style = style or Style()
    scene = snapshot.scene
    geo, background = _background(scene, style)
    img = background.copy()
    band = img[geo.top:geo.bottom]
    colors, failed = _colors(snapshot)
    if snapshot.corridors:
        _corridors(band, geo, snapshot, style)
    if style.show_paths and snapshot.paths is not None:
        _path_layer(band, geo, snapshot, colors, failed, style)
    cx, cy = _to_band(geo, snapshot.x, snapshot.y)
    half = _half_px(scene, geo, style)
    if style.ghosts and snapshot.ghosts is not None:
        gx, gy, gh = (np.asarray(a, dtype=np.float64) for a in snapshot.ghosts)
        keep = np.flatnonzero(np.isfinite(gx) & np.isfinite(gy) & np.isfinite(gh))
        gpx, gpy = _to_band(geo, gx[keep], gy[keep])
        draw_ghosts(band, gpx, gpy, gh[keep], half[keep], cx[keep], cy[keep], PALETTE["ghost"])
    draw_bodies(band, cx, cy, np.asarray(snapshot.heading, dtype=np.float64), half, colors,
                failed=failed, loaded=np.asarray(snapshot.loaded, dtype=bool),
                detail_px=style.detail_min_px, label_px=style.label_min_px,
                outline=PALETTE["outline"], cargo=PALETTE["shelf"])
    if style.arrows and snapshot.blocker is not None:
        _arrow_layer(band, geo, snapshot, cx, cy, half)
    if style.switches and snapshot.switches:
        _switches(band, geo, snapshot, cx, cy)
    _wipe_margins(band, background[geo.top:geo.bottom], geo)
    if style.show_hud:
        _hud(img, geo, snapshot, style, int(failed.sum()))
    return img
