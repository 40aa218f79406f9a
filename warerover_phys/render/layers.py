"""The per-frame layers of :func:`~.frame.draw_frame`, each drawn in a few batched calls.

- :func:`draw_bodies`: every AGV body in one compiled pass (:func:`.raster.fill_boxes`,
  anti-aliased), then, only for bodies big enough on screen, their outlines, heading marks,
  cargo squares and failure crosses in one OpenCV call per kind, and ids;
- :func:`draw_paths`: the paths ahead, one ``polylines`` call per colour;
- :func:`draw_arrows`: a thin arrow from each AGV waiting on a dependency to its blocker
  (shafts in one call, heads in another);
- :func:`draw_ghosts`: planned poses as outlines and a line to the body when apart;
- :func:`corridor_layer`: the open corridors' zones as one mask (made again only when the
  set of zones changes) and their outlines.

Coordinates: OpenCV puts pixel ``(r, c)``'s centre at ``(c, r)``; :class:`~.frame.
Geometry` gives those coordinates; the compiled fill takes pixel corners (``+ 0.5``).
"""

from __future__ import annotations

import cv2
import numpy as np

from .raster import draw_lines, fill_boxes

__all__ = ["draw_bodies", "draw_paths", "draw_arrows", "draw_ghosts", "ink_for", "SHIFT",
           "fixed", "corridor_layer", "corridor_key"]

SHIFT = 4
"""Sub-pixel bits for OpenCV drawing (coordinates are multiplied by 16)."""
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_AA = cv2.LINE_AA
_SX = np.array([1, -1, -1, 1])[None, :, None]
_SY = np.array([1, 1, -1, -1])[None, :, None]


def fixed(px: np.ndarray) -> np.ndarray:
    """Pixel coordinates as OpenCV fixed-point integers (``SHIFT`` fractional bits), in
    C order (OpenCV refuses other layouts of a point array)."""
    return np.ascontiguousarray(np.round(px * (1 << SHIFT)), dtype=np.int32)


def ink_for(colors: np.ndarray) -> np.ndarray:
    """(N,) True where marks on a body of that BGR colour are drawn white (dark bodies)."""
    c = np.asarray(colors, dtype=np.float64)
    return (0.114 * c[..., 0] + 0.587 * c[..., 1] + 0.299 * c[..., 2]) < 140


def _corners(cx: np.ndarray, cy: np.ndarray, heading: np.ndarray,
             half: np.ndarray) -> np.ndarray:
    """(N, 4, 2) pixel corners of rotated rectangles (``half``: (N, 2) along, across)."""
    c, s = np.cos(heading), np.sin(heading)
    ux, uy = np.stack([c, s], axis=1), np.stack([-s, c], axis=1)
    centre = np.stack([cx, cy], axis=1)
    return (centre[:, None, :] + _SX * half[:, None, 0:1] * ux[:, None, :]
            + _SY * half[:, None, 1:2] * uy[:, None, :])


def draw_bodies(band: np.ndarray, cx: np.ndarray, cy: np.ndarray, heading: np.ndarray,
                half: np.ndarray, colors: np.ndarray, *, failed: np.ndarray,
                loaded: np.ndarray, detail_px: float, label_px: float,
                outline: tuple[int, int, int], cargo: tuple[int, int, int]) -> None:
    """Bodies at pixel centres ``cx``, ``cy`` with half sizes ``half`` (N, 2: along and
    across the heading) in ``colors`` (N, 3 BGR uint8), marks on those at least
    ``detail_px`` wide, ids on those at least ``label_px`` wide."""
    n = len(cx)
    if n == 0:
        return
    bh, bw = band.shape[:2]
    reach = half.max(axis=1) * 1.5
    vis = np.flatnonzero((cx + reach >= 0) & (cx - reach < bw) & (cy + reach >= 0)
                         & (cy - reach < bh))
    if len(vis) == 0:
        return
    fill_boxes(band, cx[vis] + 0.5, cy[vis] + 0.5, np.cos(heading[vis]), np.sin(heading[vis]),
               half[vis, 0], half[vis, 1], colors[vis])
    size = 2 * half[vis].min(axis=1)
    big = vis[size >= detail_px]
    if len(big) == 0:
        return
    corners = _corners(cx[big], cy[big], heading[big], half[big])
    cv2.polylines(band, fixed(corners), True, outline, 1, _AA, SHIFT)
    centre = np.stack([cx[big], cy[big]], axis=1)[:, None, :]
    white = ink_for(colors[big])
    sel = loaded[big]
    if sel.any():                           # cargo: a shelf-coloured square in the middle
        sq = fixed(corners[sel] * 0.5 + centre[sel] * 0.5)
        cv2.fillPoly(band, sq, cargo, _AA, SHIFT)
        cv2.polylines(band, sq, True, outline, 1, _AA, SHIFT)
    sel = failed[big]
    if sel.any():                           # failed: a cross corner to corner
        k = corners[sel] * 0.8 + centre[sel] * 0.2
        thick = max(1, int(round(float(np.median(size[size >= detail_px])) / 14)))
        for ink, rows in ((True, white[sel]), (False, ~white[sel])):
            if rows.any():
                seg = np.concatenate([k[rows][:, [0, 2]], k[rows][:, [1, 3]]])
                cv2.polylines(band, fixed(seg), False, (255, 255, 255) if ink else outline,
                              thick, _AA, SHIFT)
    # heading mark: a triangle towards the front
    f = (np.stack([np.cos(heading[big]), np.sin(heading[big])], axis=1)
         * half[big, 0:1])[:, None, :]
    left = (np.stack([-np.sin(heading[big]), np.cos(heading[big])], axis=1)
            * half[big, 1:2])[:, None, :]
    nose = centre + f * np.array([0.92, 0.58, 0.58])[None, :, None] \
        + left * np.array([0.0, 0.3, -0.3])[None, :, None]
    for ink in (True, False):
        rows = white == ink
        if rows.any():
            cv2.fillPoly(band, fixed(nose[rows]), (255, 255, 255) if ink else outline, _AA,
                         SHIFT)
    _labels(band, big, cx, cy, 2 * half[big].min(axis=1), white, label_px, outline)


def _labels(band: np.ndarray, ids: np.ndarray, cx: np.ndarray, cy: np.ndarray,
            size: np.ndarray, white: np.ndarray, label_px: float,
            outline: tuple[int, int, int]) -> None:
    for j in np.flatnonzero(size >= label_px).tolist():
        i = int(ids[j])
        text = str(i)
        fs = min(1.2, float(size[j]) / 60)
        th = 1 if fs < 0.7 else 2
        (tw, tht), _ = cv2.getTextSize(text, _FONT, fs, th)
        fit = 0.6 * float(size[j]) / tw    # keep clear of the heading mark
        if fit < 1:
            fs *= fit
            (tw, tht), _ = cv2.getTextSize(text, _FONT, fs, th)
        if fs < 0.28:
            continue
        cv2.putText(band, text, (int(cx[i] - tw / 2), int(cy[i] + tht / 2)), _FONT, fs,
                    (255, 255, 255) if white[j] else outline, th, _AA)


def draw_paths(band: np.ndarray, px: np.ndarray, colors: np.ndarray, thick: int,
               dots: bool) -> None:
    """Polylines ``px`` (M, K, 2 pixels) in ``colors`` (M, 3): one compiled call when one
    pixel wide, else one OpenCV call per colour; a dot at each end when ``dots``."""
    if len(px) == 0:
        return
    if thick <= 1 and not dots:
        draw_lines(band, px, colors)
        return
    pts = fixed(px)
    keys = colors.astype(np.int64) @ np.array([1, 256, 65536])
    radius = int(round(max(2.0, thick * 1.6) * (1 << SHIFT)))
    for key in np.unique(keys).tolist():
        rows = keys == key
        color = tuple(int(v) for v in colors[np.argmax(rows)])
        cv2.polylines(band, pts[rows], False, color, thick, _AA, SHIFT)
        if dots:
            for end in pts[rows, -1].tolist():
                cv2.circle(band, tuple(end), radius, color, -1, _AA, SHIFT)


def draw_arrows(band: np.ndarray, start: np.ndarray, end: np.ndarray, back: np.ndarray,
                color: tuple[int, int, int], head_px: float, alpha: float = 0.6) -> None:
    """Arrows from ``start`` to ``end`` (M, 2 pixels), stopping ``back`` (M,) pixels short
    of ``end`` (the blocker's edge); heads ``head_px`` long where the arrow is longer.
    Blended at ``alpha``: a crowd's arrows do not hide the floor."""
    if len(start) == 0:
        return
    d = end - start
    length = np.hypot(d[:, 0], d[:, 1])
    keep = length > back + 1.0
    if not keep.any():
        return
    start, d, length, back = start[keep], d[keep], length[keep], back[keep]
    u = d / length[:, None]
    tip = start + u * (length - back)[:, None]
    # Each arrow one polyline: shaft, one barb, back to the tip, the other barb (a barb
    # collapses onto the tip where the arrow is too short for a head).
    head = np.where((length - back) > 1.5 * head_px, head_px, 0.0)[:, None]
    n = np.stack([-u[:, 1], u[:, 0]], axis=1)
    base = tip - u * head
    pts = np.stack([start, tip, base + n * head * 0.5, tip, base - n * head * 0.5], axis=1)
    draw_lines(band, pts, np.broadcast_to(np.array(color, dtype=np.uint8), (len(pts), 3)),
               alpha)


def draw_ghosts(band: np.ndarray, gx: np.ndarray, gy: np.ndarray, gh: np.ndarray,
                half: np.ndarray, rx: np.ndarray, ry: np.ndarray,
                color: tuple[int, int, int]) -> None:
    """Planned poses (pixel centres ``gx``, ``gy``, headings ``gh``, half sizes ``half``)
    as outlines, each with a line to its real body (``rx``, ``ry``) when they are more than
    a quarter of the body apart."""
    if len(gx) == 0:
        return
    thick = max(2, int(round(float(half.min()) * 0.2)))
    cv2.polylines(band, fixed(_corners(gx, gy, gh, half)), True, color, thick, _AA, SHIFT)
    apart = np.hypot(rx - gx, ry - gy) > half.min(axis=1) / 2
    if apart.any():
        seg = np.stack([np.stack([gx, gy], axis=1), np.stack([rx, ry], axis=1)], axis=1)[apart]
        cv2.polylines(band, fixed(seg), False, color, max(1, thick // 2), _AA, SHIFT)


def _apart(points: np.ndarray, starts: np.ndarray) -> list[list[int]]:
    """The rings (``points`` from each of ``starts`` to the next) in groups whose bounding
    boxes do not touch: OpenCV fills several polygons in one call by the even-odd rule, so
    an overlap of two in the same call would stay empty (greedy colouring of the overlap
    graph; a handful of groups even for hundreds of corridors)."""
    lo, hi = np.minimum.reduceat(points, starts), np.maximum.reduceat(points, starts)
    touch = ((lo[:, None, :] <= hi[None, :, :]) & (lo[None, :, :] <= hi[:, None, :])).all(axis=2)
    group = np.full(len(starts), -1)
    for j in range(len(starts)):
        used = set(group[touch[j]].tolist())
        g = 0
        while g in used:
            g += 1
        group[j] = g
    return [np.flatnonzero(group == g).tolist() for g in range(int(group.max()) + 1)]


def corridor_key(rings: list[np.ndarray]) -> int:
    """A key of a set of corridor rings (metres): equal sets, equal keys."""
    return hash((np.vstack(rings).tobytes(), tuple(len(r) for r in rings)))


def corridor_layer(shape: tuple[int, ...], pts: np.ndarray, lengths: list[int],
                   thick: int) -> tuple | None:
    """Corridor rings (``pts``: every ring's points in band pixels, one after another,
    ``lengths`` of each) in a band of ``shape`` as ``(y0, y1, x0, x1, mask, outlines)``:
    their bounding box, the filled mask over it and the outlines (``thick`` > 1: fixed-point
    rings in the box for OpenCV; else rings closed and padded to one length, in band
    pixels, for :func:`.raster.draw_lines`). None when they are off the band."""
    bh, bw = shape[:2]
    x0, y0 = np.maximum(np.floor(pts.min(axis=0)).astype(int) - 2, 0)
    x1, y1 = np.ceil(pts.max(axis=0)).astype(int) + 2
    x1, y1 = min(x1, bw), min(y1, bh)
    if x1 <= x0 or y1 <= y0:
        return None
    starts = np.cumsum([0] + list(lengths))[:-1]
    local = np.split(fixed(pts - (x0, y0)), starts[1:])
    mask = np.zeros((y1 - y0, x1 - x0), dtype=np.uint8)
    for group in _apart(pts, starts):
        cv2.fillPoly(mask, [local[j] for j in group], 255, cv2.LINE_8, SHIFT)
    if thick > 1:
        return y0, y1, x0, x1, mask, local
    outlines = np.empty((len(lengths), max(lengths) + 1, 2))
    for j, (s0, n) in enumerate(zip(starts.tolist(), lengths, strict=True)):
        outlines[j, :n] = pts[s0:s0 + n]
        outlines[j, n:] = pts[s0]
    return y0, y1, x0, x1, mask, outlines
