"""Action Dependency Graph (Hoenig et al. 2019): execute timed plans without a clock.

A timed path is cut into *actions*, one per cell move (waits are dropped; the several ticks
of a slow AGV's move are one action). An action from anchor ``src`` to anchor ``dst``
*enters* the footprint cells of ``dst`` that ``src`` does not cover and *leaves* the cells of
``src`` that ``dst`` does not cover.

Dependencies are kept per cell, never between all pairs of actions. Each cell has a queue of
*visits* ``(agv, entering action, leaving action, planned enter tick)`` ordered by planned
enter tick (ties: first inserted stays first). The visits an AGV physically holds (the cells
it stands on when its first plan is set, and cells entered by started actions) are always at
the head of their queues. An action may start when, for every cell it enters, its own visit
is at the head; a visit leaves its queue when its leaving action *finishes* (the AGV has
arrived at ``dst``). An AGV's own actions run one after the other (type-1 edges, implicit);
the per-cell order gives the type-2 edges ``leave(previous visit) -> enter(next visit)``.

Turns in place (fault 2 of issue 13). A differential-drive AGV whose body sweeps beyond its
footprint when it turns (``sweeps``: per AGV a
:class:`~warerover_phys.planning.sweep.Sweep`, the cells a turn must hold and the turn locks
it takes, offsets from its anchor) turns before every move whose direction differs from its
heading. Such a move also *sweeps* those cells and locks (:attr:`Action.sweeps`; a lock of
anchor ``a`` is the queue key ``-1 - a``, which no cell uses): it gets a visit in each of
their queues, planned at the tick it starts (the turn happens then), entered when it starts
and left when it finishes. So the turn waits for every AGV planned on those cells (and every
overlapping turn planned) before it, and every one planned there after it waits for the
turn. The executor turns such an AGV only once the move is ready. A planner
that keeps the swept cells free of other AGVs at the turn's tick and the next one (as
:func:`warerover_phys.planning.sweep_checks.sweep_conflicts` checks) gets only edges that go
strictly forward in planned time from them, so they add no cycle.

Carried shelves. The cells a turn's disc reaches only through the shelf a neighbour may
carry (:attr:`~warerover_phys.planning.sweep.Sweep.shelf_cells`) get *shelf* sweep visits:
they order the turn only against AGVs that carry a shelf. The executor tells the graph
who carries one (:meth:`ActionGraph.set_loaded`; an AGV it was never told about counts as
loaded). A visit ahead of another in a queue does not hold it back when one of the two is
a shelf sweep visit and the other's AGV carries no shelf now (or both are shelf sweep
visits): an unloaded AGV drives past a turn's shelf cells, and a turn goes ahead beside an
unloaded AGV. Loads change only while an AGV dwells, never during a move.

Communication latency (``latency_s``, ``executor.comm_latency_s``): an AGV hears that
another AGV's action finished ``latency_s`` after it did (:attr:`ActionGraph.now` is the
executor's clock). Until then a cell that action left counts as not yet free for the AGV's
next action (:meth:`ActionGraph.ready`, :meth:`ActionGraph.released`), although the queue
says it is (:meth:`ActionGraph.listening`). Its own actions need no message.

>>> from warerover_phys.planning.base import TimedPath
>>> # A 1 x 4 corridor: AGV 0 at cell 1 goes to 3, AGV 1 follows it from 0 to 2.
>>> g = build({0: TimedPath(0, 0, ((1, 1), (2, 2), (3, 3))),
...            1: TimedPath(1, 0, ((0, 0), (1, 1), (2, 2)))}, {0: 1, 1: 1}, cols=4)
>>> g.ready(0), g.ready(1)
(True, False)
>>> g.start(0).enters, g.ready(1)
((2,), False)
>>> g.finish(0).dst, g.ready(1)
(2, True)
"""

from __future__ import annotations

import heapq
import logging
from collections import defaultdict
from collections.abc import Iterable, Mapping
from itertools import islice

from ..planning.base import State, TimedPath
from ..planning.sweep import Sweep
from .adg_build import PlanBuilding, _bulk_key  # noqa: F401 (re-exported)
from .adg_cycles import DeadlockChecks, _prune_acyclic, _sccs  # noqa: F401 (re-exported)
from .adg_types import (  # noqa: F401 (_direction re-exported)
    Action,
    ADGCycleError,
    Visit,
    _Agent,
    _direction,
    _Step,
    _Visit,
    path_moves,
)

__all__ = ["ADGCycleError", "Action", "Visit", "ActionGraph", "build", "path_moves"]

log = logging.getLogger(__name__)


class ActionGraph(PlanBuilding, DeadlockChecks):
    """The per-cell visit queues of every AGV's remaining actions.

    ``sizes`` maps every AGV id to its footprint ``k``. Register an AGV (and later replace
    its remaining plan) with :meth:`set_plan`; drive it with :meth:`ready`, :meth:`start`
    and :meth:`finish`.
    """

    def __init__(self, cols: int, sizes: Mapping[int, int], *,
                 sweeps: Mapping[int, Sweep] | None = None,
                 rows: int | None = None,
                 heading: tuple[int, int] | None = (0, 1),
                 latency_s: float = 0.0) -> None:
        """``sweeps``: per AGV the cells its turns in place hold (offsets from its anchor;
        see the module doc), ``rows`` bounds them (cells outside the grid are dropped);
        ``heading``: the direction every AGV faces when registered (east, as the physics
        executor places them; None: unknown, so its first move counts as a turn);
        ``latency_s``: communication latency (seconds of :attr:`now`) before the other AGVs
        hear that an action finished: a cell it left is free for another AGV's action only
        ``latency_s`` after the finish (see :meth:`listening`)."""
        self.cols = cols
        self.rows = rows
        self._sizes = dict(sizes)
        self._sweeps = {a: o for a, o in (sweeps or {}).items()
                        if o.cells or o.locks or o.shelf_cells}
        self._unloaded: set[int] = set()
        """AGVs that carry no shelf now (:meth:`set_loaded`)."""
        self._heading0 = heading
        self._agents: dict[int, _Agent] = {}
        self._queues: dict[int, list[_Visit]] = {}
        self.cell_version: defaultdict[int, int] = defaultdict(int)
        """Per cell: counts the changes of its queue and of its visits' ``entered`` and
        ``claimed`` (by starting, finishing, claiming, switching; a new plan counts in
        :attr:`plan_version` instead). What is read of a cell's queue stays the same
        while its number does (:meth:`.switch.SwitchableGraph.candidate` keeps its
        answers by them)."""
        self.load_version = 0
        """Counts the changes of who carries a shelf (:meth:`set_loaded`)."""
        self._order = 0
        self._waiters: dict[int, list[int]] = {}
        """Cell -> AGVs whose next action waits for that cell's queue head to change."""
        self.woken: set[int] = set()
        """AGVs registered with :meth:`wait_on` whose blocking queue head has changed (or
        whose plan changed) since; the executor clears it after it has looked at them."""
        self._ext_waiters: dict[int, list[int]] = {}
        """Cell -> AGVs whose last :meth:`released` stopped at a visit ahead in that cell's
        queue (:meth:`wait_release`)."""
        self.ext_woken: set[int] = set()
        """AGVs registered with :meth:`wait_release` whose cell's queue changed (or whose
        plan, or the set of loaded AGVs, changed) since; the executor takes out the AGVs it
        has looked at again."""
        self.released_stop: int | None | bool = None
        """Why the last :meth:`released` stopped: the cell whose queue has a visit ahead
        that holds the AGV back, ``None`` (the limit, or no more actions) or ``False`` (a
        message not yet heard: a matter of time, not of the queues)."""
        self.latency_s = float(latency_s)
        self.now = 0.0
        """Simulated time (seconds), set by the executor; used only with a latency."""
        self._heard_at: dict[int, tuple[int, float]] = {}
        """Cell -> (AGV that left it, time the others hear of it), with a latency."""
        self._progress: tuple[list, list, list, list] | None = None
        """:meth:`progress`'s answers of its last call, per AGV."""
        self._live: set[int] = set()
        """AGVs with an action running or upcoming at the last :meth:`progress`."""
        self._dirty: set[int] = set()
        """AGVs whose record changed since the last :meth:`progress`."""
        self._due: list[tuple[int, int, int]] = []
        """Heap of (tick after which an AGV not late at the last :meth:`progress` is late,
        AGV, version): the live AGVs that progress must look at again."""
        self._due_ver: dict[int, int] = {}
        """AGV -> version of its newest entry in :attr:`_due` (older ones are stale)."""
        self._progress_tick = 0
        self._n_visits = 0
        """Visits in the queues."""
        self._acyclic = False
        """:meth:`check_acyclic` passed since the last change of a plan or a load."""
        self._acyclic_failed = False
        """:meth:`check_acyclic` failed since the last change of a plan or a load."""
        self._dl_spent = 0
        """AGVs looked at by :meth:`deadlock_cycles` since the last change or check."""
        self._bulk: set[int] | None = None
        """Between :meth:`begin_bulk` and :meth:`end_bulk`: the cells whose queues got
        visits (appended, sorted at the end)."""
        self.plan_version = 0
        """Counts :meth:`set_plan` and :meth:`end_bulk` calls: the queues changed other
        than by actions starting and finishing (:mod:`.switch` rebuilds its order)."""

    # ----------------------------------------------------------------- building

    @property
    def agvs(self) -> tuple[int, ...]:
        """The registered AGVs, in id order."""
        return tuple(sorted(self._agents))

    def set_loaded(self, loaded) -> None:
        """Who carries a shelf now (``loaded[agv]`` bool, for every AGV id ``< len``):
        shelf sweep visits hold back only those (see the module doc). AGVs whose load
        changed wake up."""
        now = {a for a, x in enumerate(loaded) if not x}
        if now != self._unloaded:
            self._unloaded = now
            self.load_version += 1
            self._plans_changed()
            for cell in list(self._waiters):
                self._touch(cell)
            for cell in list(self._ext_waiters):
                self._touch(cell)

    def _passes(self, w: _Visit, v: _Visit) -> bool:
        """Visit ``w`` ahead of ``v`` in a queue does not hold ``v`` back."""
        if w.shelf:
            return v.shelf or v.agv in self._unloaded
        return v.shelf and w.agv in self._unloaded

    def _first(self, v: _Visit) -> bool:
        """``v`` is at the head of its queue, but for visits it passes."""
        q = self._queues[v.cell]
        if q[0] is v:
            return True
        for w in q:
            if w is v:
                return True
            if not self._passes(w, v):
                return False
        return True

    def turn_sweeps(self, agv: int) -> bool:
        """Whether the AGV's turns in place hold cells beyond its footprint."""
        return agv in self._sweeps

    def set_heading(self, agv: int, direction: tuple[int, int]) -> None:
        """The AGV (standing) now faces ``direction`` (the executor turned it): its next
        plan's first move sweeps if it goes another way."""
        self._rec(agv).heading = direction

    def _new_visit(self, cell: int, agv: int, enter: Action | None, tick: int,
                   entered: bool) -> _Visit:
        v = _Visit(cell, agv, enter, None, tick, self._order, entered)
        self._order += 1
        self._n_visits += 1
        q = self._queues.setdefault(cell, [])
        if self._bulk is not None:  # sorted by end_bulk; nobody waits yet
            q.append(v)
            self._bulk.add(cell)
            return v
        i = len(q)
        if entered:
            while i > 0 and (not q[i - 1].entered or q[i - 1].sweep):
                i -= 1
        else:
            key = (tick, v.order)
            while i > 0 and not q[i - 1].entered and not q[i - 1].claimed \
                    and (q[i - 1].tick, q[i - 1].order) > key:
                i -= 1
        q.insert(i, v)
        if i == 0:
            self._touch(cell)
        return v

    def _touch(self, cell: int) -> None:
        """The head of ``cell``'s queue may have changed: wake the AGVs waiting on it."""
        waiting = self._waiters.pop(cell, None)
        if waiting:
            self.woken.update(waiting)
        waiting = self._ext_waiters.pop(cell, None)
        if waiting:
            self.ext_woken.update(waiting)

    def wait_on(self, agv: int) -> bool:
        """The AGV's next action is not ready: register it on the first cell whose queue
        head is not its own visit, so that :attr:`woken` names it once that head changes.
        Returns False (nothing registered) if it is not waiting on a queue."""
        rec = self._agents.get(agv) or self._rec(agv)
        if rec.running is not None or not rec.pending:
            return False
        for v in rec.pending[0].enter_visits:
            if not self._first(v):
                self._waiters.setdefault(v.cell, []).append(agv)
                return True
        return False

    # ----------------------------------------------------------------- queries

    def _rec(self, agv: int) -> _Agent:
        """The AGV's record; ``KeyError`` if it has no plan. (The hot queries inline the
        look-up as ``self._agents.get(agv) or self._rec(agv)``: one call fewer.)"""
        rec = self._agents.get(agv)
        if rec is None:
            raise KeyError(f"AGV {agv} has no plan (call set_plan first)")
        return rec

    def cut_node(self, agv: int) -> int:
        """Where the AGV will stand after its running and claimed actions: a new plan
        (:meth:`set_plan`) must start there."""
        rec = self._agents.get(agv) or self._rec(agv)
        for step in reversed(rec.pending):
            if step.claimed:
                return step.action.dst
        return rec.running.action.dst if rec.running is not None else rec.node

    def cut_tick(self, agv: int) -> int | None:
        """The planned tick at which the AGV stands at :meth:`cut_node` (the end of its last
        claimed or running action, in its plan's ticks); None if it has done no action
        since it was registered. A new plan that passes the cut node more than once starts
        at its first standing there at or after this tick."""
        rec = self._agents.get(agv) or self._rec(agv)
        for step in reversed(rec.pending):
            if step.claimed:
                return step.action.tick + step.action.ticks
        if rec.running is not None:
            return rec.running.action.tick + rec.running.action.ticks
        return rec.last_tick

    def claim(self, agv: int, limit: int | None = None,
              released: list[Action] | None = None) -> list[Action]:
        """Commit the AGV to its released actions (at most ``limit``): their visits keep
        their place at the front of their queues (no visit placed later goes ahead of them)
        and a new plan keeps them. The executor claims what it drives through without
        stopping, so it never has to stop inside a braking distance. Returns the claimed
        actions (already claimed ones included). ``released``: what :meth:`released`
        returned for this AGV with nothing changed since (its first ``limit`` are the
        released ones), to save a second look at the queues."""
        rec = self._agents.get(agv) or self._rec(agv)
        out = self.released(agv, limit) if released is None else released[:limit]
        ver = self.cell_version
        for step in islice(rec.pending, len(out)):
            new = not step.claimed
            step.claimed = True
            for v in step.enter_visits:
                v.claimed = True
                if new:
                    ver[v.cell] += 1
        return out

    def claimed(self, agv: int) -> list[Action]:
        """The AGV's claimed upcoming actions (a leading run of them)."""
        out = []
        for step in self._rec(agv).pending:
            if not step.claimed:
                break
            out.append(step.action)
        return out

    def unclaim(self, agv: int, keep: int = 0) -> None:
        """Give back the claims on the AGV's upcoming actions after the first ``keep``
        (it stops sooner than it planned to, e.g. before a corridor that just opened)."""
        for n, step in enumerate(self._rec(agv).pending):
            if not step.claimed:
                break  # the claims are a leading run
            if n >= keep:
                step.claimed = False
                for v in step.enter_visits:
                    v.claimed = False
                    self.cell_version[v.cell] += 1

    def next_action(self, agv: int) -> Action | None:
        """The first not-started action, if any."""
        rec = self._agents.get(agv) or self._rec(agv)
        return rec.pending[0].action if rec.pending else None

    def current(self, agv: int) -> Action | None:
        """The started, not yet finished action, if any."""
        rec = self._agents.get(agv) or self._rec(agv)
        return rec.running.action if rec.running is not None else None

    def state(self, agv: int) -> State:
        """``(src, dst)`` while an action runs, else ``(node, node)``."""
        rec = self._agents.get(agv) or self._rec(agv)
        if rec.running is not None:
            return (rec.running.action.src, rec.running.action.dst)
        return (rec.node, rec.node)

    def done(self, agv: int) -> bool:
        """No started and no upcoming actions."""
        rec = self._agents.get(agv) or self._rec(agv)
        return rec.running is None and not rec.pending

    def progress(self, n: int, tick: int) -> tuple[list[State], list[bool], list[bool],
                                                   list[bool]]:
        """For AGVs ``0 .. n-1`` in one pass (the executor's write-back at the end of a
        tick): each one's :meth:`state`, whether it is late at ``tick`` (its next action,
        with none running, was planned to start before ``tick``, or its running action to
        end before it), whether it has an upcoming action and whether one runs. Raises
        ``KeyError`` for an AGV without a plan, as :meth:`state` does.

        Only the AGVs that have an action running or upcoming, or whose record changed
        since the last call (:meth:`set_plan`, :meth:`start`, :meth:`finish`), are looked
        at: an AGV with nothing left to do answers as it did (at 1,000 AGVs most of them
        stand at their goals)."""
        cache = self._progress
        due, due_ver = self._due, self._due_ver
        if cache is None or len(cache[0]) != n:
            todo: Iterable[int] = range(n)
            cache = self._progress = ([(0, 0)] * n, [False] * n, [False] * n, [False] * n)
            self._live = set()
            due.clear()
        elif tick < self._progress_tick:  # back in time: look at every live AGV again
            todo = sorted(self._live | self._dirty)
            due.clear()
        else:
            # A live AGV whose record did not change answers as it did, but that it may be
            # late by now: only those whose due tick has passed are looked at again.
            again = set(self._dirty)
            while due and due[0][0] < tick:
                _, i, ver = heapq.heappop(due)
                if due_ver.get(i) == ver:
                    again.add(i)
            todo = sorted(again)
        self._progress_tick = tick
        states, late, pending, running = cache
        live = self._live
        agents = self._agents
        for i in todo:
            if i >= n:
                continue
            rec = agents.get(i)
            if rec is None:
                self._rec(i)
            run = rec.running
            nxt = rec.pending[0].action if rec.pending else None
            if run is not None:
                a = run.action
                states[i] = (a.src, a.dst)
                late[i] = a.tick + a.ticks < tick
                running[i] = True
            else:
                states[i] = (rec.node, rec.node)
                late[i] = nxt is not None and nxt.tick < tick
                running[i] = False
            pending[i] = nxt is not None
            ver = due_ver.get(i, 0) + 1
            due_ver[i] = ver
            if run is not None or nxt is not None:
                live.add(i)
                if not late[i]:  # late once tick passes this
                    heapq.heappush(due, (a.tick + a.ticks if run is not None else nxt.tick,
                                         i, ver))
            else:
                live.discard(i)
        self._dirty.clear()
        return list(states), list(late), list(pending), list(running)

    def upcoming(self, agv: int, limit: int | None = None) -> list[Action]:
        """The not-started actions in order (at most ``limit``)."""
        return [s.action for s in islice((self._agents.get(agv) or self._rec(agv)).pending, limit)]

    def ready(self, agv: int) -> bool:
        """The next action exists, no action runs, for every cell it enters the AGV's visit
        is at the head of the queue, and (with a latency) it has heard that the AGVs before
        it left those cells."""
        rec = self._agents.get(agv) or self._rec(agv)
        if rec.running is not None or not rec.pending:
            return False
        step = rec.pending[0]
        return all(self._first(v) for v in step.enter_visits) and self._heard(agv, step)

    def _heard(self, agv: int, step: _Step) -> bool:
        """Whether the AGV has heard that the cells ``step`` enters were left by the AGVs
        before it (always, without a latency)."""
        if not self._heard_at:
            return True
        now = self.now
        for v in step.enter_visits:
            left = self._heard_at.get(v.cell)
            if left is not None and left[0] != agv and now < left[1]:
                return False
        return True

    def listening(self, agv: int) -> bool:
        """The next action's cells are free (its visits head their queues) but the AGV has
        not yet heard so: another AGV left one of them less than ``latency_s`` ago."""
        rec = self._agents.get(agv) or self._rec(agv)
        if rec.running is not None or not rec.pending or not self._heard_at:
            return False
        step = rec.pending[0]
        return all(self._first(v) for v in step.enter_visits) and not self._heard(agv, step)

    def released(self, agv: int, limit: int | None = None) -> list[Action]:
        """The leading upcoming actions that are each ready once the AGV's own earlier actions
        are done: only the AGV's own visits are ahead of them. The AGV may drive through all
        of them without stopping; no other AGV can take these cells before it."""
        out: list[Action] = []
        for step in islice((self._agents.get(agv) or self._rec(agv)).pending, limit):
            for v in step.enter_visits:
                for w in self._queues[v.cell]:
                    if w is v:
                        break
                    if w.agv != agv and not self._passes(w, v):
                        self.released_stop = v.cell
                        return out
            if not self._heard(agv, step):
                self.released_stop = False
                return out
            out.append(step.action)
        self.released_stop = None
        return out

    def wait_release(self, agv: int, cell: int) -> None:
        """Name the AGV in :attr:`ext_woken` once ``cell``'s queue changes (a visit leaves
        it, or one goes to its head), its plan changes, or the loaded AGVs change: until
        then :meth:`released` gives it the same answer (visits placed later go behind
        the ones it has claimed, and only make the cell's visit wait longer)."""
        self._ext_waiters.setdefault(cell, []).append(agv)

    def collinear_run(self, agv: int, limit: int | None = None) -> list[Action]:
        """The leading upcoming actions with the direction of the first (one merged move)."""
        ups = self.upcoming(agv, limit)
        if not ups:
            return []
        run = [ups[0]]
        for a in ups[1:]:
            if a.direction != run[0].direction:
                break
            run.append(a)
        return run

    def visits(self, cell: int) -> tuple[Visit, ...]:
        """The queue of a cell, head first."""
        return tuple(Visit(v.agv, v.enter.seq if v.enter is not None else None,
                           v.leave.seq if v.leave is not None else None, v.tick, v.entered)
                     for v in self._queues.get(cell, ()))

    def head(self, cell: int) -> int | None:
        """The AGV whose visit heads ``cell``'s queue (entered or not), if any."""
        q = self._queues.get(cell)
        return q[0].agv if q else None

    def blockers(self, agvs: Iterable[int]) -> list[int]:
        """Per AGV of ``agvs``: the AGV whose visit heads the queue of the first cell its
        next action enters where its own does not (the one it waits for; the holder if
        that visit is entered, else the next in line), -1 if none or no next action. (The
        cause recorder asks for every waiting AGV at once.)"""
        agents, queues = self._agents, self._queues
        out = []
        for agv in agvs:
            rec = agents.get(agv) or self._rec(agv)
            b = -1
            if rec.pending:
                for c in rec.pending[0].action.enters:
                    q = queues.get(c)
                    if q and q[0].agv != agv:
                        b = q[0].agv
                        break
            out.append(b)
        return out

    def holder(self, cell: int) -> int | None:
        """The AGV that physically holds ``cell`` (its visit is entered), if any."""
        q = self._queues.get(cell)
        return q[0].agv if q and q[0].entered else None

    # ----------------------------------------------------------------- execution

    def start(self, agv: int, force: bool = False) -> Action:
        """Mark the next action started. Raises ``RuntimeError`` if it is not ready, unless
        ``force`` (naive time-indexed execution, which ignores the dependencies)."""
        if not force and not self.ready(agv):
            raise RuntimeError(f"AGV {agv}: the next action is not ready "
                               f"({self.next_action(agv)!r}, running {self.current(agv)!r})")
        rec = self._agents[agv]
        step = rec.pending.popleft()
        ver = self.cell_version
        for v in step.enter_visits:
            v.entered = True
            rec.held[v.cell] = v
            ver[v.cell] += 1
        rec.running = step
        self._dirty.add(agv)
        return step.action

    def finish(self, agv: int) -> Action:
        """Mark the running action finished (the AGV stands at ``dst``); the visits it leaves
        leave their queues. Raises ``RuntimeError`` if no action runs."""
        rec = self._agents.get(agv) or self._rec(agv)
        step = rec.running
        if step is None:
            raise RuntimeError(f"AGV {agv} has no running action to finish")
        for v in step.leave_visits:
            q = self._queues[v.cell]
            if q[0] is v:
                del q[0]
            else:  # cannot happen while the invariants hold; stay safe
                q.remove(v)
            self._n_visits -= 1
            del rec.held[v.cell]
            self.cell_version[v.cell] += 1
            self._touch(v.cell)
            if self.latency_s > 0:
                self._heard_at[v.cell] = (agv, self.now + self.latency_s)
        rec.running = None
        rec.node = step.action.dst
        rec.last_tick = step.action.tick + step.action.ticks
        rec.heading = step.action.direction
        self._dirty.add(agv)
        return step.action

    # ----------------------------------------------------------------- deadlocks

    def _plans_changed(self) -> None:
        """A plan or a load changed: the dependency graph may have a cycle again."""
        self._acyclic = self._acyclic_failed = False
        self._dl_spent = 0


def build(paths: Mapping[int, TimedPath], sizes: Mapping[int, int], cols: int) -> ActionGraph:
    """Build the ADG of a whole plan (every path starts at the same tick) and check that it
    is acyclic; raises :class:`ADGCycleError` if no execution order exists (a swap, or a
    rotation of AGVs that each move into the cell the next one leaves in the same tick)."""
    starts = {p.start_tick for p in paths.values()}
    if len(starts) > 1:
        raise ValueError(f"all paths must start at the same tick, got {sorted(starts)}")
    graph = ActionGraph(cols, sizes)
    graph.begin_bulk()
    try:
        for agv in sorted(paths):
            graph.set_plan(agv, paths[agv])
    finally:
        graph.end_bulk()
    graph.check_acyclic()
    return graph
