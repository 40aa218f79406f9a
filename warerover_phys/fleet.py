"""The fleet of an episode: AGV states, AGVs and their trips, where each AGV starts, and the checks
that a layout can serve the fleet (see :mod:`warerover_phys.world`, which re-exports the names)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from .config import AgvTypeSpec, Scenario
from .errors import LayoutError, ScenarioError
from .layout import CellType, Layout
from .planning.base import State
from .planning.graph import UNREACHABLE, GraphSet

Cell = tuple[int, int]


class AgvState(IntEnum):
    IDLE = 0
    TO_SHELF = 1
    PICKING = 2
    TO_STATION = 3
    HANDOVER = 4
    RETURNING = 5
    PLACING = 6
    FAILED = 7
    ERRAND = 8
    """On an errand task: driving to its next errand cell."""

MOVING_STATES = (AgvState.IDLE, AgvState.TO_SHELF, AgvState.TO_STATION, AgvState.RETURNING,
                 AgvState.ERRAND)

WORK_STATES = (AgvState.PICKING, AgvState.HANDOVER, AgvState.PLACING)
"""Dwells: the AGV works in place on its stage's goal."""

STAGE_OF = {AgvState.PICKING: "pick", AgvState.HANDOVER: "handover", AgvState.PLACING: "place"}


class OrderStatus(IntEnum):
    PENDING = 0
    ASSIGNED = 1
    IN_PROGRESS = 2
    COMPLETED = 3


@dataclass(slots=True)
class Trip:
    """One shelf trip: fetch ``shelf``, visit ``stops`` (station indices), bring it back."""

    id: int
    agv: int
    shelf: int
    orders: tuple[int, ...]
    stops: tuple[int, ...]
    stop_idx: int = 0


@dataclass(slots=True)
class Agv:
    id: int
    type_name: str
    spec: AgvTypeSpec
    ticks_per_move: int
    home: int
    """Anchor node of its parking spot."""
    pos: State
    """Where it is now (a state: standing at ``a`` if ``a == b``)."""
    state: AgvState = AgvState.IDLE
    trip: Trip | None = None
    loaded: bool = False
    dwell_left: int = 0
    delay: int = 0
    """Ticks it is behind its committed path (blocked moves)."""
    blocked_ticks: int = 0
    plan_failures: int = 0
    retry_at: int = 0
    yield_goal: int | None = None
    """Where it waits while making way for a stuck AGV (until ``yield_until``)."""
    yield_until: int = 0
    last_goal: int | None = None
    goal_since: int = 0
    """Tick its current goal was set (lifelong PIBT priorities age from it)."""
    resume_state: AgvState | None = None
    """While FAILED: the state it returns to when repaired."""
    repair_at: int | None = None
    """While FAILED: the tick it is repaired (None: only on demand)."""
    parked: bool = False
    """IDLE, at rest on its home spot, ``parked`` logged (until it leaves)."""

    @property
    def k(self) -> int:
        return self.spec.footprint

    @property
    def node(self) -> int:
        return self.pos[1]

    @property
    def standing(self) -> bool:
        return self.pos[0] == self.pos[1]


def can_carry(spec: AgvTypeSpec, shelf_size: int) -> bool:
    """An AGV lifts a shelf from under it: the shelf must match its footprint and cargo class
    (:meth:`.AgvTypeSpec.can_carry`)."""
    return spec.can_carry(shelf_size)


def _place_fleet(scenario: Scenario, layout: Layout, graphs: GraphSet) -> list[Agv]:
    fleet, src = scenario.fleet, scenario.source
    cell_m, tick_s = layout.cell_m, scenario.tick_s
    for name, spec in fleet.types.items():
        length, width = spec.body_m
        if max(length, width) > spec.footprint * cell_m + 1e-9:
            raise ScenarioError(f"body {length} x {width} m does not fit a {spec.footprint}x"
                                f"{spec.footprint} footprint of {cell_m} m cells", file=src,
                                field=f"fleet.types.{name}.body_m", value=list(spec.body_m))
    taken = np.zeros((layout.rows, layout.cols), dtype=bool)
    is_parking = layout.grid == CellType.PARKING
    entries: list[tuple[int, int, str, Cell | None]] = []  # (group, index, type, start)
    for gi, group in enumerate(fleet.agvs):
        for j in range(group.count):
            entries.append((gi, j, group.type, tuple(group.starts[j]) if group.starts else None))
    anchors: dict[int, Cell] = {}
    # Explicit starts first, then the biggest footprints pick parking spots first.
    order = sorted(range(len(entries)), key=lambda i: (entries[i][3] is None,
                                                       -fleet.types[entries[i][2]].footprint, i))
    for idx in order:
        gi, j, tname, start = entries[idx]
        spec = fleet.types[tname]
        k = spec.footprint
        graph = graphs.get(k, False)
        if start is not None:
            r, c = start
            if not graph.is_enterable(start) or taken[r:r + k, c:c + k].any():
                raise ScenarioError(f"start is blocked or overlaps another AGV (footprint {k})",
                                    file=src, field=f"fleet.agvs[{gi}].starts[{j}]",
                                    value=list(start))
        else:
            spots = _window(is_parking & ~taken, k)
            found = np.argwhere(spots & graph.valid)
            if len(found) == 0:
                raise LayoutError(f"no free {k}x{k} parking spot for AGV {j + 1} of "
                                  f"{fleet.agvs[gi].count} (type {tname!r}); add parking "
                                  "or give starts", file=src, field=f"fleet.agvs[{gi}].count",
                                  value=fleet.agvs[gi].count)
            start = (int(found[0][0]), int(found[0][1]))
            r, c = start
        taken[r:r + k, c:c + k] = True
        anchors[idx] = start
    agvs = []
    for idx, (_, _, tname, _) in enumerate(entries):
        spec = fleet.types[tname]
        node = anchors[idx][0] * layout.cols + anchors[idx][1]
        agvs.append(Agv(id=idx, type_name=tname, spec=spec,
                        ticks_per_move=spec.ticks_per_move(cell_m, tick_s), home=node,
                        pos=(node, node)))
    return agvs


def _window(mask: np.ndarray, k: int) -> np.ndarray:
    from .planning.graph import _window_all
    return _window_all(mask, k)


def check_layout(scenario: Scenario, layout: Layout, graphs: GraphSet, agvs: list[Agv]) -> None:
    """Every station, shelf and parking cell must be reachable by the AGVs that need it.

    Raises :class:`LayoutError` naming the field and the cell that fails.
    """
    src = scenario.source
    fleet = scenario.fleet
    types_used = {a.type_name for a in agvs}
    start_of = {t: next(a for a in agvs if a.type_name == t) for t in types_used}
    shelf_sizes = sorted({s.size for s in layout.shelves})
    for size in shelf_sizes:
        if not any(can_carry(fleet.types[t], size) for t in types_used):
            raise LayoutError(f"no AGV type can carry the layout's size-{size} shelves "
                              f"(needs footprint {size} and cargo_class >= {size})", file=src,
                              field="fleet.types", value=sorted(types_used))
    for tname in sorted(types_used, key=lambda t: -fleet.types[t].footprint):
        spec = fleet.types[tname]
        k = spec.footprint
        where = f"fleet.types.{tname}.footprint"
        start = start_of[tname]
        unloaded, loaded = graphs.get(k, False), graphs.get(k, True)
        reach = unloaded.reachable_from(layout_cell(layout, start.node))
        for a in agvs:
            if a.type_name == tname and not reach[layout_cell(layout, a.node)]:
                raise LayoutError(f"AGVs of type {tname!r} start in disconnected areas "
                                  f"({layout_cell(layout, start.node)} and "
                                  f"{layout_cell(layout, a.node)})", file=src, field=where,
                                  value=k)
        carries_any = any(can_carry(spec, s) for s in shelf_sizes)
        for i, station in enumerate(layout.stations):
            anchor = loaded.goal_anchor(station) if carries_any else unloaded.goal_anchor(station)
            if anchor is None or not reach[anchor]:
                # Too big for the aisles, or a station nobody can reach?
                too_big = k > 1 and bool(graphs.get(1, False).reachable_from(
                    layout_cell(layout, start.node))[station])
                raise LayoutError(f"station {list(station)} cannot be reached by a {k}x{k} "
                                  f"AGV of type {tname!r} from its start", file=src,
                                  field=where if too_big else f"layout.stations[{i}]",
                                  value=k if too_big else list(station))
        for shelf in layout.shelves:
            if not can_carry(spec, shelf.size):
                continue
            if not reach[shelf.anchor]:
                raise LayoutError(f"shelf {shelf.id} at {list(shelf.anchor)} cannot be reached "
                                  f"by a {k}x{k} AGV of type {tname!r}", file=src,
                                  field=_shelf_field(scenario, shelf.anchor),
                                  value=list(shelf.anchor))
            carrying = graphs.get(k, True, shelf.id)
            for station in layout.stations:
                target = loaded.goal_anchor(station)
                if target is None or carrying.distance(shelf.anchor, target) >= UNREACHABLE:
                    raise LayoutError(f"a loaded {k}x{k} AGV cannot bring shelf {shelf.id} at "
                                      f"{list(shelf.anchor)} to station {list(station)}: the "
                                      "aisles are blocked or too narrow", file=src, field=where,
                                      value=k)
    small = graphs.get(1, False)
    first = layout_cell(layout, agvs[0].node)
    reach1 = small.reachable_from(first)
    for r, c in layout.parking:
        if not reach1[r, c]:
            raise LayoutError("parking cell cannot be reached", file=src,
                              field="layout.parking", value=[r, c])


def _shelf_field(scenario: Scenario, anchor: Cell) -> str:
    """The field of the scenario a shelf came from, for error messages."""
    spec = scenario.layout
    for i, block in enumerate(spec.shelf_blocks):
        r0, c0 = block.origin
        if r0 <= anchor[0] < r0 + block.rows * block.size and \
                c0 <= anchor[1] < c0 + block.cols * block.size:
            return f"layout.shelf_blocks[{i}]"
    if spec.grid is not None:
        return f"layout.grid[{anchor[0]}]"
    if spec.generator is not None:
        return "layout.generator"
    return "layout.shelf_blocks"


def layout_cell(layout: Layout, node: int) -> Cell:
    return divmod(node, layout.cols)
