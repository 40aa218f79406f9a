"""Still pictures of a whole recording: where AGVs waited, and where they passed.

:func:`heat_values` sums, per cell over the episode, either the seconds AGVs spent there
waiting (``wait``: samples whose ``exec_state`` is *waiting on a dependency*; recordings
without it count an AGV standing still, not idle and not failed, as waiting) or the number of
times an AGV entered it (``traffic``: each change of the cell under a body's centre is one
pass; every AGV's first cell counts once). :func:`draw_heat` paints those values on the
floor with the ``viridis`` colour map (readable with the common colour-vision deficiencies),
on a square-root scale so that a few very busy cells do not wash the rest out, with a colour
bar and the total in the heads-up line.

The sums run over the recording in blocks of samples, so a long recording streamed to disk
(memory maps) is read once and never whole.

>>> import numpy as np
>>> from warerover_phys.render import Recording
>>> t = np.arange(4, dtype=float)
>>> rec = Recording(t=t, x=np.array([[0.5], [1.5], [1.5], [1.5]]), y=np.full((4, 1), 0.5),
...                 heading=np.zeros((4, 1)), state=np.ones((4, 1), np.int8),
...                 loaded=np.zeros((4, 1), bool), footprint=np.array([1]),
...                 body_m=np.array([[0.7, 0.7]]), cell_m=1.0, tick_s=1.0,
...                 grid=np.zeros((1, 3), np.int8),
...                 exec_state=np.array([[1], [3], [3], [6]], np.int8),
...                 blocker=np.full((4, 1), -1, np.int32), plan_tick=np.zeros((4, 1), np.int32))
>>> heat_values(rec, "traffic").tolist(), heat_values(rec, "wait").tolist()
([[1.0, 1.0, 0.0]], [[0.0, 2.0, 0.0]])
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import cv2
import numpy as np

from ..executors.recording import WAITING
from .frame import PALETTE, Style, _background

if TYPE_CHECKING:
    from .trajectory import Recording

__all__ = ["HEAT_KINDS", "heat_values", "draw_heat"]

HEAT_KINDS = {"wait": "seconds waited per cell", "traffic": "passes per cell"}
BLOCK = 2048
"""Samples read at a time."""
STILL_MPS = 0.05
"""Recordings without ``exec_state``: an AGV slower than this (m/s) stands."""


def _cells(rec: Recording, lo: int, hi: int) -> np.ndarray:
    """(hi - lo, N) flat cell under each body's centre (-1 off the floor)."""
    rows, cols = rec.grid.shape
    r = np.floor(np.asarray(rec.y[lo:hi]) / rec.cell_m).astype(np.int64)
    c = np.floor(np.asarray(rec.x[lo:hi]) / rec.cell_m).astype(np.int64)
    inside = (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
    return np.where(inside, r * cols + c, -1)


def heat_values(rec: Recording, kind: str) -> np.ndarray:
    """(rows, cols) per-cell totals of ``kind`` (``wait``: seconds, ``traffic``: passes)."""
    if kind not in HEAT_KINDS:
        raise ValueError(f"heat must be one of {', '.join(HEAT_KINDS)} (got {kind!r})")
    rows, cols = rec.grid.shape
    total = np.zeros(rows * cols + 1)
    t = np.asarray(rec.t, dtype=np.float64)
    dt = np.diff(t, append=t[-1]) if len(t) else t     # a sample lasts until the next
    prev = None
    for lo in range(0, len(t), BLOCK):
        hi = min(lo + BLOCK, len(t))
        cells = _cells(rec, lo, hi)
        if kind == "traffic":
            before = np.concatenate([prev[None] if prev is not None else
                                     np.full((1, cells.shape[1]), -2), cells[:-1]])
            entered = (cells != before) & (cells >= 0)
            np.add.at(total, cells[entered], 1.0)
            prev = cells[-1]
            continue
        if rec.exec_state is not None:
            waiting = np.asarray(rec.exec_state[lo:hi]) == WAITING
        else:
            nxt = min(hi + 1, len(t))
            x, y = np.asarray(rec.x[lo:nxt]), np.asarray(rec.y[lo:nxt])
            step = np.hypot(np.diff(x, axis=0, append=x[-1:]), np.diff(y, axis=0, append=y[-1:]))
            span = np.maximum(dt[lo:nxt], 1e-9)[:, None]
            state = np.asarray(rec.state[lo:nxt])
            waiting = ((step / span < STILL_MPS) & (state != 0) & (state != 7))[:hi - lo]
        w = np.where(waiting & (cells >= 0), dt[lo:hi, None], 0.0)
        np.add.at(total, np.where(cells >= 0, cells, rows * cols), w)
    return total[:-1].reshape(rows, cols)


def _colour_bar(img: np.ndarray, geo, style: Style, vmax: float, label: str) -> None:
    """A viridis bar with its end values and ``label`` in the legend band."""
    w = style.size[0]
    img[geo.bottom:] = PALETTE["legend_bg"]
    h = max(6, geo.legend_h // 3)
    x0, x1 = 10, w // 2
    y0 = geo.bottom + (geo.legend_h - h) // 2
    ramp = cv2.applyColorMap(np.linspace(0, 255, x1 - x0).astype(np.uint8)[None, :],
                             cv2.COLORMAP_VIRIDIS)
    img[y0:y0 + h, x0:x1] = ramp
    font = geo.font * 0.85
    ink = PALETTE["legend_text"]
    yt = y0 + h
    cv2.putText(img, "0", (x0, y0 - 2), cv2.FONT_HERSHEY_SIMPLEX, font * 0.8, ink, 1,
                cv2.LINE_AA)
    top = f"{vmax:,.0f}" if vmax >= 10 else f"{vmax:.2g}"
    tw = cv2.getTextSize(top, cv2.FONT_HERSHEY_SIMPLEX, font * 0.8, 1)[0][0]
    cv2.putText(img, top, (x1 - tw, y0 - 2), cv2.FONT_HERSHEY_SIMPLEX, font * 0.8, ink, 1,
                cv2.LINE_AA)
    cv2.putText(img, f"{label} (square-root scale)", (x1 + 14, yt),
                cv2.FONT_HERSHEY_SIMPLEX, font, ink, 1, cv2.LINE_AA)


def draw_heat(rec: Recording, kind: str, style: Style | None = None,
              values: np.ndarray | None = None) -> np.ndarray:
    """The floor with ``kind``'s per-cell totals (:func:`heat_values`, or ``values``) as a
    BGR image of ``style.size``: cells with nothing stay as the floor draws them."""
    style = dataclasses.replace(style or Style(), show_legend=True)
    values = heat_values(rec, kind) if values is None else values
    scene = rec.scene()
    geo, background = _background(scene, style)
    img = background.copy()
    band = img[geo.top:geo.bottom]
    r0, c0, r1, c1 = style.viewport or (0, 0, *(s - 1 for s in rec.grid.shape))
    r1, c1 = min(r1, rec.grid.shape[0] - 1), min(c1, rec.grid.shape[1] - 1)
    part = values[r0:r1 + 1, c0:c1 + 1]
    vmax = float(values.max(initial=0.0))
    if vmax > 0:
        level = np.sqrt(part / vmax)
        small = cv2.applyColorMap((level * 255).round().astype(np.uint8), cv2.COLORMAP_VIRIDIS)
        mw = int(round(part.shape[1] * rec.cell_m * geo.scale))
        mh = int(round(part.shape[0] * rec.cell_m * geo.scale))
        big = cv2.resize(small, (max(mw, 1), max(mh, 1)), interpolation=cv2.INTER_NEAREST)
        mask = cv2.resize((part > 0).astype(np.uint8), (max(mw, 1), max(mh, 1)),
                          interpolation=cv2.INTER_NEAREST)
        ox, oy = int(geo.ox), int(geo.oy)
        h, w = min(mh, band.shape[0] - oy), min(mw, band.shape[1] - ox)
        cv2.copyTo(big[:h, :w], mask[:h, :w], band[oy:oy + h, ox:ox + w])
    _colour_bar(img, geo, style, vmax, HEAT_KINDS[kind])
    if style.show_hud:
        unit = "AGV-s waited" if kind == "wait" else "passes"
        text = (f"{HEAT_KINDS[kind]} over {rec.end_s - rec.start_s:.0f} s, {rec.num_agvs} "
                f"AGVs: {values.sum():,.0f} {unit}, busiest cell {vmax:,.0f}")
        (_, th), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, geo.font, 1)
        cv2.putText(img, text, (10, geo.hud_h // 2 + th // 2), cv2.FONT_HERSHEY_SIMPLEX,
                    geo.font, PALETTE["hud_text"], 1, cv2.LINE_AA)
        if style.title:
            (tw, _), _ = cv2.getTextSize(style.title, cv2.FONT_HERSHEY_SIMPLEX, geo.font, 1)
            cv2.putText(img, style.title, (style.size[0] - tw - 10, geo.hud_h // 2 + th // 2),
                        cv2.FONT_HERSHEY_SIMPLEX, geo.font, PALETTE["hud_text"], 1,
                        cv2.LINE_AA)
    return img
