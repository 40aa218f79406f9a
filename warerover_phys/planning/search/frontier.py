"""What the conflict-counting space-time A* searches share: their open list and move checks.

The low level of :mod:`~warerover_phys.planning.search.cbs` and the heading-aware searches of
:mod:`~warerover_phys.planning.search.turning_astar` search states ``(sid, t)`` (``sid`` an anchor, or an
anchor and a heading packed into one integer) and rank them by ``(f, conflicts, -t)``: the
lexicographic pair ``(f, conflicts)`` never decreases along a path, so a state is closed with
its fewest conflicts (with the conflict-avoidance table) among the shortest routes to it.
:class:`ConflictFrontier` is that open list; :func:`move_conflicts` checks one move against
the reservations and constraints and counts the conflicts of its inner ticks.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Iterator, Sequence

from ..graph import UNREACHABLE
from ..reservation import FOREVER, ReservationTable

__all__ = ["ConflictFrontier", "arrivals", "avoidance_hits", "free_check", "goal_free_tick",
           "move_conflicts", "swaps"]

Key = tuple[int, int]
"""A search state ``(sid, tick)``."""


class ConflictFrontier:
    """Open list, parent links, best conflict counts and closed set of one search, started
    at state ``(sid, t0)`` whose f-value is ``f0``; states with ``t + h > t_max`` are never
    pushed (they could not end by the search's deadline)."""

    __slots__ = ("heap", "parent", "best", "closed", "t_max", "goal", "expansions")

    def __init__(self, sid: int, t0: int, f0: int, t_max: int) -> None:
        self.heap: list[tuple[int, int, int, int, int]] = [(f0, 0, -t0, sid, t0)]
        self.parent: dict[Key, Key | None] = {(sid, t0): None}
        self.best: dict[Key, int] = {(sid, t0): 0}
        self.closed: set[Key] = set()
        self.t_max = t_max
        self.goal: Key | None = None
        self.expansions = 0

    def push(self, sid: int, t: int, conf: int, hn: int, frm: Key) -> None:
        """Offer state ``(sid, t)`` reached from ``frm`` with ``conf`` conflicts so far and
        heuristic ``hn``; kept only if it is open and better than any earlier offer."""
        key = (sid, t)
        if key in self.closed or conf >= self.best.get(key, UNREACHABLE) or t + hn > self.t_max:
            return
        self.best[key] = conf
        self.parent[key] = frm
        heapq.heappush(self.heap, (t + hn, conf, -t, sid, t))

    def pop(self) -> tuple[int, int, int] | None:
        """The next state to expand as ``(sid, t, conflicts)``, now closed; None when the
        open list is empty. Stale entries (closed, or since reached with fewer conflicts)
        are skipped."""
        heap, closed, best = self.heap, self.closed, self.best
        while heap:
            _, conf, _, sid, t = heapq.heappop(heap)
            key = (sid, t)
            if key in closed or conf > best[key]:
                continue
            closed.add(key)
            return sid, t, conf
        return None

    def expanding(self, max_expansions: int, t_limit: int,
                  at_goal: Callable[[int, int], bool]) -> Iterator[tuple[int, int, int]]:
        """The states to expand, best first, as :meth:`pop` gives them: the search loop of
        every space-time A* on this frontier. It ends at the first state ``at_goal(sid, t)``
        accepts (kept in :attr:`goal`; None when it ends otherwise), after
        ``max_expansions`` expansions or when the open list is empty; a state at or after
        ``t_limit`` counts as expanded but is not yielded. :attr:`expansions`: the states
        expanded, once it has ended."""
        expansions = 0
        while (top := self.pop()) is not None:
            sid, t, _ = top
            if at_goal(sid, t):
                self.goal = (sid, t)
                break
            expansions += 1
            if expansions > max_expansions:
                break
            if t >= t_limit:
                continue
            yield top
        self.expansions = expansions


def swaps(res: ReservationTable, here: tuple[int, ...], there: tuple[int, ...], t: int,
          me: int) -> bool:
    """True if another AGV now in ``there`` moves into ``here`` during tick ``t -> t + 1``."""
    for c in there:
        other = res.owner(c, t)
        if other is not None and other != me:
            for c2 in here:
                if res.owner(c2, t + 1) == other:
                    return True
    return False


def move_conflicts(res: ReservationTable, node: int, nxt: int, here: tuple[int, ...],
                   there: tuple[int, ...], t: int, m: int,
                   ok: Callable[[tuple[int, ...], int], bool],
                   hits: Callable[[tuple[int, ...], int], int], edge: set, me: int,
                   ) -> int | None:
    """A move from anchor ``node`` (cells ``here``) at tick ``t`` to ``nxt`` (cells
    ``there``), taking ``m`` ticks, whose arrival was already found free: None if a
    reservation, a swap or an edge constraint forbids it, else the conflicts of its inner
    ticks with the avoidance table (a slow move holds both footprints until it arrives).

    ``ok(cells, tick)``: the cells are free of reservations and vertex constraints then;
    ``hits(cells, tick)``: conflicts with the avoidance table; ``edge``: CBS edge
    constraints ``(tick, from state, to state)``."""
    if m > 1:
        both = tuple(dict.fromkeys(here + there))
        if not all(ok(both, t + i) for i in range(1, m)):
            return None
        if edge and ((t + 1, (node, node), (node, nxt)) in edge
                     or (t + m, (node, nxt), (nxt, nxt)) in edge):
            return None
        return sum(hits(both, t + i) for i in range(1, m))
    if swaps(res, here, there, t, me):
        return None
    if edge and (t + m, (node, node), (nxt, nxt)) in edge:
        return None
    return 0


def free_check(res: ReservationTable, me: int, vertex: dict[int, set[int]],
               never: dict[int, int]) -> Callable[[Sequence[int], int], bool]:
    """``ok(cells, tick)`` for AGV ``me``: no other AGV holds one of the cells then (planned
    or resting for good in ``res``), no CBS vertex constraint ``vertex`` (tick -> cells) bans
    one, and none is closed to it for good from ``never`` (cell -> first tick)."""
    occ, rest = res._occ, res._rest

    def ok(cells: Sequence[int], t: int) -> bool:
        banned = vertex.get(t)
        for c in cells:
            slot = occ.get(c)
            if slot is not None:
                a = slot.get(t)
                if a is not None and a != me:
                    return False
            r = rest.get(c)
            if r is not None and t >= r[0] and r[1] != me:
                return False
            if banned is not None and c in banned:
                return False
            if never and t >= never.get(c, FOREVER):
                return False
        return True

    return ok


def avoidance_hits(cat: dict[int, dict[int, int]], cat_rest: dict[int, int],
                   ) -> Callable[[Sequence[int], int], int]:
    """``hits(cells, tick)``: how many other planned AGVs of a conflict-avoidance table use
    the cells at that tick (``cat``: tick -> cell -> count; ``cat_rest``: cell -> tick from
    which an AGV rests there for good)."""
    if not cat and not cat_rest:
        return lambda cells, t: 0

    def hits(cells: Sequence[int], t: int) -> int:
        row = cat.get(t)
        n = 0
        for c in cells:
            if row is not None and c in row:
                n += row[c]
            else:
                r = cat_rest.get(c)
                if r is not None and t >= r:
                    n += 1
        return n

    return hits


def goal_free_tick(res: ReservationTable, me: int, goal_cells: tuple[int, ...],
                   cons=None) -> int | None:
    """Earliest tick from which the AGV may stay at the goal for good: after every fixed
    AGV's last use of the goal's cells and, with CBS constraints ``cons``
    (:class:`~warerover_phys.planning.search.cbs.Constraints`), after every vertex
    constraint on them and after its own "finish after" constraint (None: never)."""
    t_free = max((res.last_use(c, me) for c in goal_cells), default=-1) + 1
    if t_free >= FOREVER:
        return None
    if cons is not None:
        t_free = max(t_free, cons.finish_after + 1)
        for t, cells in cons.vertex.items():
            if t >= t_free and not cells.isdisjoint(goal_cells):
                t_free = t + 1
    return t_free


def arrivals(open_: ConflictFrontier, res: ReservationTable, fp: Callable, ok: Callable,
             hits: Callable, edge, me: int, m: int, far: int) -> Callable:
    """The move test of every space-time A* on ``open_``: ``arrive(node, nxt, nsid, here, t,
    hn)`` is the conflicts of the move ``node -> nxt`` started at tick ``t`` from the cells
    ``here`` into state ``nsid`` (its heuristic ``hn``), counted until it arrives, or None
    when that state is closed, cannot reach the goal (``hn >= far``), its cells are not
    free on arrival or the move breaks a constraint (:func:`move_conflicts`)."""
    closed = open_.closed

    def arrive(node: int, nxt: int, nsid: int, here: tuple[int, ...], t: int,
               hn: int) -> int | None:
        t_arr = t + m
        if (nsid, t_arr) in closed or hn >= far:
            return None
        there = fp(nxt)
        if not ok(there, t_arr):
            return None
        extra = move_conflicts(res, node, nxt, here, there, t, m, ok, hits, edge, me)
        return None if extra is None else extra + hits(there, t_arr)

    return arrive
