"""Independent validator of timed paths and executed trajectories.

It shares no code with the planners: it rebuilds every AGV's occupied cells per tick from
scratch and reports

- ``bounds`` / ``obstacle``: a footprint cell outside the grid or on an obstacle;
- ``move``: a step that is not a wait or a move to a 4-neighbour, or a slow AGV's move that
  does not take exactly its ``ticks_per_move`` ticks;
- ``vertex``: two AGVs' occupied cells overlap at a tick (footprints included);
- ``swap``: two AGVs pass through each other between two ticks.

A state per tick is ``(a, b)`` of flat anchor indices (``row * cols + col``): standing at
``a`` if equal, else moving from ``a`` to ``b`` and covering both footprints. After its last
state an AGV stays where it is.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["Conflict", "validate_states"]


@dataclass(frozen=True, slots=True)
class Conflict:
    kind: str
    tick: int
    agvs: tuple[int, ...]
    cell: tuple[int, int] | None = None

    def __str__(self) -> str:
        where = f" at {self.cell}" if self.cell is not None else ""
        return f"{self.kind} conflict at tick {self.tick} between AGVs {self.agvs}{where}"


def _cells(anchor: int, k: int, cols: int) -> set[tuple[int, int]]:
    r, c = divmod(anchor, cols)
    return {(r + i, c + j) for i in range(k) for j in range(k)}


def validate_states(trajectories: Mapping[int, Sequence[tuple[int, int]]],
                    obstacles: np.ndarray, *, sizes: Mapping[int, int] | None = None,
                    ticks_per_move: Mapping[int, int] | None = None, start_tick: int = 0,
                    max_conflicts: int = 100) -> list[Conflict]:
    """Check per-tick states of every AGV; return at most ``max_conflicts`` conflicts."""
    rows, cols = obstacles.shape
    sizes = sizes or {}
    speeds = ticks_per_move or {}
    horizon = max((len(s) for s in trajectories.values()), default=0)
    out: list[Conflict] = []

    def at(agv: int, i: int) -> tuple[int, int]:
        states = trajectories[agv]
        return tuple(states[min(i, len(states) - 1)])

    def occupied(agv: int, i: int) -> set[tuple[int, int]]:
        a, b = at(agv, i)
        k = sizes.get(agv, 1)
        return _cells(a, k, cols) | (_cells(b, k, cols) if a != b else set())

    for agv, states in trajectories.items():
        m = speeds.get(agv, 1)
        # Ticks spent in the current move; unknown if the window starts mid-move.
        transit: int | None = None if states and states[0][0] != states[0][1] else 0
        for i, (a, b) in enumerate(states):
            for r, c in _cells(a, sizes.get(agv, 1), cols) | _cells(b, sizes.get(agv, 1), cols):
                if not (0 <= r < rows and 0 <= c < cols):
                    out.append(Conflict("bounds", start_tick + i, (agv,), (r, c)))
                elif obstacles[r, c]:
                    out.append(Conflict("obstacle", start_tick + i, (agv,), (r, c)))
            if a != b:
                ra, ca = divmod(a, cols)
                rb, cb = divmod(b, cols)
                if abs(ra - rb) + abs(ca - cb) != 1:
                    out.append(Conflict("move", start_tick + i, (agv,), (rb, cb)))
            if i == 0:
                continue
            pa, pb = states[i - 1]
            if (pa, pb) == (a, b) and a != b:
                transit = None if transit is None else transit + 1
            elif pa == pb and a != b and a == pa:
                transit = 1
            elif pa != pb and a == b == pb:
                if transit is not None and transit != m - 1:
                    out.append(Conflict("move", start_tick + i, (agv,), divmod(b, cols)))
                transit = 0
            elif pa == pb and a == b:
                if a != pa:
                    ra, ca = divmod(a, cols)
                    rp, cp = divmod(pa, cols)
                    if abs(ra - rp) + abs(ca - cp) != 1 or m != 1:
                        out.append(Conflict("move", start_tick + i, (agv,), (ra, ca)))
            else:
                out.append(Conflict("move", start_tick + i, (agv,), divmod(b, cols)))
    ids = sorted(trajectories)
    for i in range(horizon):
        owner: dict[tuple[int, int], int] = {}
        for agv in ids:
            for cell in occupied(agv, i):
                other = owner.get(cell)
                if other is not None:
                    out.append(Conflict("vertex", start_tick + i, (other, agv), cell))
                else:
                    owner[cell] = agv
        if i == 0:
            continue
        moved = [agv for agv in ids if at(agv, i) != at(agv, i - 1)]
        before = {agv: occupied(agv, i - 1) for agv in moved}
        after = {agv: occupied(agv, i) for agv in moved}
        for x, p in enumerate(moved):
            for q in moved[x + 1:]:
                if after[p] & before[q] and after[q] & before[p] \
                        and not after[p] & after[q] and not before[p] & before[q]:
                    out.append(Conflict("swap", start_tick + i, (p, q)))
        if len(out) >= max_conflicts:
            break
    return out[:max_conflicts]
