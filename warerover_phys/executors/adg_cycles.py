"""Deadlocks and cycles of the action dependency graph (:mod:`.adg`): who waits for whom,
the cycles of that relation, and the full acyclicity check (Kahn's algorithm) with a
readable account of a cycle. A mixin of :class:`~.adg.ActionGraph` (its state is the
graph's)."""

from __future__ import annotations

from collections.abc import Iterator, Mapping

from .adg_types import Action, ADGCycleError, _Visit

__all__ = ["DeadlockChecks"]


class DeadlockChecks:
    """The deadlock half of :class:`~.adg.ActionGraph`."""


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
