"""What a planner's answer must satisfy: paths, headings, turn conflicts, edges, goals."""

from __future__ import annotations

from .common import STEP_TICKS, _Checker, _short


def _check_paths(world, agents: list, result, tick: int, ck: _Checker) -> None:
    """Every returned path: its format and start, the motion graph, no conflicts with the
    committed paths or each other, its headings and its turns in place."""
    _check_path_format(world, agents, result, tick, ck)
    paths = _check_conflict_free(world, result, tick, ck)
    _check_headings(world, agents, result, ck)
    _check_turns(world, agents, result, paths, tick, ck)


def _check_path_format(world, agents: list, result, tick: int, ck: _Checker) -> None:
    from ..planning.paths import TimedPath

    by_id = {a.agv: a for a in agents}
    committed = world.reservations
    stray = sorted(set(result.paths) - set(by_id))
    if stray:
        ck.fail("asked AGVs only", f"it returned paths for AGVs {stray}, which were not in "
                "request.agents", "return paths only for the AGVs of request.agents (the "
                "reservations hold the others' paths: read them, do not replan them)")
    ck.ok("asked AGVs only")
    for aid, path in result.paths.items():
        a = by_id[aid]
        if not isinstance(path, TimedPath) or path.agv != aid or not path.states:
            ck.fail("path format", f"paths[{aid}] is {_short(path)}",
                    f"map each AGV id to TimedPath(agv={aid}, start_tick=request.tick, "
                    "states=((node, node), ...)) with at least one state")
        bad = next((s for s in path.states if not (isinstance(s, tuple) and len(s) == 2 and all(
            type(x) is int for x in s))), None)
        if bad is not None:
            ck.fail("path format", f"AGV {aid}'s path has the state {bad!r} "
                    f"({type(bad).__name__} of {', '.join(type(x).__name__ for x in bad)})"
                    if isinstance(bad, tuple) else f"AGV {aid}'s path has the state {bad!r}",
                    "make every state a tuple of two Python ints (int(node)): numpy integers "
                    "do not serialise to paths.json")
        now = committed.paths[aid].state_at(tick)
        here = now if now[0] != now[1] and now[1] == a.start else (a.start, a.start)
        if path.start_tick != tick or path.states[0] != here:
            ck.fail("path start", f"AGV {aid}'s path starts at tick {path.start_tick} in state "
                    f"{path.states[0]}, but the request is for tick {tick} and the AGV is in "
                    f"state {here}", "start every path at request.tick with the state the AGV "
                    "is in: (agent.start, agent.start) when it stands")
        _check_edges(world, a, path, ck)
    ck.ok("path format")
    ck.ok("path start")
    ck.ok("motion graph")


def _check_conflict_free(world, result, tick: int, ck: _Checker) -> dict:
    """The committed paths with the returned ones (returned), checked for conflicts."""
    from ..validate import validate_states

    committed = world.reservations
    paths = {agv: committed.paths[agv] for agv in committed.paths}
    paths.update(result.paths)
    horizon = max(p.end_tick for p in paths.values()) + 2
    states = {agv: [p.state_at(t) for t in range(tick, horizon)] for agv, p in paths.items()}
    conflicts = validate_states(states, world.layout.obstacles,
                                sizes={a.id: a.k for a in world.agvs},
                                ticks_per_move={a.id: a.ticks_per_move for a in world.agvs},
                                start_tick=tick)
    if conflicts:
        c = conflicts[0]
        mine = [x for x in c.agvs if x in result.paths]
        others = [x for x in c.agvs if x not in result.paths]
        if c.kind in ("vertex", "swap") and others:
            what = (f"AGV {mine[0]}'s new path runs into AGV {others[0]}'s committed path "
                    f"({c})", "check request.reservations.free(cell, t, agv) for every cell "
                    "of the footprint (both footprints while moving) before using it, and "
                    "stay off cells another AGV rests on for good (reservations.last_use)")
        elif c.kind in ("vertex", "swap"):
            what = (f"two returned paths conflict ({c})", "commit each new path into "
                    "request.reservations (reservations.commit(path, agent.k)) before "
                    "planning the next AGV, or resolve conflicts jointly")
        elif c.kind == "move":
            what = (f"a returned path breaks the motion rules ({c}: not a wait, or a move to "
                    "a 4-neighbour that does not take exactly ticks_per_move ticks)",
                    "move one cell at a time along graph edges; a slow AGV holds (a, b) for "
                    "ticks_per_move - 1 ticks, then stands at (b, b)")
        else:
            what = (f"a returned path leaves the floor ({c})", "use only nodes of "
                    "request.graphs.get(agent.k, agent.loaded, agent.shelf)")
        ck.fail("conflict-free", *what)
    ck.ok("conflict-free")
    return paths


def _check_turns(world, agents: list, result, paths: dict, tick: int, ck: _Checker) -> None:
    turns = plan_turn_conflicts(world, paths, tick, {a.agv: a.heading for a in agents})
    if turns:
        c = turns[0]
        mine = [x for x in c.agvs if x in result.paths]
        fixes = {
            "sweep": "keep the cells agent.sweep.cells (offsets from the anchor) of every "
                     "turn in place free of other AGVs at the turn's tick and the next "
                     "(reservations.free), and off cells other AGVs' turns sweep",
            "turn_lock": "never turn at the same tick as another AGV whose turn shares one "
                         "of agent.sweep.locks (reservations.locks_free)",
            "turn_wall": "never turn in place at an anchor in agent.no_turn (drive straight "
                         "through it)"}
        ck.fail("turn sweeps", f"a returned path {'of AGV ' + str(mine[0]) + ' ' if mine else ''}"
                f"turns in place where it may not ({c})",
                fixes[c.kind] + "; a turn is a move whose direction differs from the AGV's "
                "heading (agent.heading, then its last move's); see "
                "warerover_phys.planning.search.turning_astar")
    ck.ok("turn sweeps")


def _check_headings(world, agents: list, result, ck: _Checker) -> None:
    """Rotation-aware agents (``turn_ticks`` set): their paths carry one heading per
    state, start facing the agent's heading, move only straight ahead and turn no faster
    than ``turn_ticks`` allow."""
    from ..planning.sweep import DIR_OF
    from ..validate import validate_headings

    rot = [a for a in agents if getattr(a, "turn_ticks", None) is not None
           and a.agv in result.paths]
    if not rot:
        return
    for a in rot:
        path = result.paths[a.agv]
        heads = path.headings
        if heads is None or len(heads) != len(path.states):
            ck.fail("headings", f"AGV {a.agv} is rotation-aware (agent.turn_ticks = "
                    f"{a.turn_ticks}) but its path has headings {_short(heads)} for "
                    f"{len(path.states)} states", "give TimedPath(..., headings=(h0, h1, "
                    "...)) one direction index (0 east, 1 south, 2 west, 3 north) per state")
        if a.heading is not None and heads[0] != DIR_OF[a.heading]:
            ck.fail("headings", f"AGV {a.agv}'s path starts facing {heads[0]}, but the "
                    f"agent faces {DIR_OF[a.heading]} (agent.heading = {a.heading})",
                    "start every path with the heading the agent has now")
        found = validate_headings({a.agv: path.states}, {a.agv: heads}, world.layout.cols,
                                  turn_ticks={a.agv: a.turn_ticks},
                                  start_tick=path.start_tick)
        if found:
            ck.fail("headings", f"AGV {a.agv}'s path breaks the rotation rules ({found[0]}: "
                    f"{found[0].kind})", "move only along the heading (the direction of "
                    "headings[i] before the move); turn in place a quarter at a time, "
                    "standing turn_ticks[0] ticks per quarter (turn_ticks[1] for a half "
                    "turn), the new heading on the turn's last state; see "
                    "warerover_phys.planning.rotation")
    ck.ok("headings")


def plan_turn_conflicts(world, paths: dict, tick: int,
                        headings: dict | None = None, max_conflicts: int = 100,
                        loaded: dict | None = None) -> list:
    """Turn-in-place conflicts (:func:`~warerover_phys.planning.sweep_checks.sweep_conflicts`:
    ``sweep``, ``turn_lock``, ``turn_wall``) of the timed ``paths`` (``agv -> TimedPath``)
    from ``tick`` on, for ``world``'s fleet and layout (empty when no AGV's turn holds
    anything). ``headings``: the heading of AGVs at ``tick`` (for paths that start then);
    the others' headings are worked out from their paths and the reservation table.
    ``loaded`` (``agv -> bool``, or one bool per tick from ``tick``): also the turns beside
    AGVs that carry a shelf (``shelf_sweep``; planners do not reserve these yet, the
    physics executor's dependency graph makes such a turn wait)."""
    from ..planning.sweep import turn_fields
    from ..planning.sweep_checks import heading_after, sweep_conflicts

    fields = turn_fields(world.layout, [a.spec for a in world.agvs])
    if not fields:
        return []
    cols = world.layout.cols
    res = world.reservations
    horizon = max(p.end_tick for p in paths.values()) + 2
    states = {agv: [p.state_at(t) for t in range(tick, horizon)] for agv, p in paths.items()}
    heads = {}
    for agv, p in paths.items():
        if headings is not None and agv in headings and p.start_tick == tick:
            heads[agv] = headings[agv]
        else:
            heads[agv] = heading_after(p.states[:max(0, tick - p.start_tick) + 1], cols,
                                       res.heading_at_start(agv))
    return sweep_conflicts(
        states, world.layout.rows, cols, {a.id: a.k for a in world.agvs},
        {a: sw.cells for a, (sw, _) in fields.items() if sw is not None},
        start_tick=tick, headings=heads, max_conflicts=max_conflicts,
        locks={a: sw.locks for a, (sw, _) in fields.items() if sw is not None},
        no_turn={a: nt for a, (_, nt) in fields.items()},
        shelf_offsets=None if loaded is None else {
            a: sw.shelf_cells for a, (sw, _) in fields.items() if sw is not None},
        loaded=loaded)


def _check_edges(world, agent, path, ck: _Checker) -> None:
    """Every state is an enterable anchor or a move along an edge of the AGV's graph."""
    graph = world.graphs.get(agent.k, agent.loaded, agent.shelf)
    cols = graph.cols
    prev = None
    for i, (a, b) in enumerate(path.states):
        t = path.start_tick + i
        for node in (a, b):
            if not 0 <= node < graph.num_nodes or not graph.enterable.ravel()[node]:
                ck.fail("motion graph", f"AGV {agent.agv} ({agent.k}x{agent.k}) is at node "
                        f"{node} = cell {divmod(node, cols)} at tick {t}, which its footprint "
                        "cannot occupy (off the grid, on an obstacle, or on a shelf when "
                        "loaded)", "search request.graphs.get(agent.k, agent.loaded, "
                        "agent.shelf) and use only its nodes")
        moves = [(a, b)] if a != b else []
        if prev is not None and prev[0] == prev[1] and a == b and a != prev[0]:
            moves.append((prev[0], a))
        for u, v in moves:
            if v not in graph.neighbors[u]:
                ck.fail("motion graph", f"AGV {agent.agv} moves from {divmod(u, cols)} to "
                        f"{divmod(v, cols)} at tick {t}, which is not an edge of its motion "
                        "graph (a jump, a diagonal or a move into a blocked footprint)",
                        "take each step from graph.neighbors[node] (or wait in place)")
        prev = (a, b)


def _check_goals(world, goals: dict[int, int], replans_all: bool, ck: _Checker) -> None:
    res = world.reservations
    for agv, goal in goals.items():
        path = res.paths[agv]
        if path.states[-1] != (goal, goal):
            end = divmod(path.states[-1][1], world.layout.cols)
            within = f"within {STEP_TICKS} ticks" if replans_all else "in one call"
            ck.fail("reaches goals", f"AGV {agv} ends at {end}, not at its goal "
                    f"{divmod(goal, world.layout.cols)} ({within}, on an open floor where it "
                    "can)", "plan each path to the agent's goal (the last state must be "
                    "(goal, goal)); put AGVs you cannot plan in PlanResult.failed")
    ck.ok("reaches goals")
