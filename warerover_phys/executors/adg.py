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
from collections import deque
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from itertools import islice

from ..planning.base import State, TimedPath, footprint_nodes
from ..planning.sweep import Sweep

__all__ = ["ADGCycleError", "Action", "Visit", "ActionGraph", "build", "path_moves"]

log = logging.getLogger(__name__)


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


class ActionGraph:
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

    def begin_bulk(self) -> bool:
        """Start registering many AGVs at once (the first plans of a whole fleet): until
        :meth:`end_bulk`, :meth:`set_plan` appends visits to their queues and the queues
        are sorted once at the end, into the order that inserting them one by one gives
        (held cells first in registration order, then by planned tick and insertion
        order): one sort per queue instead of a search per visit. Only on an empty graph
        (returns False, and does nothing, otherwise). Between the two calls nothing may
        read the queues."""
        if self._agents or self._bulk is not None:
            return False
        self._bulk = set()
        return True

    def end_bulk(self) -> None:
        """Sort the queues that got visits since :meth:`begin_bulk`."""
        cells, self._bulk = self._bulk, None
        self.plan_version += 1
        for c in cells or ():
            self._queues[c].sort(key=_bulk_key)

    def set_plan(self, agv: int, path: TimedPath) -> None:
        """Commit cut and rebuild for one AGV.

        Keeps the AGV's finished actions and its started one, drops every not-started action
        (and its visits), then appends the actions of ``path``. ``path.states[0]`` must be the
        AGV standing where it will be after the cut (``dst`` of the running action, else its
        anchor); otherwise ``ValueError``. The visits of the cells it holds after the cut stay
        where they are in their queues; only their leaving action changes. The first call for
        an AGV registers where it stands (its cells go to the head of their queues).
        """
        if agv not in self._sizes:
            raise KeyError(f"AGV {agv} has no footprint size")
        if path.agv != agv:
            raise ValueError(f"set_plan for AGV {agv} got the path of AGV {path.agv}")
        moves = path_moves(path, self.cols)
        k, cols = self._sizes[agv], self.cols
        here = path.states[0][0]
        rec = self._agents.get(agv)
        if rec is None:
            cells = footprint_nodes(here, k, cols)
            for c in cells:
                q = self._queues.get(c)
                if q and (q[0].entered and not q[0].sweep if self._bulk is None
                          else any(w.entered for w in q)):
                    raise ValueError(f"AGV {agv} cannot start at {divmod(here, cols)}: cell "
                                     f"{divmod(c, cols)} is held by AGV {q[0].agv}")
            rec = _Agent(k=k, node=here, held={}, pending=deque(), heading=self._heading0)
            for c in cells:
                v = self._new_visit(c, agv, None, path.start_tick, entered=True)
                rec.held[c] = v
            self._agents[agv] = rec
        else:
            cut = self.cut_node(agv)
            if here != cut:
                raise ValueError(f"AGV {agv}: the new path starts at {divmod(here, cols)} but "
                                 f"the AGV will stand at {divmod(cut, cols)} after the cut")
            kept = [s for s in rec.pending if s.claimed]
            gone = [s for s in rec.pending if not s.claimed]
            dropped = {id(s.action) for s in gone}
            for step in gone:
                for v in step.enter_visits:
                    self._queues[v.cell].remove(v)
                    self._n_visits -= 1
                    self._touch(v.cell)
            for step in [rec.running, *kept]:
                if step is None:
                    continue
                for v in step.enter_visits:
                    if v.leave is not None and id(v.leave) in dropped:
                        v.leave = None
            for v in rec.held.values():
                if v.leave is not None and id(v.leave) in dropped:
                    v.leave = None
            rec.pending = deque(kept)
        # Cells the AGV holds (or has claimed) after the cut, and not left by then.
        committed = [s for s in (rec.running, *rec.pending) if s is not None]
        open_visits = dict(rec.held)
        for step in committed:
            for v in step.leave_visits:
                if not v.sweep:
                    open_visits.pop(v.cell, None)
            for v in step.enter_visits:
                if not v.sweep:
                    open_visits[v.cell] = v
        offsets = self._sweeps.get(agv)
        heading = committed[-1].action.direction if committed else rec.heading
        # (path_moves checked every move: its direction is the step's offset.)
        dirs = {1: (0, 1), -1: (0, -1), cols: (1, 0), -cols: (-1, 0)}
        for src, dst, tick, ticks in moves:
            direction = dirs[dst - src]
            if k == 1:
                fs, fd = (src,), (dst,)
                enters, leaves = fd, fs
            else:
                fs, fd = footprint_nodes(src, k, cols), footprint_nodes(dst, k, cols)
                enters = tuple(c for c in fd if c not in fs)
                leaves = tuple(c for c in fs if c not in fd)
            swept: tuple[int, ...] = ()
            shelf: tuple[int, ...] = ()
            if offsets and direction != heading:
                swept = tuple(c for c in self._sweep_cells(src, offsets)
                              if c not in fs and c not in fd)
                shelf = tuple(c for c in self._shelf_cells(src, offsets)
                              if c not in fs and c not in fd)
            heading = direction
            action = Action(agv=agv, seq=rec.next_seq, src=src, dst=dst, tick=tick,
                            ticks=ticks, enters=enters, leaves=leaves,
                            direction=direction, sweeps=swept + shelf)
            rec.next_seq += 1
            leave_visits = [open_visits.pop(c) for c in action.leaves]
            for v in leave_visits:
                v.leave = action
            enter_visits = []
            for c in action.enters:
                v = self._new_visit(c, agv, action, tick + 1, entered=False)
                open_visits[c] = v
                enter_visits.append(v)
            for c in swept + shelf:
                # The turn happens at the move's start tick; the same action leaves it.
                v = self._new_visit(c, agv, action, tick, entered=False)
                v.leave = action
                v.sweep = True
                v.shelf = c in shelf
                enter_visits.append(v)
                leave_visits.append(v)
            rec.pending.append(_Step(action, enter_visits, leave_visits))
        self.woken.add(agv)
        self.ext_woken.add(agv)
        self._plans_changed()
        self.plan_version += 1
        self._dirty.add(agv)

    def _sweep_cells(self, anchor: int, sweep: Sweep) -> tuple[int, ...]:
        """Queue keys of a turn at ``anchor``: swept cells, then locks (``-1 - anchor``)."""
        cols, rows = self.cols, self.rows
        r, c = divmod(anchor, cols)

        def inside(dr: int, dc: int) -> bool:
            return 0 <= c + dc < cols and r + dr >= 0 and (rows is None or r + dr < rows)

        return tuple((r + dr) * cols + c + dc for dr, dc in sweep.cells if inside(dr, dc)) \
            + tuple(-1 - ((r + dr) * cols + c + dc) for dr, dc in sweep.locks
                    if inside(dr, dc))

    def _shelf_cells(self, anchor: int, sweep: Sweep) -> tuple[int, ...]:
        """Cells of a turn at ``anchor`` held only against AGVs that carry a shelf."""
        cols, rows = self.cols, self.rows
        r, c = divmod(anchor, cols)
        return tuple((r + dr) * cols + c + dc for dr, dc in sweep.shelf_cells
                     if 0 <= c + dc < cols and r + dr >= 0 and (rows is None or r + dr < rows))

    def set_loaded(self, loaded) -> None:
        """Who carries a shelf now (``loaded[agv]`` bool, for every AGV id ``< len``):
        shelf sweep visits hold back only those (see the module doc). AGVs whose load
        changed wake up."""
        now = {a for a, x in enumerate(loaded) if not x}
        if now != self._unloaded:
            self._unloaded = now
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
        for step in islice(rec.pending, len(out)):
            step.claimed = True
            for v in step.enter_visits:
                v.claimed = True
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
        for v in step.enter_visits:
            v.entered = True
            rec.held[v.cell] = v
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

    def waiting_for(self) -> dict[int, set[int]]:
        """Wait-for graph: each AGV whose next action is not ready (and that runs nothing)
        -> the other AGVs whose visits are ahead of its own in the cells it would enter."""
        out: dict[int, set[int]] = {}
        for agv, rec in self._agents.items():
            if rec.running is not None or not rec.pending:
                continue
            ahead: set[int] = set()
            blocked = False
            for v in rec.pending[0].enter_visits:
                q = self._queues[v.cell]
                if self._first(v):
                    continue
                blocked = True
                for w in q:
                    if w is v:
                        break
                    if w.agv != agv and not self._passes(w, v):
                        ahead.add(w.agv)
            if blocked:
                out[agv] = ahead
        return out

    def deadlock_cycles(self, max_cycles: int = 64) -> list[list[int]]:
        """Elementary cycles of :meth:`waiting_for`, each once, rotated to start at its
        smallest AGV id, sorted; at most ``max_cycles``.

        A cycle of waits is a cycle of the remaining dependency graph (an AGV waits on one
        whose visit is ahead of its own: that AGV's next action comes before its leaving
        the cell, which comes before the waiting AGV's next action). Starting and
        finishing actions never add an edge, so once :meth:`check_acyclic` has passed
        there is no cycle to find until a plan or a load changes. It is run once the
        passes spent since the last change (AGVs looked at) reach the number of visits
        in the queues (its own cost): at most about twice the work of looking every
        time, and, with a fixed plan, one check instead of a pass per tick. The answers
        are the same either way."""
        if self._acyclic:
            return []
        cycles = self._cycles(max_cycles)
        self._dl_spent += len(self._agents)
        if not cycles and not self._acyclic_failed and self._dl_spent >= self._n_visits:
            self._dl_spent = 0
            try:
                self.check_acyclic()
            except ADGCycleError:
                self._acyclic_failed = True  # (a visit behind a plan's end: look each time)
            else:
                self._acyclic = True
        return cycles

    def _plans_changed(self) -> None:
        """A plan or a load changed: the dependency graph may have a cycle again."""
        self._acyclic = self._acyclic_failed = False
        self._dl_spent = 0

    def _cycles(self, max_cycles: int) -> list[list[int]]:
        """:meth:`deadlock_cycles` by a search of the wait-for graph."""
        graph = _prune_acyclic({a: sorted(b) for a, b in self.waiting_for().items()})
        cycles: list[list[int]] = []
        for comp in _sccs(graph):
            if len(comp) < 2:
                continue
            members = set(comp)
            for s in sorted(comp):
                # Depth-first search for simple paths back to s through ids above s.
                path, stack = [s], [iter(graph.get(s, ()))]
                on_path = {s}
                while stack and len(cycles) < max_cycles:
                    nxt = next(stack[-1], None)
                    if nxt is None:
                        stack.pop()
                        on_path.discard(path.pop())
                    elif nxt == s:
                        cycles.append(list(path))
                    elif nxt > s and nxt in members and nxt not in on_path:
                        path.append(nxt)
                        on_path.add(nxt)
                        stack.append(iter(graph.get(nxt, ())))
        return sorted(cycles)

    def _edges(self, q: list[_Visit]) -> Iterator[tuple[_Visit, _Visit]]:
        """Type-2 edges of one queue: ``(prev, nxt)`` for each visit and every earlier one
        that holds it back (:meth:`_passes`); only the nearest such plain visit (plain
        visits hold each other back in queue order)."""
        for i, nxt in enumerate(q):
            for w in reversed(q[:i]):
                if self._passes(w, nxt):
                    continue
                yield w, nxt
                if not w.shelf:
                    break

    def check_acyclic(self) -> None:
        """Check the remaining dependency graph (type-1 edges between an AGV's unfinished
        actions, type-2 edges ``leave(previous visit) -> enter(next visit)`` per cell) with
        Kahn's algorithm. Raises :class:`ADGCycleError` naming the AGVs and cells of a cycle,
        or of a visit stuck behind an AGV whose plan ends on the cell."""
        cols = self.cols
        preds: dict[Action, list[tuple[Action, int | None]]] = {}
        succs: dict[Action, list[Action]] = {}
        for rec in self._agents.values():
            chain = ([rec.running.action] if rec.running is not None else []) + [
                s.action for s in rec.pending]
            for a in chain:
                preds[a] = []
                succs[a] = []
            for a, b in zip(chain, chain[1:], strict=False):
                preds[b].append((a, None))
                succs[a].append(b)
        for cell, full in self._queues.items():
            for prev, nxt in self._edges(full):
                if prev.leave is None:
                    raise ADGCycleError(
                        f"AGV {nxt.agv} must enter cell {divmod(cell, cols)} after AGV "
                        f"{prev.agv}, whose plan ends on it", (prev.agv, nxt.agv),
                        (divmod(cell, cols),))
                if nxt.enter is None:  # two registered AGVs on one cell: set_plan forbids it
                    raise ADGCycleError(f"AGVs {prev.agv} and {nxt.agv} both hold cell "
                                        f"{divmod(cell, cols)}", (prev.agv, nxt.agv),
                                        (divmod(cell, cols),))
                preds[nxt.enter].append((prev.leave, cell))
                succs[prev.leave].append(nxt.enter)
        indeg = {a: len(p) for a, p in preds.items()}
        todo = [a for a, d in indeg.items() if d == 0]
        seen = 0
        while todo:
            a = todo.pop()
            seen += 1
            for b in succs[a]:
                indeg[b] -= 1
                if indeg[b] == 0:
                    todo.append(b)
        if seen == len(indeg):
            return
        left = {a for a, d in indeg.items() if d > 0}
        # Every action left has a predecessor left: walk back until one repeats.
        walk: list[tuple[Action, int | None]] = []
        index: dict[Action, int] = {}
        a = next(iter(sorted(left, key=lambda x: (x.agv, x.seq))))
        while a not in index:
            index[a] = len(walk)
            p, cell = next((p, c) for p, c in preds[a] if p in left)
            walk.append((a, cell))
            a = p
        cycle = walk[index[a]:]
        cycle.reverse()  # now in execution order: each waits for the one before it
        agvs = tuple(dict.fromkeys(x.agv for x, _ in cycle))
        cells = tuple(divmod(c, cols) for _, c in cycle if c is not None)
        parts = [f"AGV {x.agv} {divmod(x.src, cols)}->{divmod(x.dst, cols)}"
                 + (f" waits for cell {divmod(c, cols)}" if c is not None else
                    " waits for its own previous action") for x, c in cycle]
        raise ADGCycleError(f"the action dependency graph has a cycle through AGVs "
                            f"{list(agvs)} and cells {list(cells)}: " + "; ".join(parts),
                            agvs, cells)


def _bulk_key(v: _Visit) -> tuple[int, int, int]:
    """Queue order of visits registered in bulk (:meth:`ActionGraph.begin_bulk`): held
    cells first, in registration order, then by (planned enter tick, insertion order)."""
    return (0, 0, v.order) if v.entered else (1, v.tick, v.order)


def _prune_acyclic(graph: dict[int, list[int]]) -> dict[int, list[int]]:
    """``graph`` without the nodes that reach no cycle (an AGV that waits on no waiting
    AGV, then those that wait only on such AGVs, and so on): in a jammed fleet most
    waiting AGVs are in such chains, which end at an AGV that still drives. The nodes
    left and the order of their edges are kept, so the cycles found do not change."""
    waits_on = {a: sum(1 for b in bs if b in graph) for a, bs in graph.items()}
    if all(waits_on.values()):
        return graph
    waited_by: dict[int, list[int]] = {}
    for a, bs in graph.items():
        for b in bs:
            if b in graph:
                waited_by.setdefault(b, []).append(a)
    free = [a for a, d in waits_on.items() if d == 0]
    gone = set(free)
    while free:
        b = free.pop()
        for a in waited_by.get(b, ()):
            waits_on[a] -= 1
            if waits_on[a] == 0:
                gone.add(a)
                free.append(a)
    return {a: [b for b in bs if b not in gone] for a, bs in graph.items() if a not in gone}


def _sccs(graph: Mapping[int, list[int]]) -> Iterator[list[int]]:
    """Strongly connected components (iterative Tarjan)."""
    index: dict[int, int] = {}
    low: dict[int, int] = {}
    stack: list[int] = []
    on_stack: set[int] = set()
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(graph.get(root, ())))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(graph.get(w, ()))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                yield comp


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
