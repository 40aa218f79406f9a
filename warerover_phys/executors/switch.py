"""Switchable action dependency graph (Berndt, van Duijkeren, Palmieri, Keviczky 2020):
change the order of AGVs at the cells they share, keeping the graph acyclic.

The :class:`~.adg.ActionGraph` keeps per cell a queue of visits; the order of two
neighbouring visits ``u`` (AGV ``i``) and ``w`` (AGV ``j``) is the type-2 edge
``leave(u) -> enter(w)``. *Switching* puts ``w`` right before ``u``: the edge becomes
``leave(w) -> enter(u)``, and ``j`` also goes before any (movable) visits that were
between the two. Every AGV still drives its own actions in their order; only who passes a
shared cell first changes.

A switch is made for a :class:`Group` (:meth:`SwitchableGraph.candidate`): the AGV ``j``
that waits, its next action's cells reserved for AGVs that have not entered them yet, and
``j``'s visits that then go first. On each cell ``j`` enters before it has left all the
group's cells it passes the visits ahead of its own too: those AGVs may wait for the ones
it passed, and ``j`` would wait for them there, a cycle. (Switching only the first cell of
a corridor that ``i`` and ``j`` both drive through is the plainest such cycle: ``j`` would
wait for ``i`` on the second cell, ``i`` for ``j`` on the first.) So a whole corridor, or a
single crossing cell, is switched at once, or nothing. On a cell of the group that another
AGV stands on, ``j`` waits for it and passes the visits behind it. (Until 2026-11-29 it
passed none there, and waited for them: when ``i`` was among them, the group closed a
cycle and was refused. LaCAM's 400-agent plan of warehouse-10-20-10-2-1, bernoulli 0.1,
``greedy``, seed 0: 188 groups refused instead of 722, AET 282.6 instead of 285.2 s.)

**Acyclic, checked.** :class:`SwitchableGraph` keeps a topological order of the remaining
actions (a number per action: Kahn's algorithm once per plan change,
:attr:`~.adg.ActionGraph.plan_version`) over a graph that contains every dependency of
the ADG: type-1 edges between an AGV's actions and an edge between each two *neighbouring*
visits of a queue (whose transitive closure holds every type-2 edge, shelf sweep visits
included). A switch adds, per cell, the one edge ``leave(w) -> enter(u)``; each is
inserted with the incremental algorithm of Pearce and Kelly (2006): if the new edge goes
backwards in the order, the actions reachable from ``enter(u)`` and the actions that reach
``leave(w)`` between the two positions are searched; reaching ``leave(w)`` is a cycle,
otherwise the two sets are renumbered. The group's old edges are taken out before its new
ones go in (the graph in between has neither order at the cells not yet switched), so a
group that is acyclic as a whole is never refused because one of its cells alone would
close a cycle. A cycle, or a search that exceeds ``search_limit`` actions, undoes the
whole group (a deterministic limit: no wall clock). Removing actions (started, finished)
keeps the order valid. Before any edge goes in, one forward search looks for a cycle
through the edge of the group's last cell alone: nearly every group refused closes its
cycle there (LaCAM's plans of warehouse-10-20-10-2-1, 400 agents, bernoulli 0.1, seed 0:
all 722 refused), and this search finds it without renumbering the other cells' edges
in vain (at 1,000 agents: 180,386 actions searched instead of 3,294,122 for the refused
groups). With ``check=True`` :meth:`~.adg.ActionGraph.check_acyclic` also runs after
every switch, and the insertions go on after that search to confirm its cycle (tests).

**Candidates are kept.** :meth:`SwitchableGraph.candidate` keeps its last answer per AGV
with the numbers (:attr:`~.adg.ActionGraph.cell_version`) of the cells whose queues it
read, and gives it again while the AGV's next action and those numbers stay the same:
most waiting AGVs wait on queues that did not change since the last decision.

Visits that may not move: an entered visit (the AGV is on the cell), a claimed one (the
AGV drives through it without stopping, :meth:`~.adg.ActionGraph.claim`), a turn's swept
cells, and visits whose AGV's plan ends on the cell.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from itertools import islice
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .adg import ActionGraph, _Step, _Visit

__all__ = ["Group", "SwitchableGraph", "SEARCH_LIMIT", "SEGMENT_LIMIT"]

SEARCH_LIMIT = 20_000
"""Most actions one edge insertion may search before the switch is refused."""
SEGMENT_LIMIT = 256
"""Most actions of the waiting AGV a group's cells may span."""


@dataclass(frozen=True, eq=False)
class Group:
    """A switch: at each pair's cell ``second``'s visit goes before the other's."""

    first: int
    """The AGV whose visit holds ``second``'s next action back (``i``; with others of
    :attr:`pairs` it will wait for ``second``)."""
    second: int
    """The waiting AGV (``j``)."""
    pairs: tuple[tuple[_Visit, _Visit], ...]
    """``(u, w)``: the first visit ahead of ``second``'s visit ``w`` that ``w`` passes,
    per cell, in ``second``'s order."""

    @property
    def cells(self) -> tuple[int, ...]:
        """The switched cells (queue keys), in ``second``'s order."""
        return tuple(u.cell for u, _ in self.pairs)


def _movable(u: _Visit, w: _Visit, q: list[_Visit]) -> bool:
    """``w`` may go before ``u`` in queue ``q`` (``u`` ahead of it), and before the visits
    between them (see the module doc)."""
    if not (not u.entered and not u.claimed and not u.sweep and not u.shelf
            and u.enter is not None and u.leave is not None
            and not w.entered and not w.sweep and not w.shelf
            and w.enter is not None and w.leave is not None):
        return False
    i, n = q.index(u), q.index(w)
    return i < n and all(not x.claimed and not x.entered and not x.sweep and not x.shelf
                         for x in q[i + 1:n])


class SwitchableGraph:
    """Switches on an :class:`~.adg.ActionGraph` that keep it acyclic (module doc). A
    friend of the graph: it reads and reorders its queues."""

    def __init__(self, adg: ActionGraph, *, check: bool = False,
                 search_limit: int = SEARCH_LIMIT) -> None:
        self.adg = adg
        self.check = check
        """Tests: :meth:`~.adg.ActionGraph.check_acyclic` after every switch, kept
        candidates and found cycles checked against a fresh look."""
        self.search_limit = search_limit
        self.switches = 0
        """Groups switched."""
        self.refused = 0
        """Groups refused: a cycle, or a search over the limit."""
        self.rebuilds = 0
        """Topological orders built from scratch (once per plan change)."""
        self._version = -1
        self._ok = False
        self._ord: dict[_Step, int] = {}
        self._where: dict[_Step, tuple[int, int]] = {}
        self._chain: dict[int, list[_Step]] = {}
        self._step_of: dict[int, _Step] = {}
        self._pend_u: dict[int, list[_Visit]] = {}
        self._pend_w: dict[int, _Visit] = {}
        """Pairs ``(u, w)`` of the group being switched whose old edges are out and new one
        not yet in: ``id(u) -> [w, ...]`` and ``id(w) -> u``."""
        self._cands: dict[int, tuple] = {}
        """Per AGV: :meth:`candidate`'s last answer, with what it read (its next action,
        the limit, :attr:`~.adg.ActionGraph.load_version`, the cells of the queues read
        and their :attr:`~.adg.ActionGraph.cell_version`): the same while those are.
        Emptied when the plans change."""

    # ----------------------------------------------------------------- candidates

    def candidate(self, j: int, limit: int = SEGMENT_LIMIT, ahead: bool = False
                  ) -> Group | None:
        """The group that would let standing AGV ``j`` start its next action now, or
        None; with ``ahead``, driving AGV ``j`` (an action runs) the first action it has
        not claimed, as soon as the ones before are done (it drives through its claimed
        actions; :meth:`~.adg.ActionGraph.claim`). Each cell that action enters must be
        free for it but for movable visits of other AGVs that have not entered it; ``j``
        goes before them. Then, on each cell ``j`` enters before it has left every cell
        of the group, it goes before the visits ahead of its own there too (they may wait
        for those it passed: a cycle); on such a cell that is held (its AGV is on it)
        ``j`` waits for the holder and passes only the visits behind it, if they may move
        (else it waits for those too). None if a visit it must pass on that action's
        cells may not move, or ``j``'s plan ends on a cell of the group."""
        self._sync()
        adg = self.adg
        rec = adg._agents.get(j)
        if rec is None or (rec.running is None) == ahead:
            return None
        start = 0
        if ahead:
            for step in rec.pending:
                if not step.claimed:
                    break
                start += 1
        if start >= len(rec.pending):
            return None
        head = rec.pending[start]
        ver = adg.cell_version
        got = self._cands.get(j)
        if got is not None and got[0] is head and got[1] == limit \
                and got[2] == adg.load_version \
                and all(ver[c] == n for c, n in zip(got[3], got[4], strict=True)):
            if self.check:
                fresh = self._candidate(j, rec, limit, [], start)
                if (fresh is None) != (got[5] is None) or fresh is not None and (
                        fresh.first, fresh.pairs) != (got[5].first, got[5].pairs):
                    raise AssertionError(f"AGV {j}: a kept candidate is out of date")
            return got[5]
        cells: list[int] = []
        g = self._candidate(j, rec, limit, cells, start)
        self._cands[j] = (head, limit, adg.load_version, cells, [ver[c] for c in cells], g)
        return g

    def _candidate(self, j: int, rec, limit: int, cells: list[int], start: int = 0
                   ) -> Group | None:
        """:meth:`candidate` (not kept); ``cells`` gets the cells whose queues it read."""
        adg = self.adg
        queues = adg._queues
        n_steps = min(len(rec.pending), limit)
        steps = islice(rec.pending, start, None)
        pairs: list[tuple[_Visit, _Visit]] = []
        last = start  # j's step that leaves the group's last cell
        k = start
        while k <= last and k < n_steps:
            for w in next(steps).enter_visits:
                cells.append(w.cell)
                q = queues[w.cell]
                idx = q.index(w)
                ahead = [x for x in q[:idx] if x.agv != j]
                if w.sweep or w.shelf:
                    if k == start and ahead and not adg._first(w):
                        return None  # a turn that waits for its swept cells
                    continue
                if k > start and any(x.entered for x in ahead):
                    # a held cell: j waits there for its holder, and passes the visits
                    # behind it, if it may (else it waits for those too)
                    rest = [x for x in ahead if not x.entered]
                    if not rest or w.leave is None or not _movable(rest[0], w, q):
                        continue
                    ahead = rest
                if not ahead:
                    continue
                if w.leave is None or not _movable(ahead[0], w, q):
                    return None
                pairs.append((ahead[0], w))
                last = max(last, self.pending_index(self._step_of[id(w.leave)]))
            if k == start and not pairs:
                return None  # that action's cells are free: nothing to switch
            k += 1
        if not pairs or last >= n_steps:
            return None
        return Group(pairs[0][0].agv, j, tuple(pairs))

    def pending_index(self, step: _Step) -> int:
        """The position of ``step`` among its AGV's not-started actions (-1: running)."""
        self._sync()
        agv, k = self._where[step]
        return k - self._live_from(agv) - (1 if self.adg._agents[agv].running is not None
                                           else 0)

    def step_of(self, visit_action) -> _Step:
        """The step of an action of a visit (``visit.enter`` / ``visit.leave``)."""
        self._sync()
        return self._step_of[id(visit_action)]

    # ----------------------------------------------------------------- switching

    def switch(self, group: Group) -> bool:
        """Switch ``group`` if the graph stays acyclic (see the module doc); returns
        whether it did. The AGVs waiting on its cells are woken."""
        self._sync()
        if not self._ok or not group.pairs:
            self.refused += 1
            return False
        queues = self.adg._queues
        for u, w in group.pairs:  # still as found (nothing moved since)?
            q = queues.get(u.cell)
            if q is None or u not in q or w not in q or not _movable(u, w, q):
                return False
        pend_u, pend_w = self._pend_u, self._pend_w
        for u, w in group.pairs:  # (j may pass a cell twice: then two w for one u)
            pend_u.setdefault(id(u), []).append(w)
            pend_w[id(w)] = u
        # A cycle through the last pair's edge alone (nearly every cycle found: its cell
        # is the one ``j`` reaches last) is found by one forward search, before the
        # other pairs' edges are inserted and renumbered in vain. (With ``check`` the
        # insertions go on, and must find it.)
        u, w = group.pairs[-1]
        cyclic = self._reaches(self._step_of[id(u.enter)], self._step_of[id(w.leave)])
        if cyclic and not self.check:
            pend_u.clear()
            pend_w.clear()
            self.refused += 1
            return False
        journal: list[tuple[_Step, int]] = []
        ver = self.adg.cell_version
        done: list[tuple[list[_Visit], int, int]] = []
        ok = True
        for u, w in group.pairs:
            q = queues[u.cell]
            iw, iu = q.index(w), q.index(u)
            q.insert(iu, q.pop(iw))  # w right before u
            ver[u.cell] += 1
            done.append((q, iu, iw))
            pend_u[id(u)].remove(w)
            del pend_w[id(w)]
            if not self._insert(self._step_of[id(w.leave)], self._step_of[id(u.enter)],
                                journal):
                ok = False
                break
        pend_u.clear()
        pend_w.clear()
        if cyclic and ok:
            raise AssertionError("the search found a cycle that the insertions did not")
        if not ok:
            for q, iu, iw in reversed(done):
                q.insert(iw, q.pop(iu))
                ver[q[iw].cell] += 1
            for node, old in reversed(journal):
                self._ord[node] = old
            self.refused += 1
            return False
        for u, _ in group.pairs:
            self.adg._touch(u.cell)
        self.switches += 1
        if self.check:
            self.adg.check_acyclic()
        return True

    # ----------------------------------------------------------------- the order

    def _sync(self) -> None:
        if self._version != self.adg.plan_version:
            self._rebuild()

    def _rebuild(self) -> None:
        """A topological order of the remaining actions from scratch (Kahn)."""
        adg = self.adg
        self._cands.clear()
        self._version = adg.plan_version
        self.rebuilds += 1
        self._where, self._chain, self._step_of, self._ord = {}, {}, {}, {}
        nodes: list[_Step] = []
        for agv in sorted(adg._agents):
            rec = adg._agents[agv]
            chain = ([rec.running] if rec.running is not None else []) + list(rec.pending)
            self._chain[agv] = chain
            for k, s in enumerate(chain):
                self._where[s] = (agv, k)
                self._step_of[id(s.action)] = s
            nodes += chain
        indeg = dict.fromkeys(nodes, 0)
        for s in nodes:
            for t in self._succ(s):
                indeg[t] += 1
        # Kahn's algorithm taking the ready action of the earliest planned start first
        # (then AGV id and place): an order close to the plan's time, so that a switch's
        # edge spans few actions of it and its search (:meth:`_insert`) stays small.
        todo = [(s.action.tick, *self._where[s]) for s in nodes if indeg[s] == 0]
        heapq.heapify(todo)
        chain, order = self._chain, self._ord
        while todo:
            _, agv, k = heapq.heappop(todo)
            s = chain[agv][k]
            order[s] = len(order)
            for t in self._succ(s):
                indeg[t] -= 1
                if indeg[t] == 0:
                    heapq.heappush(todo, (t.action.tick, *self._where[t]))
        self._ok = len(order) == len(nodes)

    def _live_from(self, agv: int) -> int:
        """Index in the AGV's chain of its first remaining action."""
        rec = self.adg._agents[agv]
        head = rec.running if rec.running is not None else (
            rec.pending[0] if rec.pending else None)
        return self._where[head][1] if head is not None else len(self._chain[agv])

    def _target(self, action) -> _Step | None:
        """The step a type-2 edge into ``action`` reaches (None: started or gone)."""
        if action is None:
            return None
        s = self._step_of.get(id(action))
        if s is None:
            return None
        agv, k = self._where[s]
        rec = self.adg._agents[agv]
        if rec.running is s or k < self._live_from(agv):
            return None
        return s

    def _after(self, q: list[_Visit], idx: int) -> list[_Visit]:
        """The visits right behind ``q[idx]``. A visit ``w`` of the group being switched
        whose old edges are out and new one not yet in hangs between the visit before
        its ``u`` and the visit after its own place."""
        k = idx + 1
        while k < len(q) and id(q[k]) in self._pend_w:
            k += 1
        if k >= len(q):
            return []
        return [q[k], *self._pend_u.get(id(q[k]), ())]

    def _before(self, q: list[_Visit], idx: int) -> list[_Visit]:
        """The visits right ahead of ``q[idx]`` (see :meth:`_after`)."""
        u = self._pend_w.get(id(q[idx]))
        if u is not None:
            iu = q.index(u)
            return [q[iu - 1]] if iu > 0 else []
        k = idx - 1
        out = []
        while k >= 0 and id(q[k]) in self._pend_w:
            out.append(q[k])
            k -= 1
        if k >= 0:
            out.append(q[k])
        return out

    def _succ(self, s: _Step) -> list[_Step]:
        agv, k = self._where[s]
        chain = self._chain[agv]
        out = [chain[k + 1]] if k + 1 < len(chain) else []
        queues = self.adg._queues
        for v in s.leave_visits:
            q = queues[v.cell]
            for w in self._after(q, q.index(v)):
                t = self._target(w.enter)
                if t is not None:
                    out.append(t)
        return out

    def _pred(self, s: _Step) -> list[_Step]:
        agv, k = self._where[s]
        rec = self.adg._agents[agv]
        if rec.running is s:
            return []
        out = [self._chain[agv][k - 1]] if k - 1 >= self._live_from(agv) else []
        queues = self.adg._queues
        for v in s.enter_visits:
            q = queues[v.cell]
            for u in self._before(q, q.index(v)):
                if u.leave is not None:
                    t = self._step_of.get(id(u.leave))
                    if t is not None:
                        out.append(t)
        return out

    def _forward(self, y: _Step, x: _Step) -> tuple[list[_Step] | bool, int]:
        """Pearce-Kelly's forward search from ``y`` over the actions ordered before ``x``:
        ``(True, _)`` if it reaches ``x`` (the edge ``x -> y`` would close a cycle),
        ``(False, _)`` if it gives up at the limit, else the actions found and the
        budget left."""
        order = self._ord
        ox = order[x]
        budget = self.search_limit
        fwd, seen, stack = [], {y}, [y]
        while stack:
            n = stack.pop()
            fwd.append(n)
            for m in self._succ(n):
                if m is x:
                    return True, budget
                if m not in seen and order[m] < ox:
                    seen.add(m)
                    stack.append(m)
            budget -= 1
            if budget <= 0:
                return False, budget
        return fwd, budget

    def _reaches(self, y: _Step, x: _Step) -> bool:
        """Whether ``y`` surely reaches ``x`` (so the edge ``x -> y`` would close a
        cycle): the forward search of :meth:`_insert` alone, without renumbering; False
        also when it gives up at the limit."""
        if self._ord[x] < self._ord[y]:
            return False
        return self._forward(y, x)[0] is True

    def _insert(self, x: _Step, y: _Step, journal: list[tuple[_Step, int]]) -> bool:
        """Insert the edge ``x -> y`` (Pearce-Kelly); False on a cycle or a search over
        the limit (the order is then as the journal says to restore)."""
        order = self._ord
        oy = order[y]
        if order[x] < oy:
            return True
        fwd, budget = self._forward(y, x)
        if isinstance(fwd, bool):
            return False
        back, seen_b, stack = [], {x}, [x]
        while stack:
            n = stack.pop()
            back.append(n)
            for m in self._pred(n):
                if m not in seen_b and order[m] > oy:
                    seen_b.add(m)
                    stack.append(m)
            budget -= 1
            if budget <= 0:
                return False
        back.sort(key=order.__getitem__)
        fwd.sort(key=order.__getitem__)
        moved = back + fwd
        slots = sorted(order[n] for n in moved)
        for n, p in zip(moved, slots, strict=True):
            journal.append((n, order[n]))
            order[n] = p
        return True
