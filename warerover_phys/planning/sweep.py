"""Turning sweeps: the cells a differential-drive AGV must hold while it turns in place.

A rectangular body of length ``l`` and width ``w`` turning about its centre covers the disc
of radius ``r = hypot(l, w) / 2`` (its *swept disc*). The default 0.7 m bodies on 1 m cells
have ``r = 0.495 m`` and never leave their cell; an 0.8 m body (``r = 0.566 m``) reaches
into the neighbouring cells, and so does a 1.6 m body on a 2 x 2 footprint (``r = 1.13 m``).

:func:`sweep_offsets` gives, per AGV type, the cells around its footprint (offsets from its
anchor) that a turn must hold exclusively, so that no other AGV's body can be in the disc
while it turns. A neighbour cell ``n`` is included only if the disc can reach a body that
holds ``n`` (the *occupants' own extents* are taken into account):

- a body standing or driving straight (axis-aligned, between two anchors of its footprint):
  ``n`` is included if the disc overlaps the part of that body's rectangle (or of the
  rectangle it sweeps while driving one cell) that lies in ``n``'s square. Every point of
  such a body lies in one of the cells it holds, so one of those cells is held by the turn;
- a differential-drive body that may itself turn at anchor ``a``: if the two discs overlap,
  the two turns must not happen at once. That is no cell: a body standing still at ``a`` is
  not hit. :func:`turn_locks` gives these anchors; a turn *locks* its own anchor and each of
  them (two overlapping turns then share a lock and are ordered), nothing else waits on a
  lock.

Placements that would overlap the turner's own footprint are ignored (the turner holds those
cells). Touching is not overlapping: with 0.7 m bodies on 1 m cells two neighbours turning at
once keep 1 cm apart and nothing is reserved.

The reservation can express the *ring*: cells at most one cell away from the footprint
(Chebyshev distance). :func:`sweep_offsets` raises :class:`SweepError` if a fleet needs more
(:func:`check_fleet_sweeps` words that for ``warerover check``).

:func:`turn_sweeps` finds the turns of a timed path (a move whose direction differs from the
AGV's previous move), :func:`sweep_conflicts` checks a whole plan against them (the
independent validator's sweep check).

>>> small = BodyShape(k=1, length_m=0.8, width_m=0.8, turns=True)
>>> sweep_offsets(small, (small,), 1.0)  # a neighbour standing aligned is not reached
()
>>> turn_locks(small, (small,), 1.0)  # but two neighbours turning at once collide
((-1, 0), (0, -1), (0, 0), (0, 1), (1, 0))
>>> default = BodyShape(k=1, length_m=0.7, width_m=0.7, turns=True)
>>> sweep_offsets(default, (default,), 1.0)
()
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import numpy as np

__all__ = ["turn_locks", "BodyShape", "SweepError", "disc_overlaps_rect", "discs_overlap", "sweep_offsets",
           "fleet_sweeps", "agv_sweeps", "Sweep", "check_fleet_sweeps", "static_sweep_hits", "turn_sweeps", "sweep_cells",
           "sweep_conflicts", "SweepConflict", "EAST"]

EAST = (0, 1)
"""``(drow, dcol)`` an AGV faces when it is placed (heading 0 = +x)."""
_EPS = 1e-9


class SweepError(ValueError):
    """A fleet whose turning sweeps the reservation cannot express."""


@dataclass(frozen=True, slots=True)
class BodyShape:
    """What the sweep geometry needs about one AGV type."""

    k: int
    """Footprint side (cells)."""
    length_m: float
    width_m: float
    turns: bool
    """Differential drive (turns in place); omnidirectional AGVs never turn."""

    @property
    def radius_m(self) -> float:
        """Half-diagonal: the radius of the disc swept by a turn in place."""
        return math.hypot(self.length_m, self.width_m) / 2

    @classmethod
    def of(cls, spec) -> BodyShape:
        """From an :class:`~warerover_phys.config.AgvTypeSpec`."""
        return cls(int(spec.footprint), float(spec.body_m[0]), float(spec.body_m[1]),
                   spec.drive == "diff")


def disc_overlaps_rect(cx: float, cy: float, r: float, x0: float, y0: float, x1: float,
                       y1: float) -> bool:
    """Whether the open disc (centre, radius) and the rectangle ``[x0, x1] x [y0, y1]``
    share a point (touching does not count)."""
    if x1 < x0 or y1 < y0:
        return False
    dx = max(x0 - cx, 0.0, cx - x1)
    dy = max(y0 - cy, 0.0, cy - y1)
    return dx * dx + dy * dy < (r - _EPS) ** 2 if r > _EPS else False


def discs_overlap(ax: float, ay: float, ar: float, bx: float, by: float, br: float) -> bool:
    """Whether two open discs share a point (touching does not count)."""
    return math.hypot(ax - bx, ay - by) < ar + br - _EPS


def _fp(r: int, c: int, k: int) -> Iterator[tuple[int, int]]:
    for i in range(k):
        for j in range(k):
            yield (r + i, c + j)


def _centre(r: int, c: int, k: int, m: float) -> tuple[float, float]:
    return ((c + k / 2) * m, (r + k / 2) * m)


_DIRS = ((0, 1), (1, 0), (0, -1), (-1, 0))


@lru_cache(maxsize=256)
def sweep_offsets(turner: BodyShape, fleet: tuple[BodyShape, ...], cell_m: float,
                  ) -> tuple[tuple[int, int], ...]:
    """Cells (``(drow, dcol)`` from the turner's anchor, sorted) that a turn in place of
    ``turner`` must hold, given every AGV type of the ``fleet`` (see the module doc).
    Empty for AGVs that never turn or whose disc cannot reach a neighbour's body.
    Raises :class:`SweepError` if a cell beyond the footprint's ring would be needed."""
    if not turner.turns:
        return ()
    k, m, r_a = turner.k, cell_m, turner.radius_m
    cx, cy = _centre(0, 0, k, m)
    own = set(_fp(0, 0, k))
    out: set[tuple[int, int]] = set()
    beyond: set[tuple[int, int]] = set()
    for b in fleet:
        kb = b.k
        hl, hw = b.length_m / 2, b.width_m / 2
        reach = math.ceil((r_a + b.radius_m) / m) + kb + 1
        for ar in range(-reach, k + reach):
            for ac in range(-reach, k + reach):
                fa = set(_fp(ar, ac, kb))
                if fa & own:
                    continue
                qx, qy = _centre(ar, ac, kb, m)
                # Standing (omni: axis-aligned; a diff body standing is inside its disc,
                # handled above) and driving one cell straight from ``a``.
                shapes = []
                if not b.turns:
                    shapes.append(((qx - hl, qy - hw, qx + hl, qy + hw), fa))
                for dr, dc in _DIRS:
                    fb = set(_fp(ar + dr, ac + dc, kb))
                    if fb & own:
                        continue
                    rx, ry = _centre(ar + dr, ac + dc, kb, m)
                    if b.turns:  # heading along the move
                        ex, ey = (hl, hw) if dc else (hw, hl)
                    else:
                        ex, ey = hl, hw
                    shapes.append(((min(qx, rx) - ex, min(qy, ry) - ey,
                                    max(qx, rx) + ex, max(qy, ry) + ey), fa | fb))
                for (x0, y0, x1, y1), cells in shapes:
                    for (nr, nc) in cells:
                        # The part of the body that lies in cell n's square.
                        sx0, sy0 = max(x0, nc * m), max(y0, nr * m)
                        sx1, sy1 = min(x1, (nc + 1) * m), min(y1, (nr + 1) * m)
                        if disc_overlaps_rect(cx, cy, r_a, sx0, sy0, sx1, sy1):
                            if -1 <= nr <= k and -1 <= nc <= k:
                                out.add((nr, nc))
                            else:
                                beyond.add((nr, nc))
    if beyond:
        raise SweepError(f"the swept disc reaches bodies in cells {sorted(beyond)} (offsets "
                         "from the anchor) beyond the ring of cells around the footprint")
    return tuple(sorted(out - own))


@lru_cache(maxsize=256)
def turn_locks(turner: BodyShape, fleet: tuple[BodyShape, ...], cell_m: float,
               ) -> tuple[tuple[int, int], ...]:
    """Anchors (``(drow, dcol)`` from the turner's anchor, sorted, its own ``(0, 0)``
    included) whose turns in place the turner's turn must not overlap in time: another
    type's swept disc there overlaps its own. Empty if no two turns can touch (then the
    turn needs no lock at all)."""
    if not turner.turns:
        return ()
    k, m, r_a = turner.k, cell_m, turner.radius_m
    cx, cy = _centre(0, 0, k, m)
    own = set(_fp(0, 0, k))
    out: set[tuple[int, int]] = set()
    for b in fleet:
        if not b.turns:
            continue
        kb = b.k
        reach = math.ceil((r_a + b.radius_m) / m) + kb + 1
        for ar in range(-reach, k + reach):
            for ac in range(-reach, k + reach):
                if set(_fp(ar, ac, kb)) & own:
                    continue
                qx, qy = _centre(ar, ac, kb, m)
                if discs_overlap(cx, cy, r_a, qx, qy, b.radius_m):
                    out.add((ar, ac))
    return tuple(sorted(out | {(0, 0)})) if out else ()


def fleet_sweeps(types: Mapping[str, object], cell_m: float) -> dict[str, tuple]:
    """:func:`sweep_offsets` of every AGV type (``name -> AgvTypeSpec``) of a fleet."""
    shapes = {name: BodyShape.of(spec) for name, spec in types.items()}
    fleet = tuple(sorted(set(shapes.values()), key=lambda s: (s.k, s.length_m, s.width_m,
                                                                s.turns)))
    return {name: sweep_offsets(s, fleet, cell_m) for name, s in shapes.items()}


class Sweep(NamedTuple):
    """What one AGV's turn in place holds: ``cells`` (offsets from its anchor, held
    exclusively, :func:`sweep_offsets`) and ``locks`` (anchor offsets, :func:`turn_locks`)."""

    cells: tuple[tuple[int, int], ...]
    locks: tuple[tuple[int, int], ...]


def agv_sweeps(specs: Sequence, cell_m: float) -> dict[int, Sweep]:
    """Per AGV (index into ``specs``, one ``AgvTypeSpec`` each) what its turns hold;
    AGVs whose turns hold nothing are left out (all of them for 0.7 m bodies on 1 m
    cells)."""
    shapes = [BodyShape.of(s) for s in specs]
    fleet = tuple(sorted(set(shapes), key=lambda s: (s.k, s.length_m, s.width_m, s.turns)))
    out = {}
    for i, s in enumerate(shapes):
        sw = Sweep(sweep_offsets(s, fleet, cell_m), turn_locks(s, fleet, cell_m))
        if sw.cells or sw.locks:
            out[i] = sw
    return out


def check_fleet_sweeps(types: Mapping[str, object], cell_m: float) -> list[str]:
    """Problems with the fleet's turning sweeps, one sentence each (empty if none): a type
    whose swept disc reaches bodies the reservation cannot hold (see the module doc)."""
    shapes = {name: BodyShape.of(spec) for name, spec in types.items()}
    fleet = tuple(sorted(set(shapes.values()), key=lambda s: (s.k, s.length_m, s.width_m,
                                                                s.turns)))
    out = []
    for name, s in shapes.items():
        try:
            sweep_offsets(s, fleet, cell_m)
        except SweepError as err:
            out.append(f"fleet.types.{name}: a {s.length_m} x {s.width_m} m body on a "
                       f"{s.k}x{s.k} footprint turning in place sweeps a disc of radius "
                       f"{s.radius_m:.3f} m on {cell_m} m cells; {err}, so its turns cannot "
                       "be reserved (use a smaller body, drive: omni, or larger cells)")
    return out


def static_sweep_hits(layout, types: Mapping[str, object]) -> list[str]:
    """Problems, one sentence per AGV type: a differential-drive type whose swept disc
    reaches an obstacle or the map's edge from an anchor where it can stand (no
    reservation can clear those; a turn there hits the static world)."""
    from ..layout import CellType
    from .graph import MotionGraph

    m = layout.cell_m
    obstacle = layout.grid == CellType.OBSTACLE
    out = []
    for name, spec in types.items():
        s = BodyShape.of(spec)
        if not s.turns or s.radius_m <= s.k * m / 2 + 1e-12:
            continue
        valid = MotionGraph(layout, s.k, False).valid
        hits = []
        for r, c in zip(*np.nonzero(valid), strict=True):
            cx, cy = _centre(int(r), int(c), s.k, m)
            if cx - s.radius_m < 0 or cy - s.radius_m < 0 or \
                    cx + s.radius_m > layout.cols * m or cy + s.radius_m > layout.rows * m:
                hits.append((int(r), int(c)))
                continue
            for dr in range(-1, s.k + 1):
                for dc in range(-1, s.k + 1):
                    rr, cc = int(r) + dr, int(c) + dc
                    if 0 <= rr < layout.rows and 0 <= cc < layout.cols and obstacle[rr, cc] \
                            and disc_overlaps_rect(cx, cy, s.radius_m, cc * m, rr * m,
                                                   (cc + 1) * m, (rr + 1) * m):
                        hits.append((int(r), int(c)))
        if hits:
            hits = sorted(set(hits))
            out.append(f"fleet.types.{name}: a {s.length_m} x {s.width_m} m body on a "
                       f"{s.k}x{s.k} footprint turning in place sweeps a disc of radius "
                       f"{s.radius_m:.3f} m on {m} m cells, which reaches an obstacle or "
                       f"the map edge from {len(hits)} anchors it can stand on (first "
                       f"{hits[0]}); no reservation can clear those, so a turn there hits "
                       "the static world (use a body whose half-diagonal is at most "
                       f"{s.k * m / 2} m, drive: omni, or larger cells)")
    return out


def sweep_cells(anchor: int, offsets: Sequence[tuple[int, int]], rows: int,
                cols: int) -> tuple[int, ...]:
    """Flat indices of the swept cells of a turn at ``anchor`` that lie inside the grid."""
    r, c = divmod(anchor, cols)
    return tuple((r + dr) * cols + c + dc for dr, dc in offsets
                 if 0 <= r + dr < rows and 0 <= c + dc < cols)


def turn_sweeps(states: Sequence[tuple[int, int]], cols: int,
                heading: tuple[int, int] | None = EAST) -> list[tuple[int, int]]:
    """The turns in place of a per-tick state list: ``(index, anchor)`` for each move whose
    direction differs from the previous move's (the first move is compared with
    ``heading``; None: unknown, it counts as a turn). ``index`` is the last state standing
    at ``anchor`` before the move (the turn happens then)."""
    out = []
    prev = heading
    for i in range(1, len(states)):
        a, b = states[i - 1]
        a2, b2 = states[i]
        if a == b and (a2, b2) != (a, b):
            dst = b2 if a2 == a else a2
            ra, ca = divmod(a, cols)
            rb, cb = divmod(dst, cols)
            d = (rb - ra, cb - ca)
            if abs(d[0]) + abs(d[1]) != 1:
                continue
            if d != prev:
                out.append((i - 1, a))
            prev = d
    return out


@dataclass(frozen=True, slots=True)
class SweepConflict:
    tick: int
    agvs: tuple[int, int]
    """(turning AGV, AGV in the swept cells)."""
    cell: tuple[int, int]

    kind = "sweep"

    def __str__(self) -> str:
        return (f"sweep conflict at tick {self.tick}: AGV {self.agvs[0]} turns in place "
                f"while AGV {self.agvs[1]} holds {self.cell}")


def sweep_conflicts(trajectories: Mapping[int, Sequence[tuple[int, int]]], rows: int,
                    cols: int, sizes: Mapping[int, int], offsets: Mapping[int, Sequence],
                    *, start_tick: int = 0, headings: Mapping[int, tuple[int, int] | None]
                    | None = None, max_conflicts: int = 100) -> list[SweepConflict]:
    """Turns whose swept cells another AGV occupies at the turn's tick or the next one.

    Independent of the planners: it rebuilds every AGV's cells per tick from its states
    (``(a, b)`` flat anchors, moving if different; the last state holds). ``offsets``:
    per AGV the cells its turns hold (:func:`sweep_offsets`; missing or empty: it never
    sweeps). ``headings``: the direction each AGV faces before its first move (default
    east, as AGVs are placed; None: unknown)."""
    headings = headings or {}
    horizon = max((len(s) for s in trajectories.values()), default=0)

    def cells_at(agv: int, i: int) -> set[int]:
        states = trajectories[agv]
        a, b = states[min(i, len(states) - 1)]
        k = sizes.get(agv, 1)
        out = set()
        for node in {a, b}:
            r, c = divmod(node, cols)
            out.update((r + x) * cols + c + y for x in range(k) for y in range(k))
        return out

    out: list[SweepConflict] = []
    for agv, states in sorted(trajectories.items()):
        off = offsets.get(agv)
        if not off:
            continue
        for i, anchor in turn_sweeps(states, cols, headings.get(agv, EAST)):
            swept = set(sweep_cells(anchor, off, rows, cols))
            for j in (i, i + 1):
                if j >= horizon:
                    continue
                for other in sorted(trajectories):
                    if other == agv:
                        continue
                    hit = swept & cells_at(other, j)
                    if hit:
                        out.append(SweepConflict(start_tick + j, (agv, other),
                                                 divmod(min(hit), cols)))
                        if len(out) >= max_conflicts:
                            return out
    return out
