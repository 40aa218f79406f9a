"""Timed paths: what a plan is made of.

A timed path lists one *state* per tick from ``start_tick`` on. A state is a pair of anchor
nodes ``(a, b)``: ``a == b`` means the AGV stands at ``a``; ``a != b`` means it is moving from
``a`` to ``b`` and occupies both footprints (slow AGVs take several ticks per cell). After its
last state the AGV stays where it is. Nodes are flat cell indices ``row * cols + col``; a
``k x k`` AGV is anchored at its top-left cell.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

__all__ = ["State", "TimedPath", "footprint_nodes", "occupancy"]

State = tuple[int, int]


@lru_cache(maxsize=1 << 16)
def footprint_nodes(anchor: int, k: int, cols: int) -> tuple[int, ...]:
    """Flat cell indices covered by a ``k x k`` AGV anchored at node ``anchor``."""
    if k == 1:
        return (anchor,)
    return tuple(anchor + i * cols + j for i in range(k) for j in range(k))


def occupancy(state: State, k: int, cols: int) -> tuple[int, ...]:
    """Cells a state covers: the footprint, or both footprints while moving."""
    a, b = state
    if a == b:
        return footprint_nodes(a, k, cols)
    return tuple(dict.fromkeys(footprint_nodes(a, k, cols) + footprint_nodes(b, k, cols)))


@dataclass(frozen=True, slots=True)
class TimedPath:
    agv: int
    start_tick: int
    states: tuple[State, ...]
    headings: tuple[int, ...] | None = None
    """Rotation-aware plans (``planner.rotations``): the heading of every state (direction
    index 0 east, 1 south, 2 west, 3 north; :mod:`~warerover_phys.planning.rotation`);
    None where the plan does not say (turns are then free)."""

    def heading_at(self, tick: int) -> int | None:
        """The planned heading at ``tick`` (held after the last state), or None."""
        if self.headings is None:
            return None
        i = min(max(tick - self.start_tick, 0), len(self.headings) - 1)
        return self.headings[i]

    @property
    def end_tick(self) -> int:
        return self.start_tick + len(self.states) - 1

    def state_at(self, tick: int) -> State:
        i = tick - self.start_tick
        if i < 0:
            return self.states[0]
        return self.states[min(i, len(self.states) - 1)]

    @property
    def goal(self) -> int:
        return self.states[-1][1]
