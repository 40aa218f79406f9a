"""The planner interface: a request goes in, timed paths come out.

A timed path lists one *state* per tick from ``start_tick`` on. A state is a pair of anchor
nodes ``(a, b)``: ``a == b`` means the AGV stands at ``a``; ``a != b`` means it is moving from
``a`` to ``b`` and occupies both footprints (slow AGVs take several ticks per cell). After its
last state the AGV stays where it is.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from .graph import GraphSet
from .paths import State, TimedPath, footprint_nodes, occupancy
from .reservation import ReservationTable
from .sweep import EAST, Sweep

__all__ = ["State", "TimedPath", "AgentRequest", "PlanRequest", "PlanResult", "Planner",
           "footprint_nodes", "occupancy"]


@dataclass(frozen=True, slots=True)
class AgentRequest:
    """One AGV to plan: where it stands now, where it must go, and what it is."""

    agv: int
    start: int
    goal: int
    k: int = 1
    loaded: bool = False
    ticks_per_move: int = 1
    shelf: int | None = None
    """The shelf it carries (if loaded): bigger AGVs may use that shelf's own cells."""
    priority: tuple = ()
    """Sort key: lower is planned first (lifelong PIBT: ticks since the goal was set)."""
    hold: bool = False
    """The AGV works in place this tick and must not move (step planners only)."""
    heading: tuple[int, int] | None = EAST
    """``(drow, dcol)`` it faces (the direction of its last move; east as AGVs are placed;
    None: unknown, its first move counts as a turn). Read only for turn-aware AGVs (see
    :func:`~warerover_phys.planning.sweep.turn_aware`)."""
    sweep: Sweep | None = None
    """What its turns in place hold (:func:`~warerover_phys.planning.sweep.agv_sweeps`):
    cells that must be free of other AGVs at the turn's tick and the next, and turn locks
    no other turn at the same tick may share. None: its turns hold nothing."""
    no_turn: frozenset[int] = frozenset()
    """Anchors where it must not turn in place (its swept disc reaches an obstacle or the
    map edge: :func:`~warerover_phys.planning.sweep.no_turn_anchors`; while loaded, also
    another shelf: :class:`~warerover_phys.planning.sweep.TurnMasks`)."""
    turn_ticks: tuple[int, int] | None = None
    """Rotation-aware planning (``planner.rotations``, differential-drive AGVs): ticks of a
    quarter and of a half turn in place (:func:`~warerover_phys.planning.rotation.
    agent_turn_ticks`); the AGV then moves only along ``heading`` and the returned path
    carries headings. None: turns are free."""
    goal_dead: frozenset[int] | None = None
    """Headings (direction indices, :data:`~warerover_phys.planning.sweep.DIR_OF`) it must
    not arrive at its goal in: after its work there (loaded or not) it could never turn to
    leave. None: those it would be stuck in as it is now."""


@dataclass
class PlanRequest:
    tick: int
    agents: list[AgentRequest]
    graphs: GraphSet
    reservations: ReservationTable
    """Committed paths of every AGV: the planner's own copy, to read and to use as scratch
    space (prioritized planners commit each new path into it before planning the next).
    Nothing written here reaches the world: the loop commits the paths the planner
    *returns* in :attr:`PlanResult.paths`."""
    rng: np.random.Generator | None = None
    keep_clear: np.ndarray | None = None
    """Flat bool mask of cells where no AGV should wait (e.g. every station's footprint for
    every AGV size): planners must not park AGVs there to queue."""
    deadline: float | None = None
    """``time.monotonic()`` value after which the planner should stop planning more AGVs."""
    acyclic: bool = False
    """The executor follows an action dependency graph (physics): an AGV enters a cell only
    after the AGV before it has left, so moves that form a cycle within one tick (AGVs
    rotating into each other's cells) would wait for each other for ever. Step planners
    (PIBT) then plan no such cycle."""


@dataclass
class PlanResult:
    paths: dict[int, TimedPath] = field(default_factory=dict)
    failed: list[int] = field(default_factory=list)
    """AGVs without a new path (they keep their old one and retry)."""
    detours: list[int] = field(default_factory=list)
    """AGVs sent to wait near a goal that another AGV holds (a path is in ``paths``)."""
    expansions: int = 0
    budget_hits: int = 0
    """Times a planner ran out of its node / time budget and used its documented fallback."""


@runtime_checkable
class Planner(Protocol):
    """Plans timed paths for the AGVs of a request and returns them.

    ``replans_all``: True for step planners (PIBT, LaCAM) that want every AGV every tick;
    False for planners called only for AGVs that need a new path.
    """

    name: str
    replans_all: bool

    def plan(self, request: PlanRequest) -> PlanResult: ...
