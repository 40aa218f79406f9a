"""Windowed Conflict-Based Search (Sharon et al. 2015) on top of the reservation table.

The AGVs of a request are planned *jointly*; every other AGV's committed path in the
reservation table is a fixed obstacle at every tick, its final rest included.

High level (the constraint tree, CT). Best-first on the sum of costs (each agent's cost is
the tick at which it reaches its goal for good, minus ``request.tick``); ties go to the node
with fewer conflicts, then to the node inserted first. A node's paths are checked pairwise
from ``request.tick`` to ``request.tick + horizon``; the earliest conflict (ties: lowest AGV
ids) splits the node in two, one child constraining each AGV (lower id first):

- *vertex* (footprints overlap at tick ``t``): "AGV i may not occupy cell ``c`` at ``t``" for
  one shared cell ``c``. It is checked against the AGV's whole occupancy, the ``k x k``
  footprint and, for a slow AGV, both footprints during the ``m - 1`` transit ticks. A
  conflict with an AGV that already rests at its goal yields the same constraint, which the
  low level reads as "the goal may not be held before ``t + 1``" (it may finish only after
  the last constrained tick on a goal cell), the standard CBS goal constraint;
- *swap* (each moves into cells the other leaves, in the same tick): "AGV i may not make
  the transition ``s -> s'`` into tick ``t``" (an edge constraint on its own states).

Low level: space-time A* per AGV as in :func:`~warerover_phys.planning.search.astar.space_time_astar`
(same moves, footprints, multi-tick moves, sinks, expansion cap), plus the AGV's CBS
constraints; among equally short paths it takes the one with the fewest cells shared with
the other planned AGVs' current paths (a conflict-avoidance table).

Turns in place. For turn-aware agents (:func:`~warerover_phys.planning.sweep.turn_aware`)
the low level searches with headings (:func:`~warerover_phys.planning.search.turning_astar.turning_astar`)
and the high level also finds *sweep* conflicts (a turn's swept cell held by another agent
at the turn's tick or the next: one child forbids the turn there then, the other the cell)
and *lock* conflicts (two turns at one tick sharing a turn lock: each child forbids one of
the turns); ``path_fits`` checks turns against the table too.

Window. Conflicts after ``request.tick + horizon`` are ignored by the high level, but the
grid executor follows committed paths exactly, so the result is made safe afterwards: the
CBS paths are taken in priority order (``priority``, then id) and each one is committed only
if it fits the reservation table over its *whole* length and rest (the same check as A*:
every occupied cell per tick, swaps, and nobody crossing its goal after it arrives). The
AGVs whose paths do not fit (the lower-priority side of a late conflict) are replanned by
prioritized A* (:class:`~warerover_phys.planning.search.astar.AStarPlanner`) around everything
committed so far. Use a horizon longer than any path for plain (unwindowed) CBS.

Fallback. When the high level runs out of ``max_nodes`` CT nodes or ``max_call_expansions``
low-level expansions (work budgets: the same on any machine), the ``time_budget_s`` safety
stop (monotonic clock; logged as a warning) or the request's ``deadline``, or when the CT is
exhausted, or when a
replanned AGV of the window repair finds no path, the whole request is handed to
:class:`~warerover_phys.planning.search.astar.AStarPlanner` on the table as it was received (every
planned AGV's old path put back). A budget stop sets ``result.budget_hits = 1`` (else 0).

Before the search, AGVs are given goals that cannot clash for good: an AGV whose goal a
resting non-planned AGV holds, or whose goal footprint overlaps that of an AGV of higher
priority in the same request, is sent to the nearest free anchor (``request.keep_clear``
respected) and listed in ``detours``. An AGV with no path even when alone among the fixed
AGVs keeps its old path, which then counts as fixed for the others, and is listed in
``failed``. Everything is deterministic except where the safety stop or deadline stops it.

>>> from warerover_phys.config import LayoutSpec
>>> from warerover_phys.layout import build_layout
>>> from warerover_phys.planning import AgentRequest, GraphSet, PlanRequest, ReservationTable
>>> from warerover_phys.planning.base import TimedPath
>>> layout = build_layout(LayoutSpec(grid=["###.####", "........", "######SR"]))
>>> res = ReservationTable(layout.cols)
>>> agents = [AgentRequest(0, 8, 15), AgentRequest(1, 14, 3)]  # head-on, one pocket
>>> for a in agents:
...     _ = res.commit(TimedPath(a.agv, 0, ((a.start, a.start),)), a.k)
>>> result = CBSPlanner().plan(PlanRequest(0, agents, GraphSet(layout), res))
>>> sorted(result.paths), result.failed, result.budget_hits
([0, 1], [], 0)
"""

from __future__ import annotations

import heapq
import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

from ..base import (
    AgentRequest,
    PlanRequest,
    PlanResult,
    State,
    TimedPath,
    footprint_nodes,
    occupancy,
)
from ..graph import UNREACHABLE, MotionGraph
from ..reservation import FOREVER, ReservationTable
from ..sweep import turn_aware
from .astar import AStarPlanner, _reconstruct, goal_held, nearest_free_anchor
from .conflicts import PairConflict, find_conflicts, path_fits
from .frontier import (
    ConflictFrontier,
    arrivals,
    avoidance_hits,
    free_check,
    goal_free_tick,
)
from .turning_astar import turning_astar

__all__ = ["CBSPlanner", "Constraints", "PairConflict", "constrained_astar", "find_conflicts",
           "path_fits"]

log = logging.getLogger(__name__)

EdgeConstraint = tuple[int, State, State]
"""``(t, s, s2)``: the AGV may not be in state ``s`` at ``t - 1`` and ``s2`` at ``t``."""


@dataclass(slots=True)
class Constraints:
    """The CBS constraints on one agent."""

    vertex: dict[int, set[int]] = field(default_factory=dict)
    """tick -> cells the agent may not occupy at that tick."""
    edge: set[EdgeConstraint] = field(default_factory=set)
    never: dict[int, int] = field(default_factory=dict)
    """cell -> first tick from which the agent may never occupy it (target reasoning)."""
    finish_after: int = -1
    """The agent may reach its goal for good only after this tick."""
    finish_by: int = FOREVER
    """... and at this tick at the latest."""
    noturn: set[tuple[int, int]] = field(default_factory=set)
    """``(anchor, tick)``: the agent may not start a turn in place there then (turn-aware
    agents only)."""

    def __len__(self) -> int:
        return len(self.vertex) + len(self.edge) + len(self.never) + (
            self.finish_after >= 0) + (self.finish_by < FOREVER) + len(self.noturn)

    def last_tick(self, default: int) -> int:
        return max(max(self.vertex, default=default), max((e[0] for e in self.edge),
                                                          default=default),
                   max(self.never.values(), default=default), self.finish_after,
                   max((t for _, t in self.noturn), default=default), default)


# ----------------------------------------------------------------------------- low level


def constrained_astar(graph: MotionGraph, res: ReservationTable, agent: AgentRequest, t0: int,
                      constraints: Constraints | None = None,
                      avoid: tuple[dict[int, dict[int, int]], dict[int, int]] | None = None,
                      max_expansions: int = 50_000) -> tuple[TimedPath | None, int]:
    """Space-time A* for one AGV from tick ``t0`` around the fixed AGVs in ``res`` and its
    CBS ``constraints``.

    ``avoid`` is a conflict-avoidance table ``(per-tick cell counts, cell -> rest tick)`` of
    the other planned AGVs: it only breaks ties between equally short paths. Returns (the
    shortest path that satisfies every constraint, or None; expansions).
    """
    if turn_aware(agent) or agent.turn_ticks is not None:
        return turning_astar(graph, res, agent, t0, constraints if constraints is not None
                             else Constraints(), avoid, max_expansions, cbs=True)
    cols, k, m, me = graph.cols, agent.k, agent.ticks_per_move, agent.agv
    start, goal = agent.start, agent.goal
    cons = constraints if constraints is not None else Constraints()
    vertex, edge, never = cons.vertex, cons.edge, cons.never
    cat, cat_rest = avoid if avoid is not None else ({}, {})

    def fp(node: int) -> tuple[int, ...]:
        return footprint_nodes(node, k, cols)

    ok = free_check(res, me, vertex, never)
    hits = avoidance_hits(cat, cat_rest)

    goal_cells = fp(goal)
    if any(c in never for c in goal_cells):
        return None, 0  # it could not stay there for good
    t_free = goal_free_tick(res, me, goal_cells, cons)
    if t_free is None:
        return None, 0
    h_table = graph.dist_to(graph.cell(goal))
    h0 = graph.distance(graph.cell(start), graph.cell(goal))
    t_max = cons.finish_by
    if h0 >= UNREACHABLE or max(t_free, t0 + h0 * m) > t_max:
        return None, 0
    t_limit = max(t_free, t0 + h0 * m, cons.last_tick(t0) + 1) + h0 * m + 64
    max_expansions = min(max_expansions, 40 * (h0 * m + 25 + len(cons)))

    def h(node: int) -> int:
        v = int(h_table[node])
        return v * m if v < UNREACHABLE else (h0 * m if node == start else UNREACHABLE)

    loaded_sinks = graph.has_sinks
    expandable = graph.expandable_flat
    neighbors = graph.neighbors
    # (f, conflicts) ordered: see planning.frontier.
    open_ = ConflictFrontier(start, t0, t0 + h(start), t_max)
    push = open_.push
    arrive = arrivals(open_, res, fp, ok, hits, edge, me, m, UNREACHABLE)
    for node, t, conf in open_.expanding(max_expansions, t_limit,
                                         lambda v, t: v == goal and t >= t_free):
        key = (node, t)
        here = fp(node)
        if ok(here, t + 1):  # wait one tick
            push(node, t + 1, conf + hits(here, t + 1), h(node), key)
        for nxt in (neighbors[node] if node == start or expandable[node] else ()):
            if loaded_sinks and nxt != goal and not expandable[nxt]:
                continue  # never drive into another shelf's home
            hn = h(nxt)
            extra = arrive(node, nxt, nxt, here, t, hn)
            if extra is not None:
                push(nxt, t + m, conf + extra, hn, key)
    if open_.goal is not None:
        return _reconstruct(open_.parent, *open_.goal, me), open_.expansions
    return None, open_.expansions


# ----------------------------------------------------------------------------- conflicts


# ----------------------------------------------------------------------------- high level


@dataclass(slots=True)
class _Node:
    paths: list[TimedPath]
    soc: int
    constraints: tuple | None
    """Linked list ``(agent index, kind, payload, parent's list)`` of this node's constraints."""
    conflicts: list[PairConflict]
    n_conflicts: int


def _constraints_of(chain: tuple | None, idx: int) -> Constraints:
    cons = Constraints()
    while chain is not None:
        agent, kind, payload, chain = chain
        if agent != idx:
            continue
        if kind == "vertex":
            cell, t = payload
            cons.vertex.setdefault(t, set()).add(cell)
        elif kind == "edge":
            cons.edge.add(payload)
        elif kind == "never":
            cell, t = payload
            cons.never[cell] = min(cons.never.get(cell, FOREVER), t)
        elif kind == "noturn":
            cons.noturn.add(payload)
        elif kind == "after":
            cons.finish_after = max(cons.finish_after, payload)
        else:  # "by"
            cons.finish_by = min(cons.finish_by, payload)
    return cons


def _branches(c: PairConflict) -> list[tuple[int, list[tuple[int, str, object]]]]:
    """Each child of a conflict: (the agent to replan, the constraints it adds)."""
    if c.kind == "vertex":
        return [(c.i, [(c.i, "vertex", (c.cell, c.tick))]),
                (c.j, [(c.j, "vertex", (c.cell, c.tick))])]
    if c.kind == "target":
        # Target reasoning (Li et al. 2020): either j reaches its goal for good after the
        # tick, or it is there by then, and then i may never be on that cell again.
        return [(c.j, [(c.j, "after", c.tick)]),
                (c.i, [(c.j, "by", c.tick), (c.i, "never", (c.cell, c.tick))])]
    if c.kind == "sweep":
        assert c.turn is not None
        other = (c.j, [(c.j, "noturn", c.turn_j)]) if c.turn_j is not None else \
            (c.j, [(c.j, "vertex", (c.cell, c.tick))])
        return [(c.i, [(c.i, "noturn", c.turn)]), other]
    if c.kind == "lock":
        return [(c.i, [(c.i, "noturn", c.turn)]), (c.j, [(c.j, "noturn", c.turn_j)])]
    assert c.moves is not None
    (a0, a1), (b0, b1) = c.moves
    return [(c.i, [(c.i, "edge", (c.tick, a0, a1))]), (c.j, [(c.j, "edge", (c.tick, b0, b1))])]


def _avoidance_table(paths: Sequence[TimedPath], skip: int, sizes: Sequence[int],
                     cols: int) -> tuple[dict[int, dict[int, int]], dict[int, int]]:
    cat: dict[int, dict[int, int]] = {}
    rest: dict[int, int] = {}
    for j, p in enumerate(paths):
        if j == skip:
            continue
        k = sizes[j]
        for i, s in enumerate(p.states[:-1]):
            row = cat.setdefault(p.start_tick + i, {})
            for c in occupancy(s, k, cols):
                row[c] = row.get(c, 0) + 1
        for c in occupancy(p.states[-1], k, cols):
            rest[c] = min(rest.get(c, FOREVER), p.end_tick)
    return cat, rest


def _expand(node: _Node, child, out_of_work, stop_at: float) -> list[_Node]:
    """The children of the first cardinal conflict among the node's first few (both children
    cost more), else of the first semi-cardinal one, else of the earliest (Boyarski et al.
    2015, found by building the children with ``child``). A child as cheap as its parent
    with fewer conflicts is taken by the parent instead (bypass)."""
    choice: tuple[int, list[_Node | None]] | None = None
    for conflict in node.conflicts:
        kids = [child(node, idx, adds) for idx, adds in _branches(conflict)]
        for kid in kids:
            if kid is not None and kid.soc == node.soc \
                    and kid.n_conflicts < node.n_conflicts:
                node.paths, node.conflicts = kid.paths, kid.conflicts
                node.n_conflicts = kid.n_conflicts
                return [node]
        rises = sum(1 for kid in kids if kid is None or kid.soc > node.soc)
        if choice is None or rises > choice[0]:
            choice = (rises, kids)
        if rises == len(kids) or out_of_work() or time.monotonic() > stop_at:
            break
    assert choice is not None
    return [kid for kid in choice[1] if kid is not None]


class CBSPlanner:
    """Windowed Conflict-Based Search with a prioritized A* fallback (see the module doc)."""

    name = "cbs"
    replans_all = False
    classify = 4
    """How many of a node's earliest conflicts are tried when looking for a cardinal one."""

    def __init__(self, max_expansions: int = 50_000, horizon: int = 20, max_nodes: int = 2_000,
                 time_budget_s: float = 10.0, max_call_expansions: int | None = 100_000,
                 ) -> None:
        self.max_expansions = max_expansions
        self.horizon = horizon
        self.max_nodes = max_nodes
        self.time_budget_s = time_budget_s
        self.max_call_expansions = max_call_expansions

    # ------------------------------------------------------------------------- entry point

    def plan(self, request: PlanRequest) -> PlanResult:
        t_start = time.monotonic()
        res = request.reservations
        old = {a.agv: res.paths.get(a.agv) for a in request.agents}
        if request.deadline is not None and t_start > request.deadline:
            return self._fallback(request, old, 0, budget_hit=True)
        for a in request.agents:
            res.release(a.agv)
        result = PlanResult()
        agents, paths, detours = self._roots(request, old, result)
        order = sorted(range(len(agents)), key=lambda i: agents[i].agv)
        agents = [agents[i] for i in order]
        paths = [paths[i] for i in order]
        solved, status = self._search(request, agents, paths, result, t_start)
        if solved is None:
            log.debug("CBS %s at tick %d: prioritized fallback", status, request.tick)
            return self._fallback(request, old, result.expansions, budget_hit=status == "budget")
        # Commit in priority order what fits for good; replan the rest with prioritized A*.
        demoted: list[AgentRequest] = []
        for i in sorted(range(len(agents)), key=lambda i: (agents[i].priority, agents[i].agv)):
            if path_fits(res, solved[i], agents[i].k, agents[i]):
                res.commit(solved[i], agents[i].k, agents[i].heading)
                result.paths[agents[i].agv] = solved[i]
            else:
                demoted.append(agents[i])
        if demoted:
            sub = AStarPlanner(self.max_expansions).plan(replace(request, agents=demoted))
            result.expansions += sub.expansions
            if sub.failed:
                log.debug("window repair failed for %s: prioritized fallback", sub.failed)
                return self._fallback(request, old, result.expansions, budget_hit=False)
            result.paths.update(sub.paths)
            detours |= set(sub.detours)
        result.detours = [a.agv for a in sorted(request.agents, key=_prio)
                          if a.agv in detours and a.agv in result.paths]
        result.budget_hits = 0
        return result

    # ------------------------------------------------------------------------- helpers

    def _roots(self, request: PlanRequest, old: dict[int, TimedPath | None],
               result: PlanResult) -> tuple[list[AgentRequest], list[TimedPath], set[int]]:
        """Goals that cannot clash for good, and each agent's path alone among the fixed
        AGVs. An agent without one keeps its old path, now fixed: start again."""
        res, cols = request.reservations, request.reservations.cols
        pending = sorted(request.agents, key=_prio)
        while True:
            agents: list[AgentRequest] = []
            paths: list[TimedPath] = []
            detours: set[int] = set()
            taken: set[int] = set()
            failed: AgentRequest | None = None
            for agent in pending:
                graph = request.graphs.get(agent.k, agent.loaded, agent.shelf)
                cells = set(footprint_nodes(agent.goal, agent.k, cols))
                if cells & taken or goal_held(graph, res, agent):
                    alt = nearest_free_anchor(graph, res, agent, keep_clear=request.keep_clear,
                                              avoid=frozenset(taken))
                    if alt is None:
                        failed = agent
                        break
                    agent = replace(agent, goal=alt)
                    detours.add(agent.agv)
                    cells = set(footprint_nodes(alt, agent.k, cols))
                # Tie-break towards paths that keep clear of the roots found so far.
                avoid = _avoidance_table(paths, -1, [a.k for a in agents], cols)
                path, n = constrained_astar(graph, res, agent, request.tick, avoid=avoid,
                                            max_expansions=self.max_expansions)
                result.expansions += n
                if path is None:
                    failed = agent
                    break
                taken |= cells
                agents.append(agent)
                paths.append(path)
            if failed is None:
                return agents, paths, detours
            result.failed.append(failed.agv)
            prev = old.get(failed.agv)
            if prev is not None:
                res.commit(prev, failed.k)
            pending = [a for a in pending if a.agv != failed.agv]

    def _search(self, request: PlanRequest, agents: list[AgentRequest],
                paths: list[TimedPath], result: PlanResult,
                t_start: float) -> tuple[list[TimedPath] | None, str]:
        """Best-first search of the constraint tree. Returns (paths, "solved") or
        (None, "budget" | "exhausted")."""
        res, t0 = request.reservations, request.tick
        cols = res.cols
        sizes = [a.k for a in agents]
        turns = agents if any(turn_aware(a) for a in agents) else None
        graphs = [request.graphs.get(a.k, a.loaded, a.shelf) for a in agents]
        t_end = t0 + self.horizon
        stop_at = t_start + self.time_budget_s
        if request.deadline is not None:
            stop_at = min(stop_at, request.deadline)

        def cost(p: TimedPath) -> int:
            return p.end_tick - t0

        def out_of_work() -> bool:
            """The work budget (deterministic): low-level expansions of this call."""
            return self.max_call_expansions is not None and \
                result.expansions >= self.max_call_expansions

        def child(node: _Node, idx: int, adds: list[tuple[int, str, object]]) -> _Node | None:
            chain = node.constraints
            for agent, kind, payload in adds:
                chain = (agent, kind, payload, chain)
            path, n = constrained_astar(graphs[idx], res, agents[idx], t0,
                                        _constraints_of(chain, idx),
                                        _avoidance_table(node.paths, idx, sizes, cols),
                                        self.max_expansions)
            result.expansions += n
            if path is None:
                return None
            new_paths = list(node.paths)
            new_paths[idx] = path
            conflicts, count = find_conflicts(new_paths, sizes, cols, t0, t_end,
                                              self.classify, turns, res.rows)
            return _Node(new_paths, node.soc - cost(node.paths[idx]) + cost(path), chain,
                         conflicts, count)

        conflicts, n_conf = find_conflicts(paths, sizes, cols, t0, t_end, self.classify, turns,
                                           res.rows)
        root = _Node(paths, sum(cost(p) for p in paths), None, conflicts, n_conf)
        counter = 0
        open_list: list[tuple[int, int, int, _Node]] = [(root.soc, n_conf, counter, root)]
        generated = 1
        while open_list:
            node = heapq.heappop(open_list)[3]
            if not node.conflicts:
                return node.paths, "solved"
            if generated >= self.max_nodes or out_of_work():
                return None, "budget"
            if time.monotonic() > stop_at:
                log.warning("CBS: wall-clock safety stop (%g s) hit at tick %d; this result "
                            "depends on machine speed (raise planner.time_budget_s or lower "
                            "planner.max_nodes / planner.max_call_expansions)",
                            self.time_budget_s, t0)
                return None, "budget"
            for kid in _expand(node, child, out_of_work, stop_at):
                generated += 1
                counter += 1
                heapq.heappush(open_list, (kid.soc, kid.n_conflicts, counter, kid))
        return None, "exhausted"

    def _fallback(self, request: PlanRequest, old: dict[int, TimedPath | None],
                  expansions: int, budget_hit: bool) -> PlanResult:
        """Put the table back as received and plan the request with prioritized A*."""
        res = request.reservations
        for a in request.agents:
            res.release(a.agv)
        for a in request.agents:
            prev = old.get(a.agv)
            if prev is not None:
                res.commit(prev, a.k)
        result = AStarPlanner(self.max_expansions).plan(request)
        result.expansions += expansions
        result.budget_hits = int(budget_hit)
        return result


def _prio(agent: AgentRequest) -> tuple:
    return (agent.priority, agent.agv)
