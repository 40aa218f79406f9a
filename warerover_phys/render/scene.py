"""What a frame is drawn from and with: the Okabe-Ito palette, the AGV status colours, the
static :class:`Scene`, one :class:`Snapshot` of it, the :class:`Style` and the frame's
:class:`Geometry`."""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ..executors.recording import EXEC_STATES
from .plans import PathSet, PlanProgress


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
    # what an AGV is doing (the recording's exec_state)
    "standing": OKABE_ITO["black"],
    "driving": OKABE_ITO["blue"],
    "turning": OKABE_ITO["sky"],
    "waiting": OKABE_ITO["orange"],
    "delayed": OKABE_ITO["purple"],
    "finished": (190, 190, 190),
    "working": _bgr("B89B00"),
    "arrow": _bgr("8C3C14"),
    "switch": _bgr("C2007A"),      # a switched edge of the dependency graph (magenta)
    "outline": (30, 30, 30),
    "hud_bg": (38, 38, 38),
    "hud_text": (245, 245, 245),
    "legend_bg": (238, 238, 238),
    "legend_text": (20, 20, 20),
}
"""Colours (BGR) by role; cells use ``floor``/``obstacle``/``shelf``/``station``/``parking``,
AGVs what they are doing (``EXEC_STATES``: ``driving``, ``turning``, ``waiting``,
``delayed``, ``failed``, ``finished``, ``working``, ``standing``; finished ones fade into the
floor so the busy ones stand out) or, in recordings without it, their status (``idle``,
``moving``, ``loaded``, ``failed``); ``arrow`` points from a waiting AGV to its blocker."""

STATUS_NAMES = ("idle", "moving", "loaded", "failed")
_STATUS_BGR = np.array([PALETTE[s] for s in STATUS_NAMES], dtype=np.uint8)
_EXEC_BGR = np.array([PALETTE[s] for s in EXEC_STATES], dtype=np.uint8)
EXEC_LABELS = {"standing": "standing", "driving": "driving", "turning": "turning",
               "waiting": "waiting on another AGV", "delayed": "injected delay",
               "failed": "failed", "finished": "finished", "working": "working in place"}
"""Legend text of each ``exec_state``."""
_CELL_BGR = np.array([PALETTE["floor"], PALETTE["obstacle"], PALETTE["shelf"],
                      PALETTE["station"], PALETTE["parking"]], dtype=np.uint8)
"""Indexed by ``CellType`` (FLOOR, OBSTACLE, SHELF, STATION, PARKING)."""
_CELL_NAMES = ("floor", "obstacle", "shelf", "station", "parking")
FAILED_STATE = 7
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_AA = cv2.LINE_AA


def status_of(state: np.ndarray, loaded: np.ndarray) -> np.ndarray:
    """Status index per AGV: 0 idle, 1 moving (working, no cargo), 2 loaded, 3 failed."""
    state = np.asarray(state)
    out = np.where(np.asarray(loaded, dtype=bool), 2, np.where(state == 0, 0, 1))
    return np.where(state == FAILED_STATE, 3, out)


@dataclass(frozen=True, eq=False)
class Scene:
    """What stays the same in every frame: the layout, the fleet's bodies and what the
    legend lists."""

    grid: np.ndarray
    """``(rows, cols)`` ``CellType`` codes."""
    cell_m: float
    body_m: np.ndarray
    """``(N, 2)`` body length (along the heading) and width, metres."""
    footprint: np.ndarray
    states: tuple[int, ...] | None = None
    """The ``exec_state`` codes the legend lists (those the recording has); None: the
    recording has none, AGVs are coloured by task status."""
    corridors: bool = True
    """The legend lists the safety corridor."""
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
    paths: PathSet | list[np.ndarray | None] | None = None
    """The path ahead of each AGV: a :class:`~.plans.PathSet`, or per AGV ``(K, 2)`` points
    (metres) or None."""
    ghosts: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    """Per AGV, the planned pose ``(x, y, heading)`` at this time (metres, radians; NaN:
    none), drawn as an outlined ghost when ``Style.ghosts`` is on."""
    exec_state: np.ndarray | None = None
    """What each AGV is doing (``EXEC_STATES`` codes); None: colour by task status."""
    blocker: np.ndarray | None = None
    """The AGV each waiting AGV waits for (-1: none)."""
    progress: PlanProgress | None = None
    """A plan execution's figures for the heads-up line (None: not a plan execution)."""
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
    arrows: bool = True
    """Draw an arrow from each AGV waiting on a dependency to its blocker."""
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
    map_w: int = 0
    map_h: int = 0
    """Size of the map's rectangle (pixels) at ``ox``, ``oy`` in the band; what is drawn
    outside it (AGVs beyond a viewport) is wiped."""

    def to_px(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Frame pixel coordinates (float) of world points."""
        return (self.ox + (np.asarray(x) - self.x0_m) * self.scale,
                self.top + self.oy + (np.asarray(y) - self.y0_m) * self.scale)
