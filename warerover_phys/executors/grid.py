"""Ideal grid executor: AGVs jump from state to state exactly as planned.

An AGV whose next cells are held by an AGV that stays (or is itself blocked) waits: that is a
*blocked move*, counted apart from collisions, and the AGV falls one tick behind its plan.
Moves that overlap another AGV anyway (two AGVs entering the same free cell, or passing
through each other) are carried out and counted as *collisions*; a valid plan has none.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..planning.base import occupancy
from .base import StepReport

if TYPE_CHECKING:
    from ..world import World

__all__ = ["GridExecutor"]


class GridExecutor:
    name = "grid"

    def step(self, world: World) -> StepReport:
        cols, t = world.layout.cols, world.tick
        agvs = world.agvs
        paths = world.reservations.paths
        now = {a.id: occupancy(a.pos, a.k, cols) for a in agvs}
        want = {}
        for a in agvs:
            path = paths.get(a.id)
            want[a.id] = a.pos if path is None else path.state_at(t + 1 - a.delay)
        holder: dict[int, int] = {}
        for aid, cells in now.items():
            for c in cells:
                holder[c] = aid
        moving = {aid for aid, s in want.items() if s != agvs[aid].pos}
        nxt = {aid: occupancy(want[aid], agvs[aid].k, cols) for aid in moving}
        blocked: set[int] = set()
        changed = True
        while changed:  # a blocked AGV stays, which may block the AGV behind it
            changed = False
            for aid in sorted(moving - blocked):
                for c in nxt[aid]:
                    other = holder.get(c)
                    if other is None or other == aid:
                        continue
                    if other not in moving or other in blocked or c in nxt[other]:
                        blocked.add(aid)
                        changed = True
                        break
        report = StepReport(blocked=sorted(blocked))
        after: dict[int, set[int]] = {}
        for a in agvs:
            if a.id in moving and a.id not in blocked:
                a.pos = want[a.id]
            elif a.id in blocked:
                a.delay += 1
        for a in agvs:
            after[a.id] = set(occupancy(a.pos, a.k, cols))
        owner: dict[int, int] = {}
        for aid, cells in after.items():
            for c in cells:
                if c in owner:
                    report.collisions += 1
                else:
                    owner[c] = aid
        moved = sorted(moving - blocked)
        for i, p in enumerate(moved):
            for q in moved[i + 1:]:
                if after[p] & set(now[q]) and after[q] & set(now[p]) and not after[p] & after[q]:
                    report.collisions += 1
        return report
