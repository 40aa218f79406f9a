"""Checks built on turning sweeps: the static checks of a fleet on a layout (sweeps that fit,
anchors where a turn hits a wall or a shelf) and the sweep conflicts of timed paths
(:func:`sweep_conflicts`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import partial

import numpy as np

from .headings import dead_ends
from .sweep import (
    DIR_OF,
    EAST,
    SHELF_BOX,
    BodyShape,
    SweepError,
    _bare,
    _fleet,
    _shapes,
    move_dir,
    no_turn_anchors,
    sweep_cells,
    sweep_offsets,
    turn_sweeps,
)

__all__ = ["check_fleet_sweeps", "static_sweep_hits", "heading_after", "SweepConflict",
           "sweep_conflicts"]


def check_fleet_sweeps(types: Mapping[str, object], cell_m: float, layout=None,
                       shelf_sweeps: bool = True) -> list[str]:
    """Problems with the fleet's turning sweeps, one sentence each (empty if none): a type
    whose swept disc reaches bodies, or shelves they may carry on ``layout``, that the
    reservation cannot hold (see the module doc). ``shelf_sweeps``
    (``executor.shelf_sweeps``): turns wait for loaded neighbours, so two loaded AGVs at
    stations side by side can never turn (reported); without it such turns go ahead."""
    names = list(types)
    shapes = dict(zip(names, _shapes([types[n] for n in names], layout), strict=True))
    fleet = _fleet(shapes.values())
    bare = _fleet(_bare(s) for s in shapes.values())
    out = []
    for name, s in shapes.items():
        try:
            sweep_offsets(s, fleet, cell_m)
        except SweepError as err:
            try:
                sweep_offsets(_bare(s), bare, cell_m)
                shelves = sorted({f"{b.shelf_m:g} m" for b in fleet if b.shelf_m > 0})
                why = (f"; with the shelves the fleet carries on this layout "
                       f"({', '.join(shelves)} squares, kept parallel to the grid) {err}")
            except SweepError:
                why = f"; {err}"
            out.append(f"fleet.types.{name}: a {s.length_m} x {s.width_m} m body on a "
                       f"{s.k}x{s.k} footprint turning in place sweeps a disc of radius "
                       f"{s.radius_m:.3f} m on {cell_m} m cells{why}, so its turns cannot "
                       "be reserved (use a smaller body, drive: omni, or larger cells)")
            continue
        if layout is None or s.k != 1 or not s.turns or not shelf_sweeps:
            continue
        body = set(sweep_offsets(_bare(s), bare, cell_m))
        shelf = set(sweep_offsets(s, fleet, cell_m)) - body
        stations = sorted(tuple(x) for x in layout.stations)
        pairs = [(a, b) for a in stations for b in stations
                 if a < b and (b[0] - a[0], b[1] - a[1]) in shelf]
        if pairs:
            more = f" and {len(pairs) - 2} more pairs" if len(pairs) > 2 else ""
            reach = s.radius_m - (cell_m - max(b.shelf_m for b in fleet) / 2)
            out.append(f"fleet.types.{name}: a {s.length_m} x {s.width_m} m body on a "
                       f"1x1 footprint turning in place sweeps a disc of radius "
                       f"{s.radius_m:.3f} m, which reaches {reach * 100:.1f} cm into the "
                       f"{max(b.shelf_m for b in fleet):g} m shelf a neighbour carries (kept "
                       f"parallel to the grid) on {cell_m} m cells; stations "
                       f"{', '.join(f'{a} and {b}' for a, b in pairs[:2])}{more} are side "
                       "by side, so two loaded AGVs there block each other's turns and "
                       "neither can turn to leave; the planners do not reserve turns "
                       "against loaded neighbours (the physics executor makes such a turn "
                       "wait), so these stations cannot be served together (use a body "
                       f"whose half-diagonal is at most {cell_m - SHELF_BOX * cell_m / 2:g} m, "
                       "drive: omni, larger cells, or a free cell between stations)")
    return out


def static_sweep_hits(layout, types: Mapping[str, object],
                      starts: Mapping[str, Sequence[tuple[int, int]]] | None = None,
                      ) -> list[str]:
    """Problems, one sentence per AGV type: a differential-drive type that cannot do its
    work because turning in place is impossible where its swept disc reaches an obstacle
    or the map's edge (see :func:`no_turn_anchors`; planners never turn it there).

    For each such type, over its unloaded motion graph with headings: every anchor it
    starts on must let it reach an anchor where it may turn, and every station, parking
    spot and shelf anchor it can stand on must be reachable in a state from which it can
    leave again (not facing a wall where it cannot turn). ``starts``: per type the anchors
    its AGVs start on (facing east, as they are placed). Types that turn nowhere near the
    static world, or whose every required place passes this test, are not reported."""
    from .graph import MotionGraph

    m = layout.cell_m
    out = []
    for name, spec in types.items():
        s = BodyShape.of(spec)
        no_turn = no_turn_anchors(layout, s)
        if not no_turn:
            continue
        graph = MotionGraph(layout, s.k, False)
        cols = layout.cols
        dead = dead_ends(graph.neighbors, no_turn, cols)
        free = [int(n) for n in np.flatnonzero(graph.valid.ravel()) if int(n) not in no_turn]
        # Anchors reachable from a free anchor (where it can take any heading), in a state
        # it can leave: breadth-first over (anchor, heading) states.
        seen = {(n, d) for n in free for d in range(4)}
        frontier = list(seen)
        while frontier:
            nxt_front = []
            for v, h in frontier:
                for u in graph.neighbors[v]:
                    d = move_dir(v, u, cols)
                    if d != h and v in no_turn:
                        continue
                    key = (u, d)
                    if key in seen or key in dead:
                        continue
                    seen.add(key)
                    nxt_front.append(key)
            frontier = nxt_front
        usable = {v for v, _ in seen}
        k = s.k
        places = [("station", cell) for cell in layout.stations] + \
            [("parking spot", p) for p in layout.parking] + \
            [("shelf", sh.anchor) for sh in layout.shelves if sh.size == k]
        bad: dict[str, list[tuple[int, int]]] = {}
        for what, (r, c) in places:
            anchor = graph.goal_anchor((r, c))
            if anchor is None:
                continue
            node = anchor[0] * cols + anchor[1]
            if node not in usable:
                bad.setdefault(what, []).append((r, c))
        for r, c in (starts or {}).get(name, ()):
            if (r * cols + c, DIR_OF[EAST]) in dead:
                bad.setdefault("start", []).append((r, c))
        if not free:
            bad = {"anchor": [(-1, -1)]}
        if bad:
            words = []
            for what, cells in bad.items():
                more = f" and {len(cells) - 3} more" if len(cells) > 3 else ""
                east = " (facing east)" if what == "start" else ""
                words.append(f"{what}{'s' if len(cells) > 1 else ''} "
                             f"{', '.join(str(x) for x in cells[:3])}{more}{east}"
                             if cells[0] != (-1, -1) else "every anchor")
            out.append(f"fleet.types.{name}: a {s.length_m} x {s.width_m} m body on a "
                       f"{s.k}x{s.k} footprint turning in place sweeps a disc of radius "
                       f"{s.radius_m:.3f} m on {m} m cells, which reaches an obstacle or "
                       f"the map edge from {len(no_turn)} anchors, where it must never "
                       f"turn; then {'; '.join(words)} cannot be used: an AGV there "
                       "ends up facing a wall where it cannot turn, so it could never "
                       "leave (use a body whose half-diagonal is at most "
                       f"{s.k * m / 2} m, drive: omni, larger cells, or a layout with a "
                       "free cell between those places and the walls)")
    return out


def heading_after(states: Sequence[tuple[int, int]], cols: int,
                  heading: tuple[int, int] | None = EAST) -> tuple[int, int] | None:
    """The direction an AGV faces after the per-tick ``states`` (its last move's; a
    moving state counts as its move), starting from ``heading``."""
    out = heading
    prev = None
    for a, b in states:
        src, dst = (a, b) if a != b else ((prev[0], a) if prev is not None and
                                          prev[0] == prev[1] else (a, a))
        if src != dst:
            r0, c0 = divmod(src, cols)
            r1, c1 = divmod(dst, cols)
            if abs(r1 - r0) + abs(c1 - c0) == 1:
                out = (r1 - r0, c1 - c0)
        prev = (a, b)
    return out


@dataclass(frozen=True, slots=True)
class SweepConflict:
    tick: int
    agvs: tuple[int, ...]
    """(turning AGV, AGV in the swept cells); (one turning AGV, the other) for ``turn_lock``;
    (the turning AGV,) for ``turn_wall``; (turning AGV, loaded AGV) for ``shelf_sweep``."""
    cell: tuple[int, int]
    """The swept cell held by the other AGV; the first turn's anchor for ``turn_lock`` and
    ``turn_wall``."""
    kind: str = "sweep"
    """``sweep``: a turn's swept cell is held by another AGV at the turn's tick or the next;
    ``turn_lock``: two turns at one tick share a turn lock (their swept discs may touch);
    ``turn_wall``: a turn where the swept disc reaches an obstacle or the map edge;
    ``shelf_sweep``: a turn's shelf cell (:attr:`Sweep.shelf_cells`) is held by an AGV that
    carries a shelf at the turn's tick or the next."""
    other: tuple[int, int] | None = None
    """The second turn's anchor (``turn_lock``)."""

    def __str__(self) -> str:
        if self.kind == "turn_lock":
            return (f"turn lock conflict at tick {self.tick}: AGVs {self.agvs[0]} and "
                    f"{self.agvs[1]} turn in place at once at {self.cell} and {self.other}, "
                    "whose turn locks overlap (their swept discs may touch)")
        if self.kind == "turn_wall":
            return (f"turn-at-wall conflict at tick {self.tick}: AGV {self.agvs[0]} turns in "
                    f"place at {self.cell}, where its swept disc reaches an obstacle or the "
                    "map edge")
        if self.kind == "shelf_sweep":
            return (f"shelf sweep conflict at tick {self.tick}: AGV {self.agvs[0]} turns in "
                    f"place while AGV {self.agvs[1]}, carrying a shelf, holds {self.cell} "
                    "(the swept disc reaches its shelf)")
        return (f"sweep conflict at tick {self.tick}: AGV {self.agvs[0]} turns in place "
                f"while AGV {self.agvs[1]} holds {self.cell}")


def _unloaded_at(loaded, agv: int, i: int) -> bool:
    """Is ``agv`` without a shelf at its state ``i`` (``loaded``: see :func:`sweep_conflicts`)?"""
    x = True if loaded is None else loaded.get(agv, True)
    if isinstance(x, bool):
        return not x
    return not (bool(x[min(i, len(x) - 1)]) if len(x) else True)


def _cells_at(trajectories, sizes, cols: int, agv: int, i: int) -> set[int]:
    """The cells ``agv`` holds at its state ``i`` (both ends of a move; the last state holds)."""
    states = trajectories[agv]
    a, b = states[min(i, len(states) - 1)]
    k = sizes.get(agv, 1)
    out = set()
    for node in {a, b}:
        r, c = divmod(node, cols)
        out.update((r + x) * cols + c + y for x in range(k) for y in range(k))
    return out


def _swept_hits(swept: set[int], agv: int, i: int, horizon: int, trajectories, cells_at,
                skip=None):
    """``(state index, other AGV, cells)`` for every other AGV (not ``skip(other, j)``) whose
    cells meet ``swept`` at the turn's state ``i`` or the next."""
    for j in (i, i + 1):
        if j >= horizon:
            continue
        for other in sorted(trajectories):
            if other == agv or (skip is not None and skip(other, j)):
                continue
            hit = swept & cells_at(other, j)
            if hit:
                yield j, other, hit


def sweep_conflicts(trajectories: Mapping[int, Sequence[tuple[int, int]]], rows: int,
                    cols: int, sizes: Mapping[int, int], offsets: Mapping[int, Sequence],
                    *, start_tick: int = 0, headings: Mapping[int, tuple[int, int] | None]
                    | None = None, max_conflicts: int = 100,
                    locks: Mapping[int, Sequence[tuple[int, int]]] | None = None,
                    no_turn: Mapping[int, frozenset[int]] | None = None,
                    shelf_offsets: Mapping[int, Sequence] | None = None,
                    loaded: Mapping[int, Sequence[bool] | bool] | None = None,
                    ) -> list[SweepConflict]:
    """Turns whose swept cells another AGV occupies at the turn's tick or the next one
    (kind ``sweep``), pairs of turns at one tick that share a turn lock (``turn_lock``,
    with ``locks``: per AGV its turn locks, :func:`turn_locks`), and turns at anchors in
    the AGV's ``no_turn`` set (``turn_wall``, :func:`no_turn_anchors`).

    Independent of the planners: it rebuilds every AGV's cells per tick from its states
    (``(a, b)`` flat anchors, moving if different; the last state holds). ``offsets``:
    per AGV the cells its turns hold (:func:`sweep_offsets`; missing or empty: it never
    sweeps). ``headings``: the direction each AGV faces before its first move (default
    east, as AGVs are placed; None: unknown). ``shelf_offsets``: per AGV its turns'
    :attr:`Sweep.shelf_cells`, checked (kind ``shelf_sweep``) against AGVs that carry a
    shelf: ``loaded`` per AGV a bool or one bool per state (missing: loaded)."""
    headings = headings or {}
    shelf_offsets = shelf_offsets or {}

    locks = locks or {}
    no_turn = no_turn or {}
    horizon = max((len(s) for s in trajectories.values()), default=0)
    cells_at = partial(_cells_at, trajectories, sizes, cols)
    unloaded = partial(_unloaded_at, loaded)

    out: list[SweepConflict] = []
    turns_at: dict[int, list[tuple[int, int, set[tuple[int, int]]]]] = {}
    for agv, states in sorted(trajectories.items()):
        off = offsets.get(agv)
        lk = locks.get(agv)
        walls = no_turn.get(agv, frozenset())
        shelf_off = shelf_offsets.get(agv)
        if not off and not lk and not walls and not shelf_off:
            continue
        for i, anchor in turn_sweeps(states, cols, headings.get(agv, EAST)):
            if anchor in walls:
                out.append(SweepConflict(start_tick + i, (agv,), divmod(anchor, cols),
                                         "turn_wall"))
            if lk:
                r, c = divmod(anchor, cols)
                turns_at.setdefault(i, []).append(
                    (agv, anchor, {(r + dr, c + dc) for dr, dc in lk}))
            if shelf_off:
                shelf_swept = set(sweep_cells(anchor, shelf_off, rows, cols))
                for j, other, hit in _swept_hits(shelf_swept, agv, i, horizon, trajectories,
                                                 cells_at, unloaded):
                    out.append(SweepConflict(start_tick + j, (agv, other),
                                             divmod(min(hit), cols), "shelf_sweep"))
            if not off:
                continue
            swept = set(sweep_cells(anchor, off, rows, cols))
            for j, other, hit in _swept_hits(swept, agv, i, horizon, trajectories, cells_at):
                out.append(SweepConflict(start_tick + j, (agv, other), divmod(min(hit), cols)))
    for i, turns in sorted(turns_at.items()):
        for x, (a, na, la) in enumerate(turns):
            for b, nb, lb in turns[x + 1:]:
                if la & lb:
                    out.append(SweepConflict(start_tick + i, (a, b), divmod(na, cols),
                                             "turn_lock", divmod(nb, cols)))
    out.sort(key=lambda c: c.tick)
    return out[:max_conflicts]
