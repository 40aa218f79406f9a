"""Ideal grid executor: AGVs jump from state to state exactly as planned.

An AGV whose next cells are held by an AGV that stays (or is itself blocked) waits: that is a
*blocked move*, counted apart from collisions, and the AGV falls one tick behind its plan.
Moves that overlap another AGV anyway (two AGVs entering the same free cell, or passing
through each other) are carried out and counted as *collisions*; a valid plan has none.
"""

from __future__ import annotations

from typing import Any

from ..planning.paths import State, occupancy
from .base import ExecutorSetup, StepReport, TickView

__all__ = ["GridExecutor"]


class GridExecutor:
    """Ideal discrete execution (see the module docstring). Keeps only where each AGV is."""

    name = "grid"

    def __init__(self, spec: Any = None) -> None:
        self.spec = spec

    def bind(self, setup: ExecutorSetup) -> None:
        self.cols = setup.layout.cols
        self.k = {a.id: a.k for a in setup.agvs}
        self.pos: dict[int, State] = {a.id: a.start for a in setup.agvs}

    def remaining(self, agv: int) -> list[State]:
        return []  # it follows the committed path exactly

    def stop_short(self, agv: int, cells: frozenset[int], view: TickView) -> tuple[bool, bool]:
        return False, False  # the loop cuts the committed path after the move under way

    def summary(self) -> dict[str, Any]:
        return {}

    def trajectory(self) -> None:
        return None

    def step(self, view: TickView) -> StepReport:
        cols, t = self.cols, view.tick
        pos, ks, paths = self.pos, self.k, view.plans
        now = {i: occupancy(p, ks[i], cols) for i, p in pos.items()}
        want = {}
        for i, p in pos.items():
            path = paths.get(i)
            want[i] = p if path is None else path.state_at(t + 1 - view.behind[i])
        holder: dict[int, int] = {}
        for aid, cells in now.items():
            for c in cells:
                holder[c] = aid
        moving = {aid for aid, s in want.items() if s != pos[aid]}
        nxt = {aid: occupancy(want[aid], ks[aid], cols) for aid in moving}
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
        report = StepReport(blocked=sorted(blocked), intrusion_unit="cells")
        after: dict[int, set[int]] = {}
        for i in pos:
            if i in moving and i not in blocked:
                pos[i] = want[i]
            elif i in blocked:
                report.behind[i] = view.behind[i] + 1
        for i, p in pos.items():
            after[i] = set(occupancy(p, ks[i], cols))
        report.states = dict(pos)
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
