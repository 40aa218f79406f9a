"""Handing the loop's plans to the action dependency graph: which plans changed, where each
is cut (the commit cut: from where the AGV will stand after its running and claimed
actions), and the dwells each new plan holds its actions back for. A mixin of
:class:`~.follow.PlanFollower` (its state is the follower's)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..planning.base import TimedPath

if TYPE_CHECKING:
    from .base import TickView

__all__ = ["PlanSync"]


class PlanSync:
    """The plan-sync half of :class:`~.follow.PlanFollower`."""

    def sync_plans(self, view: TickView) -> None:
        paths, synced = view.plans, self._synced
        changed = [i for i, path in paths.items()
                   if path is not None and path is not synced.get(i, path)]
        if not changed:
            return
        changed.sort()
        # The fleet's first plans go to the ADG in one batch (see ActionGraph.begin_bulk).
        bulk = len(changed) > 1 and self.adg.begin_bulk()
        try:
            for i in changed:
                self._sync_one(i, paths[i], view)
        finally:
            if bulk:
                self.adg.end_bulk()
        if self._given_back:
            # New visits may now be ahead of the cells they gave back (or their own plan
            # dropped them): they stop at the end of their claims.
            self.reorder.stop_at_claims(sorted(self._given_back))

    def _sync_one(self, i: int, path: TimedPath, view: TickView) -> None:
        """Hand AGV ``i``'s new plan ``path`` to the ADG (commit cut)."""
        self._synced[i] = path
        cut = self._cut(i, path, view.tick)
        node = cut.states[0][0]
        self._face.pop(i, None)
        heads = path.headings
        if self._turn_in_place_on and heads and len(set(heads)) > 1 \
                and not self.st.omni[i] \
                and all(a == b == node for a, b in path.states) \
                and not self.adg.turn_sweeps(i):
            self._face[i] = int(heads[-1]) % 4
        if all(a == b == node for a, b in cut.states) and self.synced_once(i) \
                and self.adg.next_action(i) is None:
            return  # a plan to stay where it will stop anyway: nothing changes
        self.adg.set_plan(i, cut)
        self.st.has_next[i] = self.adg.next_action(i) is not None
        self._set_holds(i, view.dwells.get(i, ()))

    def _set_holds(self, i: int, dwells: tuple[tuple[int, int], ...]) -> None:
        """Map the dwells ``(tick, ticks)`` of AGV ``i``'s new plan to the actions they hold
        back: the first action that starts at or after the dwell's first tick. A dwell the
        AGV already stands in (before its next action) holds from its last arrival."""
        holds: dict[int, int] = {}
        if dwells:
            acts = self.adg.upcoming(i)
            j = 0
            for tick, ticks in sorted(dwells):
                while j < len(acts) and acts[j].tick < tick:
                    j += 1
                if j == len(acts):
                    break
                holds[acts[j].seq] = holds.get(acts[j].seq, 0) + int(ticks)
        if holds or i in self._holds:
            self._holds[i] = holds
        nxt = self.adg.next_action(i)
        if nxt is not None and self.adg.current(i) is None and nxt.seq in holds:
            st = self.st
            st.hold_until[i] = max(st.hold_until[i],
                                   st.last_finish[i] + holds[nxt.seq] * st.tick_s)

    def _cut(self, i: int, path: TimedPath, tick: int) -> TimedPath:
        """The part of ``path`` from where the AGV will stand after its current action.

        A path that starts before ``tick`` (a late plan spliced behind the prefix the AGV
        still had to drive) may stand at that node more than once (a PIBT side step and
        back): it is cut at the last such standing no later than the AGV's progress in
        the plan's ticks (:meth:`~.adg.ActionGraph.cut_tick`), so that neither a step still
        to drive is skipped nor one already driven is driven again."""
        after = None
        if self.synced_once(i):
            node = self.adg.cut_node(i)
            if path.start_tick < tick:
                after = self.adg.cut_tick(i)
        else:
            node = path.states[0][0]
        first = None
        for j, (a, b) in enumerate(path.states):
            if a == b == node:
                if first is None:
                    first = j
                    if after is None:
                        break
                if path.start_tick + j > after:
                    break
                first = j
        if first is not None:
            return TimedPath(i, path.start_tick + first, path.states[first:])
        # The plan does not pass where the AGV will stop (it was made from a stale view):
        # stop there and ask for a new plan.
        self._resync.add(i)
        return TimedPath(i, path.start_tick, ((node, node),))

    def synced_once(self, i: int) -> bool:
        """Whether AGV ``i`` has had a plan handed to the ADG."""
        try:
            self.adg.state(i)
        except KeyError:
            return False
        return True
