"""Freeze detector: AGVs that make no progress while nothing they wait on can still move.

A dependency cycle is one kind of freeze; others have no cycle at all: a livelock (two AGVs
that keep swapping places around a corner and never get nearer their goals) or a permanent
stand-still (an AGV whose replans always put it back behind the same queue head). Each
ends as a failed episode with nothing reported unless it is looked for.

Per AGV with a goal (``goals[i]`` not None), *progress* is: its goal changed, it stands on
its goal, it is working in place or failed, or its anchor came nearer its goal (Manhattan
distance, in cells) than ever since the goal was set. An AGV is *stuck* after
``freeze_ticks`` ticks without progress. A stuck AGV is *frozen* when nothing it waits on
(``waits_on``: the action dependency graph's wait-for edges,
:meth:`~warerover_phys.executors.adg.ActionGraph.waiting_for`) can still move: every AGV it
waits on is frozen too, or has no goal and no work (it stays where it is). An AGV waiting on a failed
AGV is not frozen: that is a fault, and the repair (or the corridor's replans) ends it.
Frozen AGVs are reported in groups (connected through their wait-for edges), once: a
reported AGV counts as having progressed at the report, so it is reported again only after
another ``freeze_ticks`` without progress.

The executor runs the detector and reports each :class:`Freeze` in its
:class:`~warerover_phys.executors.base.StepReport`; the loop counts it as a deadlock, logs
it (``freeze`` event) and replans the AGVs from where they stand.

>>> det = FreezeDetector(n=2, cols=10, freeze_ticks=3)
>>> for tick in range(1, 5):
...     found = det.update(tick, nodes=[0, 1], goals=[5, 9], busy=[False, False],
...                        failed=[False, False], waits_on={0: {1}, 1: {0}})
>>> found
[Freeze(agvs=(0, 1), since_tick=1, waits={0: (1,), 1: (0,)})]
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["Freeze", "FreezeDetector"]


@dataclass(frozen=True)
class Freeze:
    """A group of AGVs found frozen."""

    agvs: tuple[int, ...]
    since_tick: int
    """The earliest tick of the group's last progress."""
    waits: Mapping[int, tuple[int, ...]]
    """Who waits on whom (wait-for edges of the group's AGVs)."""


class FreezeDetector:
    """Tracks each AGV's progress towards its goal (see the module docstring)."""

    def __init__(self, n: int, cols: int, freeze_ticks: int) -> None:
        if freeze_ticks < 1:
            raise ValueError(f"freeze_ticks must be >= 1 (got {freeze_ticks})")
        self.cols, self.freeze_ticks = cols, freeze_ticks
        self.goal = np.full(n, -1, dtype=np.int64)
        self.best = np.full(n, np.iinfo(np.int64).max, dtype=np.int64)
        self.last = np.zeros(n, dtype=np.int64)
        """Tick of each AGV's last progress."""

    def update(self, tick: int, nodes: Sequence[int], goals: Sequence[int | None],
               busy: Sequence[bool], failed: Sequence[bool],
               waits_on: Mapping[int, set[int] | frozenset[int]]
               | Callable[[], Mapping[int, set[int] | frozenset[int]]]) -> list[Freeze]:
        """Record the state at the end of ``tick`` and return the groups newly frozen.

        ``nodes``: each AGV's anchor (the cell it stands on or drives to); ``goals``: its
        goal anchor, None without one; ``busy``: working in place (it will move again);
        ``failed``: down; ``waits_on``: the wait-for edges, or a function that returns them
        (called only when some AGV is stuck)."""
        cols = self.cols
        active = np.zeros(len(nodes), dtype=bool)
        for i, (node, goal) in enumerate(zip(nodes, goals, strict=True)):
            if goal is None or busy[i] or failed[i]:
                self.goal[i] = -1
                self.last[i] = tick
                continue
            if goal != self.goal[i]:
                self.goal[i], self.best[i], self.last[i] = goal, np.iinfo(np.int64).max, tick
            (r, c), (gr, gc) = divmod(node, cols), divmod(goal, cols)
            d = abs(r - gr) + abs(c - gc)
            if d == 0 or d < self.best[i]:
                self.best[i], self.last[i] = d, tick
            active[i] = d > 0
        stuck = active & (tick - self.last >= self.freeze_ticks)
        if not stuck.any():
            return []
        if callable(waits_on):
            waits_on = waits_on()
        frozen = {int(i) for i in np.flatnonzero(stuck)}
        changed = True
        while changed:  # drop AGVs that wait on one that can still move (or is down)
            changed = False
            for i in sorted(frozen):
                for b in waits_on.get(i, ()):
                    if failed[b] or busy[b] or (active[b] and b not in frozen):
                        frozen.discard(i)
                        changed = True
                        break
        groups = _components(frozen, waits_on)
        out = []
        for group in groups:
            agvs = tuple(sorted(group))
            out.append(Freeze(agvs, int(self.last[list(agvs)].min()),
                              {i: tuple(sorted(waits_on.get(i, ()))) for i in agvs}))
            self.last[list(agvs)] = tick
        return out


def _components(members: set[int], edges: Mapping[int, set[int] | frozenset[int]]
                ) -> list[set[int]]:
    """Groups of ``members`` connected through ``edges`` (either direction)."""
    adj: dict[int, set[int]] = {i: set() for i in members}
    for i in members:
        for b in edges.get(i, ()):
            if b in members:
                adj[i].add(b)
                adj[b].add(i)
    seen: set[int] = set()
    out = []
    for i in sorted(members):
        if i in seen:
            continue
        comp, stack = set(), [i]
        while stack:
            j = stack.pop()
            if j in comp:
                continue
            comp.add(j)
            stack.extend(adj[j] - comp)
        seen |= comp
        out.append(comp)
    return out
