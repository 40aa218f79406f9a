"""Space-time A* with headings, for AGVs whose turns in place must be reserved (issue 13).

A differential-drive AGV turns in place before every move whose direction differs from the
one it faces (its last move's). When its body's swept disc leaves its footprint
(:mod:`~warerover_phys.planning.sweep`), such a turn is a reservation of its own, and
:func:`turning_astar` searches over states ``(anchor, heading, tick)``:

- a move from ``a`` in a new direction at tick ``t`` is a turn at ``a``: allowed only if
  ``a`` is not a no-turn anchor (``agent.no_turn``: the disc would reach a wall), the
  turn's swept cells are free of other AGVs at ``t`` and ``t + 1``, and no other AGV's
  turn at ``t`` holds one of its turn locks (both read from the reservation table, which
  holds the committed turns of the other AGVs the same way);
- no move enters a *dead end* (:func:`~warerover_phys.planning.sweep.dead_ends`): a
  no-turn anchor faced so that straight ahead never leads to a place to turn;
- everything else is the space-time A* of :mod:`astar` and, with CBS constraints and a
  conflict-avoidance table, the low level of :mod:`cbs` (same moves, footprints, slow
  moves, sinks, swaps, goal rules and work budgets). CBS adds *no-turn* constraints
  ``(anchor, tick)``: the AGV may not start a turn there then.

Turns take no ticks of their own in the plan (the physics executor spends the turn's time
inside the move, and its dependency graph orders overlapping turns).

Rotations (issue 15, ``planner.rotations``; :mod:`~warerover_phys.planning.rotation`): for an
agent with ``turn_ticks`` the same search moves only along the heading and turns in place as
actions of their own: a quarter turn (either way) takes ``turn_ticks[0]`` ticks, a half turn
``turn_ticks[1]``, standing on the anchor throughout (CBS no-turn constraints and the turn
checks above apply at the turn's first tick); the heuristic is the exact single-agent
distance over (anchor, heading) in ticks (:func:`~warerover_phys.planning.rotation.
graph_rotation_dist`), and the path carries the heading of every state.

Only AGVs that need it are searched this way (:func:`~warerover_phys.planning.sweep.
turn_aware`): for the default 0.7 m bodies on 1 m cells nothing changes.
"""

from __future__ import annotations

from collections.abc import Callable

from ..base import AgentRequest, State, TimedPath, footprint_nodes
from ..graph import UNREACHABLE, MotionGraph
from ..reservation import FOREVER, ReservationTable
from ..rotation import UNREACHABLE_T, graph_rotation_dist
from ..sweep import DIR_OF, lock_keys, move_dir, sweep_cells
from .frontier import (
    ConflictFrontier,
    arrivals,
    avoidance_hits,
    free_check,
    goal_free_tick,
)

__all__ = ["turning_astar", "turn_ok", "heading_index", "request_turn_fields"]

_NONE = 4
"""Heading index for "unknown" (the first move counts as a turn)."""


def heading_index(heading: tuple[int, int] | None) -> int:
    return _NONE if heading is None else DIR_OF[heading]


def request_turn_fields(graphs, masks, sweep, heading: tuple[int, int] | None, k: int,
                        loaded: bool, shelf: int | None, goal: int,
                        after: tuple[bool, int | None] | None) -> dict:
    """The :class:`~warerover_phys.planning.base.AgentRequest` fields of a turn-aware AGV:
    ``heading``, ``sweep``, ``no_turn`` for how it drives now (``masks``: its
    :class:`~warerover_phys.planning.sweep.TurnMasks`; loaded: carrying ``shelf``), and
    ``goal_dead`` for ``after`` = (loaded, shelf) once its work at the goal is done (None:
    unchanged)."""
    no_turn = masks.carrying(shelf) if loaded else masks.walls
    goal_dead = None
    if after is not None and after != (loaded, shelf if loaded else None):
        loaded2, shelf2 = after
        no_turn2 = masks.carrying(shelf2) if loaded2 else masks.walls
        dead2 = graphs.get(k, loaded2, shelf2).dead_ends(no_turn2)
        goal_dead = frozenset(d for d in range(4) if (goal, d) in dead2)
    return {"heading": heading, "sweep": sweep, "no_turn": no_turn, "goal_dead": goal_dead}


def turn_ok(res: ReservationTable, agent: AgentRequest, node: int, t: int, rows: int,
            cols: int) -> bool:
    """May ``agent`` turn in place at anchor ``node`` at tick ``t`` given the committed
    paths of ``res``? (Not a no-turn anchor, swept cells free at ``t`` and ``t + 1``,
    turn locks free at ``t``.)"""
    if node in agent.no_turn:
        return False
    sw = agent.sweep
    if sw is None:
        return True
    me = agent.agv
    for c in sweep_cells(node, sw.cells, rows, cols):
        if not (res.free(c, t, me) and res.free(c, t + 1, me)):
            return False
    return not sw.locks or res.locks_free(lock_keys(node, sw.locks, rows, cols), t, me)


def turning_astar(graph: MotionGraph, res: ReservationTable, agent: AgentRequest, t0: int,
                  constraints=None, avoid=None, max_expansions: int = 50_000,
                  budget_per_move: int | None = 40, cbs: bool = False,
                  ) -> tuple[TimedPath | None, int]:
    """Search one turn-aware AGV's path from tick ``t0`` (see the module doc). With
    ``cbs`` the budgets and limits of :func:`~warerover_phys.planning.search.cbs.constrained_astar`
    apply (``constraints``: its :class:`~warerover_phys.planning.search.cbs.Constraints`;
    ``avoid``: its conflict-avoidance table), else those of
    :func:`~warerover_phys.planning.search.astar.space_time_astar`. Returns (path or None,
    expansions)."""
    cols, rows, k, m, me = graph.cols, graph.rows, agent.k, agent.ticks_per_move, agent.agv
    start, goal = agent.start, agent.goal
    cap = max_expansions
    vertex = constraints.vertex if constraints is not None else {}
    edge = constraints.edge if constraints is not None else set()
    never = constraints.never if constraints is not None else {}
    noturn = constraints.noturn if constraints is not None else set()
    cat, cat_rest = avoid if avoid is not None else ({}, {})
    no_turn = agent.no_turn
    dead = graph.dead_ends(no_turn)
    sw = agent.sweep
    sw_cells = sw.cells if sw is not None else ()
    sw_locks = sw.locks if sw is not None else ()

    def fp(node: int) -> tuple[int, ...]:
        return footprint_nodes(node, k, cols)

    ok = free_check(res, me, vertex, never)
    hits = avoidance_hits(cat, cat_rest)

    def can_turn(node: int, t: int) -> bool:
        if node in no_turn or (noturn and (node, t) in noturn):
            return False
        if sw_cells:
            cells = sweep_cells(node, sw_cells, rows, cols)
            if not (ok(cells, t) and ok(cells, t + 1)):
                return False
        return not sw_locks or res.locks_free(lock_keys(node, sw_locks, rows, cols), t, me)

    goal_cells = fp(goal)
    if any(c in never for c in goal_cells):
        return None, 0
    goal_dead = agent.goal_dead
    if no_turn and (start, heading_index(agent.heading)) not in graph.turn_dist(
            no_turn, goal, goal_dead):
        return None, 0  # no way there without turning where it may not
    t_free = goal_free_tick(res, me, goal_cells, constraints)
    if t_free is None:
        return None, 0
    t_max = constraints.finish_by if constraints is not None else FOREVER
    h_table = graph.dist_to(graph.cell(goal))
    h0 = graph.distance(graph.cell(start), graph.cell(goal))
    if h0 >= UNREACHABLE or max(t_free, t0 + h0 * m) > t_max:
        return None, 0
    last = constraints.last_tick(t0) + 1 if cbs and constraints is not None else t0
    t_limit = max(t_free, t0 + h0 * m, last) + h0 * m + 64
    n_cons = len(constraints) if cbs and constraints is not None else 0
    max_expansions = _budget(cap, h0 * m, cbs, n_cons, budget_per_move)

    def h(node: int) -> int:
        v = int(h_table[node])
        return v * m if v < UNREACHABLE else (h0 * m if node == start else UNREACHABLE)

    rot = agent.turn_ticks
    if rot is not None:
        hr = _rotation_h(graph, agent, m, h)
        h_start = hr(start, heading_index(agent.heading))
        t_limit += h_start - h0 * m
        max_expansions = _budget(cap, h_start, cbs, n_cons, budget_per_move)

    s0 = start * 5 + heading_index(agent.heading)
    if rot is not None:
        return _rotating_search(graph, agent, t0, s0, t_free, t_max, t_limit, max_expansions,
                                hr, ok, hits, can_turn, edge, dead, fp, m, res, me)
    return _plain_search(graph, agent, t0, s0, t_free, t_max, t_limit, max_expansions, h, ok,
                         hits, can_turn, edge, dead, fp, m, res, me)


def _budget(cap: int, span: int, cbs: bool, n_cons: int, budget_per_move: int | None) -> int:
    """Expansions allowed a search whose shortest path takes ``span`` ticks: the budgets of
    :func:`~warerover_phys.planning.search.cbs.constrained_astar` with ``cbs``, else
    ``budget_per_move`` per tick of it (None: ``cap``), never over ``cap``."""
    if cbs:
        return min(cap, 40 * (span + 25 + n_cons))
    if budget_per_move is not None:
        return min(cap, budget_per_move * (span + 25))
    return cap


def _rotation_h(graph: MotionGraph, agent: AgentRequest, m: int, h):
    """The heuristic with rotations: ticks to the goal from (anchor, heading), turns counted
    (:func:`~warerover_phys.planning.rotation.graph_rotation_dist`); ``h`` (plus a half
    turn at the start) where that table has no entry."""
    rot, start = agent.turn_ticks, agent.start
    r_table = graph_rotation_dist(graph, agent.goal, m, rot[0], rot[1])
    r_min = r_table.min(axis=1)

    def hr(node: int, hd: int) -> int:
        v = int(r_table[node, hd] if hd < 4 else r_min[node])
        if v < UNREACHABLE_T:
            return v
        return h(node) + (rot[1] if node == start else 0)

    return hr


def _plain_search(graph: MotionGraph, agent: AgentRequest, t0: int, s0: int, t_free: int,
                  t_max: int, t_limit: int, max_expansions: int, h, ok, hits, can_turn,
                  edge, dead, fp, m: int, res: ReservationTable, me: int,
                  ) -> tuple[TimedPath | None, int]:
    """The search of :func:`turning_astar` without rotations: states ``anchor * 5 +
    heading`` (the last move's direction, 4 while unknown); a move that changes the heading
    needs a turn in place that ``can_turn`` allows, and takes no extra time."""
    goal, start, goal_dead = agent.goal, agent.start, agent.goal_dead
    open_ = ConflictFrontier(s0, t0, t0 + h(start), t_max)
    push = open_.push
    arrive = arrivals(open_, res, fp, ok, hits, edge, me, m, UNREACHABLE)
    for sid, t, conf in open_.expanding(max_expansions, t_limit,
                                        _goal_test(goal, t_free, goal_dead)):
        key = (sid, t)
        node, hd = divmod(sid, 5)
        here = fp(node)
        if ok(here, t + 1):  # wait one tick
            push(sid, t + 1, conf + hits(here, t + 1), h(node), key)
        for nxt, d in _moves(graph, node, start, goal, goal_dead, dead):
            nsid = nxt * 5 + d
            hn = h(nxt)
            extra = arrive(node, nxt, nsid, here, t, hn)
            if extra is None or (d != hd and not can_turn(node, t)):
                continue
            push(nsid, t + m, conf + extra, hn, key)
    if open_.goal is not None:
        return _reconstruct(open_.parent, open_.goal, me), open_.expansions
    return None, open_.expansions


def _moves(graph: MotionGraph, node: int, start: int, goal: int, goal_dead, dead):
    """The moves ``(next anchor, direction)`` from ``node`` the searches may take: out of
    an expandable node (or the start), never into another shelf's home, never into a dead
    end, never into the goal facing a way ``goal_dead`` forbids."""
    expandable = graph.expandable_flat
    if not (node == start or expandable[node]):
        return
    loaded_sinks, cols = graph.has_sinks, graph.cols
    for nxt in graph.neighbors[node]:
        if loaded_sinks and nxt != goal and not expandable[nxt]:
            continue  # never drive into another shelf's home
        d = move_dir(node, nxt, cols)
        if nxt == goal and goal_dead is not None:
            if d in goal_dead:
                continue  # it would start its work there facing the wrong way
        elif (nxt, d) in dead:
            continue
        yield nxt, d


def _goal_test(goal: int, t_free: int, goal_dead) -> Callable[[int, int], bool]:
    """The goal test of the searches on states ``anchor * 5 + heading``: at the goal from
    ``t_free`` on, not facing a way ``goal_dead`` forbids."""
    def at_goal(sid: int, t: int) -> bool:
        node, hd = divmod(sid, 5)
        return node == goal and t >= t_free and (goal_dead is None or hd not in goal_dead)

    return at_goal


def _reconstruct(parent: dict, key: tuple[int, int], agv: int,
                 rotations: bool = False) -> TimedPath:
    """The path to ``key``; with ``rotations`` also the heading of every state (a turn
    keeps the old heading until its last tick; unknown headings become the first move's
    direction, east if it never moves)."""
    chain: list[tuple[int, int, int]] = []
    walk: tuple[int, int] | None = key
    while walk is not None:
        chain.append((walk[0] // 5, walk[0] % 5, walk[1]))
        walk = parent[walk]
    chain.reverse()
    states: list[State] = [(chain[0][0], chain[0][0])]
    heads: list[int] = [chain[0][1]]
    for (a, ha, ta), (b, hb, tb) in zip(chain, chain[1:], strict=False):
        hold = hb if a != b else ha
        for _ in range(tb - ta - 1):
            states.append((a, b))
            heads.append(hold)
        states.append((b, b))
        heads.append(hb)
    if not rotations:
        return TimedPath(agv=agv, start_tick=chain[0][2], states=tuple(states))
    known = next((h for h in heads if h < 4), 0)
    heads = [known if h == 4 else h for h in heads]
    return TimedPath(agv=agv, start_tick=chain[0][2], states=tuple(states),
                     headings=tuple(heads))


def _rotating_search(graph: MotionGraph, agent: AgentRequest, t0: int, s0: int, t_free: int,
                     t_max: int, t_limit: int, max_expansions: int, hr, ok, hits, can_turn,
                     edge, dead, fp, m: int, res: ReservationTable, me: int,
                     ) -> tuple[TimedPath | None, int]:
    """The search of :func:`turning_astar` with rotations (see the module doc): states
    ``anchor * 5 + heading``; moves only along the heading (any way while it is unknown),
    quarter and half turns in place that take ``agent.turn_ticks``."""
    assert agent.turn_ticks is not None
    q1, q2 = agent.turn_ticks
    goal, start, goal_dead = agent.goal, agent.start, agent.goal_dead
    open_ = ConflictFrontier(s0, t0, t0 + hr(start, s0 % 5), t_max)
    push = open_.push
    arrive = arrivals(open_, res, fp, ok, hits, edge, me, m, UNREACHABLE_T)
    for sid, t, conf in open_.expanding(max_expansions, t_limit,
                                        _goal_test(goal, t_free, goal_dead)):
        key = (sid, t)
        node, hd = divmod(sid, 5)
        here = fp(node)
        if ok(here, t + 1):  # wait one tick
            push(sid, t + 1, conf + hits(here, t + 1), hr(node, hd), key)
        if hd < 4:  # turn in place: a quarter either way, or half round
            for h2, q in (((hd + 1) % 4, q1), ((hd + 3) % 4, q1), ((hd + 2) % 4, q2)):
                if q2 >= 2 * q1 and h2 == (hd + 2) % 4:
                    continue  # two quarter turns are as fast
                if all(ok(here, t + i) for i in range(1, q + 1)) and can_turn(node, t):
                    push(node * 5 + h2, t + q,
                         conf + sum(hits(here, t + i) for i in range(1, q + 1)),
                         hr(node, h2), key)
        for nxt, d in _moves(graph, node, start, goal, goal_dead, dead):
            if hd < 4 and d != hd:
                continue  # only along the heading
            nsid = nxt * 5 + d
            hn = hr(nxt, d)
            extra = arrive(node, nxt, nsid, here, t, hn)
            if extra is None or (hd == 4 and not can_turn(node, t)):
                continue
            push(nsid, t + m, conf + extra, hn, key)
    if open_.goal is not None:
        return _reconstruct(open_.parent, open_.goal, me, rotations=True), open_.expansions
    return None, open_.expansions
