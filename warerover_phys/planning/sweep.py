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
  lock;
- a shelf the occupant may carry (:attr:`BodyShape.shelf_m`, a square of side
  :data:`SHELF_BOX` x footprint x cell size when the layout holds shelves it can lift): a
  carried shelf is kept parallel to the grid while its AGV turns under it (the physics
  executor, the recording and the clearance figures all model it so), so a loaded body
  standing or driving straight holds the box of its shelf as well as its own rectangle,
  whichever reaches further. :func:`sweep_offsets` with shelves gives every cell whose
  occupant *could* be hit if it carried a shelf; :func:`agv_sweeps` splits that into
  :attr:`Sweep.cells` (held against every AGV) and :attr:`Sweep.shelf_cells` (held only
  against AGVs that carry a shelf then). A 0.8 m body's disc (``r = 0.566 m``) misses an
  aligned neighbour's 0.8 m body by 3.4 cm but reaches 1.6 cm into the 0.9 m shelf it may
  carry, so its turns hold the four edge neighbours as shelf cells: it may turn beside an
  unloaded AGV (parked, or on its way to a shelf), not beside a loaded one.

The turner's own carried shelf does not turn either: it stays in the turner's footprint and
sweeps nothing.

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
>>> loaded = BodyShape(k=1, length_m=0.8, width_m=0.8, turns=True, shelf_m=0.9)
>>> sweep_offsets(loaded, (loaded,), 1.0)  # but the 0.9 m shelf it may carry is
((-1, 0), (0, -1), (0, 1), (1, 0))
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

from .headings import dead_ends, turn_dist

__all__ = ["turn_locks", "BodyShape", "SweepError", "disc_overlaps_rect", "discs_overlap", "sweep_offsets",
           "fleet_sweeps", "agv_sweeps", "Sweep", "turn_sweeps", "sweep_cells", "EAST",
           "no_turn_anchors", "dead_ends", "move_dir", "DIR_OF", "turn_aware", "lock_keys",
           "turn_fields", "turn_dist", "TurnMasks", "SHELF_BOX", "carried_shelf_m"]
# check_fleet_sweeps, static_sweep_hits, heading_after, SweepConflict and sweep_conflicts
# live in .sweep_checks

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
    shelf_m: float = 0.0
    """Side (metres) of the square shelf it may carry, kept parallel to the grid (0: it
    never carries one; :func:`carried_shelf_m`)."""

    @property
    def radius_m(self) -> float:
        """Half-diagonal: the radius of the disc swept by a turn in place."""
        return math.hypot(self.length_m, self.width_m) / 2

    @property
    def reach_m(self) -> float:
        """How far from its centre anything it carries reaches (body or shelf corner)."""
        return max(self.radius_m, self.shelf_m / math.sqrt(2))

    @classmethod
    def of(cls, spec, shelf_m: float = 0.0) -> BodyShape:
        """From an :class:`~warerover_phys.config.AgvTypeSpec` (``shelf_m``: the side of
        the shelf it may carry, :func:`carried_shelf_m`)."""
        return cls(int(spec.footprint), float(spec.body_m[0]), float(spec.body_m[1]),
                   spec.drive == "diff", float(shelf_m))


def carried_shelf_m(layout, spec) -> float:
    """Side (metres) of the square shelf an AGV of type ``spec`` may carry on ``layout``:
    :data:`SHELF_BOX` x its footprint x the cell size if the layout holds a shelf it can
    lift, else 0 (``layout`` None: no shelves)."""
    if layout is None:
        return 0.0
    if any(spec.can_carry(size) for size in {sh.size for sh in layout.shelves}):
        return SHELF_BOX * int(spec.footprint) * float(layout.cell_m)
    return 0.0


def _shapes(specs: Sequence, layout) -> list[BodyShape]:
    """:class:`BodyShape` per spec, with the shelf each may carry on ``layout``."""
    cache: dict[int, BodyShape] = {}
    out = []
    for spec in specs:
        key = id(spec)
        if key not in cache:
            cache[key] = BodyShape.of(spec, carried_shelf_m(layout, spec))
        out.append(cache[key])
    return out


def _fleet(shapes) -> tuple[BodyShape, ...]:
    return tuple(sorted(set(shapes), key=lambda s: (s.k, s.length_m, s.width_m, s.turns,
                                                    s.shelf_m)))


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
        hs = b.shelf_m / 2  # a carried shelf: axis-aligned, whatever the body's heading
        reach = math.ceil((r_a + b.reach_m) / m) + kb + 1
        for ar in range(-reach, k + reach):
            for ac in range(-reach, k + reach):
                fa = set(_fp(ar, ac, kb))
                if fa & own:
                    continue
                qx, qy = _centre(ar, ac, kb, m)
                # Standing (omni: axis-aligned; a diff body standing is inside its disc,
                # handled above, but the shelf it carries is not) and driving one cell
                # straight from ``a``.
                shapes = []
                if not b.turns:
                    sx, sy = max(hl, hs), max(hw, hs)
                    shapes.append(((qx - sx, qy - sy, qx + sx, qy + sy), fa))
                elif hs > 0:
                    shapes.append(((qx - hs, qy - hs, qx + hs, qy + hs), fa))
                for dr, dc in _DIRS:
                    fb = set(_fp(ar + dr, ac + dc, kb))
                    if fb & own:
                        continue
                    rx, ry = _centre(ar + dr, ac + dc, kb, m)
                    if b.turns:  # heading along the move
                        ex, ey = (hl, hw) if dc else (hw, hl)
                    else:
                        ex, ey = hl, hw
                    ex, ey = max(ex, hs), max(ey, hs)
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


def fleet_sweeps(types: Mapping[str, object], cell_m: float, layout=None,
                 ) -> dict[str, tuple]:
    """:func:`sweep_offsets` of every AGV type (``name -> AgvTypeSpec``) of a fleet
    (``layout``: the floor whose shelves they may carry; None: no shelves)."""
    names = list(types)
    shapes = dict(zip(names, _shapes([types[n] for n in names], layout), strict=True))
    fleet = _fleet(shapes.values())
    return {name: sweep_offsets(s, fleet, cell_m) for name, s in shapes.items()}


class Sweep(NamedTuple):
    """What one AGV's turn in place holds: ``cells`` (offsets from its anchor, held
    exclusively, :func:`sweep_offsets`), ``locks`` (anchor offsets, :func:`turn_locks`)
    and ``shelf_cells`` (offsets held only against AGVs that carry a shelf at the time:
    the disc reaches the shelf such an occupant may carry but not its body)."""

    cells: tuple[tuple[int, int], ...]
    locks: tuple[tuple[int, int], ...]
    shelf_cells: tuple[tuple[int, int], ...] = ()


def agv_sweeps(specs: Sequence, cell_m: float, layout=None) -> dict[int, Sweep]:
    """Per AGV (index into ``specs``, one ``AgvTypeSpec`` each) what its turns hold;
    AGVs whose turns hold nothing are left out (all of them for 0.7 m bodies on 1 m
    cells). ``layout``: the floor whose shelves the AGVs may carry (None: no shelves;
    the planners, the dependency graph and the validator must all pass the same)."""
    shapes = _shapes(specs, layout)
    fleet = _fleet(shapes)
    bare = _fleet(_bare(s) for s in shapes)
    out = {}
    for i, s in enumerate(shapes):
        body = sweep_offsets(_bare(s), bare, cell_m)
        loaded = sweep_offsets(s, fleet, cell_m) if s.shelf_m or any(
            b.shelf_m for b in fleet) else body
        sw = Sweep(body, turn_locks(_bare(s), bare, cell_m),
                   tuple(c for c in loaded if c not in body))
        if sw.cells or sw.locks or sw.shelf_cells:
            out[i] = sw
    return out


def _bare(s: BodyShape) -> BodyShape:
    return BodyShape(s.k, s.length_m, s.width_m, s.turns)


def turn_fields(layout, specs: Sequence) -> dict[int, tuple[Sweep | None, frozenset[int]]]:
    """Per AGV (index into ``specs``, one ``AgvTypeSpec`` each) what a planner needs to
    plan its turns (:class:`~warerover_phys.planning.base.AgentRequest`'s ``sweep`` and
    ``no_turn``); AGVs whose turns need nothing are left out (all of them for the default
    0.7 m bodies on 1 m cells)."""
    sweeps = agv_sweeps(specs, layout.cell_m, layout)
    masks: dict[BodyShape, frozenset[int]] = {}
    out = {}
    for i, spec in enumerate(specs):
        shape = BodyShape.of(spec)
        if shape not in masks:
            masks[shape] = no_turn_anchors(layout, shape)
        if i in sweeps or masks[shape]:
            out[i] = (sweeps.get(i), masks[shape])
    return out


def no_turn_anchors(layout, shape: BodyShape) -> frozenset[int]:
    """Flat anchors (``row * cols + col``) where the swept disc of a turn in place of
    ``shape`` reaches an obstacle or the map's edge (the physics world has walls there):
    no reservation can clear those, so planners must not turn such an AGV there. Empty for
    AGVs that never turn and for discs that stay inside the footprint."""
    from ..layout import CellType

    s, m = shape, layout.cell_m
    if not s.turns or s.radius_m <= s.k * m / 2 + 1e-12:
        return frozenset()
    rows, cols = layout.rows, layout.cols
    obstacle = layout.grid == CellType.OBSTACLE
    out = set()
    for r in range(rows - s.k + 1):
        for c in range(cols - s.k + 1):
            cx, cy = _centre(r, c, s.k, m)
            if cx - s.radius_m < 0 or cy - s.radius_m < 0 or \
                    cx + s.radius_m > cols * m or cy + s.radius_m > rows * m:
                out.add(r * cols + c)
                continue
            if any(0 <= r + dr < rows and 0 <= c + dc < cols and obstacle[r + dr, c + dc]
                   and disc_overlaps_rect(cx, cy, s.radius_m, (c + dc) * m, (r + dr) * m,
                                          (c + dc + 1) * m, (r + dr + 1) * m)
                   for dr in range(-1, s.k + 1) for dc in range(-1, s.k + 1)):
                out.add(r * cols + c)
    return frozenset(out)


SHELF_BOX = 0.9
"""A shelf's box, as a fraction of its footprint's side (the physics executor's shelf
sensor: a loaded AGV touching another shelf is a static contact)."""


class TurnMasks:
    """Where one body shape may not turn in place on one layout: ``walls`` (the swept disc
    reaches an obstacle or the map edge: :func:`no_turn_anchors`), and, while carrying a
    shelf, also where it reaches another shelf's box (:meth:`carrying`)."""

    def __init__(self, layout, shape: BodyShape) -> None:
        self.layout, self.shape = layout, shape
        self.walls = no_turn_anchors(layout, shape)
        self._hits: dict[int, set[int]] | None = None
        self._carrying: dict[int | None, frozenset[int]] = {}

    def _shelf_hits(self) -> dict[int, set[int]]:
        """Anchor -> shelves whose box the swept disc there reaches."""
        if self._hits is None:
            lay, s = self.layout, self.shape
            m, cols = lay.cell_m, lay.cols
            hits: dict[int, set[int]] = {}
            if s.turns and s.radius_m > s.k * m / 2 * SHELF_BOX + 1e-12:
                for shelf in lay.shelves:
                    r0, c0 = shelf.anchor
                    ks = shelf.size
                    cx, cy = (c0 + ks / 2) * m, (r0 + ks / 2) * m
                    half = ks * m * SHELF_BOX / 2
                    reach = int(math.ceil(s.radius_m / m)) + 1
                    for r in range(r0 - s.k - reach, r0 + ks + reach + 1):
                        for c in range(c0 - s.k - reach, c0 + ks + reach + 1):
                            if not (0 <= r <= lay.rows - s.k and 0 <= c <= lay.cols - s.k):
                                continue
                            ax, ay = _centre(r, c, s.k, m)
                            if disc_overlaps_rect(ax, ay, s.radius_m, cx - half, cy - half,
                                                  cx + half, cy + half):
                                hits.setdefault(r * cols + c, set()).add(shelf.id)
            self._hits = hits
        return self._hits

    def carrying(self, shelf: int | None) -> frozenset[int]:
        """No-turn anchors while carrying ``shelf``: the walls' and where the disc reaches
        the box of any other shelf (cached per shelf)."""
        out = self._carrying.get(shelf)
        if out is None:
            extra = {a for a, ids in self._shelf_hits().items() if ids - {shelf}}
            out = self._carrying[shelf] = self.walls | frozenset(extra)
        return out


DIR_OF = {d: i for i, d in enumerate(_DIRS)}
"""Direction ``(drow, dcol)`` -> index (0 east, 1 south, 2 west, 3 north)."""


def move_dir(a: int, b: int, cols: int) -> int:
    """Index of the direction of the move from anchor ``a`` to its 4-neighbour ``b``."""
    d = b - a
    return 0 if d == 1 else 1 if d == cols else 2 if d == -1 else 3


def turn_aware(agent) -> bool:
    """Must a planner track this :class:`~warerover_phys.planning.base.AgentRequest`'s
    heading? (Its turns hold cells or locks, or there are anchors where it may not turn.)"""
    sw = agent.sweep
    return bool(agent.no_turn) or (sw is not None and bool(sw.cells or sw.locks))


def lock_keys(anchor: int, locks: Sequence[tuple[int, int]], rows: int | None,
              cols: int) -> tuple[int, ...]:
    """Flat anchors of the turn locks of a turn at ``anchor`` that lie inside the grid."""
    r, c = divmod(anchor, cols)
    return tuple((r + dr) * cols + c + dc for dr, dc in locks
                 if 0 <= c + dc < cols and r + dr >= 0 and (rows is None or r + dr < rows))


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
