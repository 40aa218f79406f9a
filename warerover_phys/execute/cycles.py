"""Rotations in a plan: groups of agents that move round a cycle in one timestep
(:func:`find_cycles`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..plans.model import Plan
from .validation import _dense


@dataclass(frozen=True)
class Cycle:
    """Agents that move round a cycle at ``timestep`` (each enters the cell the next one
    leaves), and the cells they occupy just before."""

    timestep: int
    agents: tuple[int, ...]
    cells: tuple[tuple[int, int], ...]


def find_cycles(plan: Plan, cols: int, sizes: list[int] | None = None) -> list[Cycle]:
    """Every rotation of ``plan`` (1x1 footprints; a bigger footprint's rotation needs a
    vertex conflict and is rejected by :func:`validate_plan`)."""
    return _cycles_dense(_dense(plan), cols)


def _cycles_dense(pos: np.ndarray, cols: int, start: int = 0) -> list[Cycle]:
    """The rotations of the dense plan ``pos`` (T, N, 2) at rows after ``start``."""
    if len(pos) - start < 2:
        return []
    anchors = pos[..., 0] * cols + pos[..., 1]
    out = []
    moving = (anchors[start + 1:] != anchors[start:-1]).any(axis=1)
    for t in np.flatnonzero(moving) + start:
        before, after = anchors[t], anchors[t + 1]
        moved = np.flatnonzero(before != after)
        at = {int(before[a]): int(a) for a in moved}
        nxt = {int(a): at.get(int(after[a])) for a in moved}  # whose cell a enters
        seen: set[int] = set()
        for a0 in nxt:
            if a0 in seen:
                continue
            chain, a = [], a0
            while a is not None and a not in seen and a not in chain:
                chain.append(a)
                a = nxt.get(a)
            seen.update(chain)
            if a is not None and a in chain:
                cyc = tuple(chain[chain.index(a):])
                out.append(Cycle(int(t + 1), cyc,
                                 tuple(tuple(map(int, pos[t, i])) for i in cyc)))
    return out
