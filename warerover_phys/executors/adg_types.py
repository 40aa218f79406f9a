"""The records of the action dependency graph (:mod:`.adg`): actions, visits, the per-AGV
state, and how a timed path becomes actions (:func:`path_moves`)."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from ..planning.base import TimedPath

__all__ = ["ADGCycleError", "Action", "Visit", "path_moves"]


class ADGCycleError(ValueError):
    """The dependency graph has a cycle (or a visit that is never left): no execution order
    exists. ``agvs`` and ``cells`` (``(row, col)``) name the AGVs and cells on the cycle."""

    def __init__(self, message: str, agvs: tuple[int, ...] = (),
                 cells: tuple[tuple[int, int], ...] = ()) -> None:
        super().__init__(message)
        self.agvs = agvs
        self.cells = cells


@dataclass(frozen=True, slots=True)
class Action:
    """One cell move of one AGV."""

    agv: int
    seq: int
    """Unique and increasing per AGV, across replans."""
    src: int
    dst: int
    tick: int
    """Planned start tick: the last tick the AGV stands at ``src`` before moving."""
    ticks: int
    """Planned duration (the AGV stands at ``dst`` at ``tick + ticks``)."""
    enters: tuple[int, ...]
    leaves: tuple[int, ...]
    direction: tuple[int, int]
    """``(drow, dcol)``."""
    sweeps: tuple[int, ...] = ()
    """Cells the AGV's turn in place before this move sweeps, and its turn locks as
    negative keys ``-1 - anchor`` (empty: no turn, or a body whose turn cannot touch
    another AGV's)."""


@dataclass(frozen=True, slots=True)
class Visit:
    """A read-only snapshot of one queue entry (see :meth:`ActionGraph.visits`)."""

    agv: int
    enter: int | None
    """``seq`` of the entering action; ``None`` for a cell held since registration."""
    leave: int | None
    """``seq`` of the leaving action; ``None`` while the AGV's plan ends on the cell."""
    tick: int
    """Planned enter tick: the first tick the AGV occupies the cell."""
    entered: bool


@dataclass(slots=True, eq=False)
class _Visit:
    cell: int
    agv: int
    enter: Action | None
    leave: Action | None
    tick: int
    order: int
    entered: bool
    claimed: bool = False
    """The AGV is committed to drive through this cell (see :meth:`ActionGraph.claim`)."""
    sweep: bool = False
    """A turn's swept cell: entered and left by the same action."""
    shelf: bool = False
    """A turn's *shelf* sweep visit: holds back only AGVs that carry a shelf."""


@dataclass(slots=True, eq=False)
class _Step:
    action: Action
    enter_visits: list[_Visit]
    leave_visits: list[_Visit]
    claimed: bool = False


@dataclass(slots=True, eq=False)
class _Agent:
    k: int
    node: int
    """Anchor after the last finished action."""
    held: dict[int, _Visit]
    """Visits the AGV physically holds (entered, not yet left), by cell."""
    pending: deque[_Step]
    running: _Step | None = None
    next_seq: int = 0
    heading: tuple[int, int] | None = None
    """Direction the AGV faces after its finished actions (None: unknown)."""
    last_tick: int | None = None
    """Planned tick at which the AGV stands at ``node`` (the end of its last finished
    action; None: none finished)."""


def path_moves(path: TimedPath, cols: int) -> list[tuple[int, int, int, int]]:
    """The moves of a timed path as ``(src, dst, tick, ticks)``; waits are dropped.

    Raises ``ValueError`` if the path does not start standing, ends mid-move, or has a step
    that is not a wait or a move to a 4-neighbour.

    >>> path_moves(TimedPath(0, 5, ((0, 0), (0, 0), (0, 1), (0, 1), (1, 1), (5, 5))), 4)
    [(0, 1, 6, 3), (1, 5, 9, 1)]
    """
    states = path.states
    if not states or states[0][0] != states[0][1]:
        raise ValueError(f"AGV {path.agv}: a path must start standing, got {states[:1]}")
    cur = states[0][0]
    out: list[tuple[int, int, int, int]] = []
    n, j = len(states), 1
    while j < n:
        a, b = states[j]
        if a == b == cur:
            j += 1
            continue
        if a == cur:
            dst = b
        elif a == b:
            dst = a
        else:
            raise ValueError(f"AGV {path.agv}: state {states[j]} at tick "
                             f"{path.start_tick + j} does not continue from anchor {cur}")
        _direction(cur, dst, cols, path.agv)
        t0 = path.start_tick + j - 1
        while j < n and states[j] == (cur, dst):
            j += 1
        if j == n or states[j] != (dst, dst):
            raise ValueError(f"AGV {path.agv}: the move {cur} -> {dst} from tick {t0} "
                             "does not end standing at its destination")
        out.append((cur, dst, t0, path.start_tick + j - t0))
        cur = dst
        j += 1
    return out


def _direction(src: int, dst: int, cols: int, agv: int) -> tuple[int, int]:
    (r0, c0), (r1, c1) = divmod(src, cols), divmod(dst, cols)
    if abs(r1 - r0) + abs(c1 - c0) != 1:
        raise ValueError(f"AGV {agv}: {divmod(src, cols)} -> {divmod(dst, cols)} is not a "
                         "move to a 4-neighbour")
    return (r1 - r0, c1 - c0)
