"""Windowed Conflict-Based Search: valid plans, optimality against brute force, budgets."""

from __future__ import annotations

import doctest
import heapq
import itertools
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from warerover_phys.config import LayoutSpec
from warerover_phys.layout import build_layout
from warerover_phys.planning import (
    AgentRequest,
    AStarPlanner,
    GraphSet,
    Planner,
    PlanRequest,
    ReservationTable,
    TimedPath,
)
from warerover_phys.planning.search import cbs as cbs_module
from warerover_phys.planning.search.cbs import CBSPlanner, find_conflicts
from warerover_phys.validate import validate_states

# --------------------------------------------------------------------------- helpers
# (the same pattern as tests/planning/test_planning.py)


def make_layout(rows: list[str]):
    # A layout needs a station and a shelf; unloaded AGVs drive over both.
    return build_layout(LayoutSpec(grid=rows))


def plan_all(layout, agents: list[AgentRequest], planner=None, tick: int = 0,
             fixed: tuple[tuple[TimedPath, int], ...] = ()):
    """Commit a resting path for every agent (and the ``fixed`` paths), then plan the agents
    jointly; return (result, table)."""
    res = ReservationTable(layout.cols)
    for path, k in fixed:
        res.commit(path, k)
    for a in agents:
        res.commit(TimedPath(a.agv, tick, ((a.start, a.start),)), a.k)
    planner = planner or CBSPlanner()
    result = planner.plan(PlanRequest(tick, agents, GraphSet(layout), res))
    return result, res


def trajectories(res: ReservationTable, horizon: int,
                 from_tick: int = 0) -> dict[int, list[tuple[int, int]]]:
    return {aid: [p.state_at(t) for t in range(from_tick, horizon)]
            for aid, p in res.paths.items()}


def check_valid(layout, res, sizes, speeds, horizon=None, from_tick=0):
    horizon = horizon or max(p.end_tick for p in res.paths.values()) + 2
    conflicts = validate_states(trajectories(res, horizon, from_tick), layout.obstacles,
                                sizes=sizes, ticks_per_move=speeds, start_tick=from_tick)
    assert conflicts == [], [str(c) for c in conflicts[:5]]


def check_result(layout, agents, result, res, from_tick=0):
    """Every agent planned or failed (not both), paths start where the agent stands and end
    at its goal unless detoured, and the whole table is conflict-free."""
    ids = {a.agv for a in agents}
    assert set(result.paths) | set(result.failed) == ids
    assert not set(result.paths) & set(result.failed)
    assert set(result.detours) <= set(result.paths)
    for a in agents:
        if a.agv in result.paths:
            path = result.paths[a.agv]
            assert res.paths[a.agv] is path
            assert path.start_tick == from_tick and path.states[0] == (a.start, a.start)
            if a.agv not in result.detours:
                assert path.states[-1] == (a.goal, a.goal)
    sizes = {aid: 1 for aid in res.paths} | {a.agv: a.k for a in agents}
    speeds = {aid: 1 for aid in res.paths} | {a.agv: a.ticks_per_move for a in agents}
    check_valid(layout, res, sizes, speeds, from_tick=from_tick,
                horizon=max(p.end_tick for p in res.paths.values()) + 2)


def sum_of_costs(result, tick: int = 0) -> int:
    return sum(p.end_tick - tick for p in result.paths.values())


def brute_force_soc(obstacles: np.ndarray, starts: list[int], goals: list[int]) -> int | None:
    """Optimal sum of costs of 1x1 agents by A* over joint states (positions, finished).

    Each step, every unfinished agent waits or moves to a free 4-neighbour; no two agents
    share a cell and no two swap; following is allowed. An agent on its goal may *finish*:
    from then on it stays there for good. A step costs the number of unfinished agents, so
    an agent's cost is the tick at which it reaches its goal for good.
    """
    rows, cols = obstacles.shape
    free = ~obstacles.ravel()
    n = len(starts)

    def bfs(goal: int) -> dict[int, int]:
        dist = {goal: 0}
        frontier = [goal]
        while frontier:
            nxt = []
            for v in frontier:
                for u in moves(v)[1:]:
                    if u not in dist:
                        dist[u] = dist[v] + 1
                        nxt.append(u)
            frontier = nxt
        return dist

    def moves(v: int) -> list[int]:
        r, c = divmod(v, cols)
        out = [v]
        for dr, dc in ((0, 1), (1, 0), (0, -1), (-1, 0)):
            r2, c2 = r + dr, c + dc
            if 0 <= r2 < rows and 0 <= c2 < cols and free[r2 * cols + c2]:
                out.append(r2 * cols + c2)
        return out

    dists = [bfs(g) for g in goals]
    if any(s not in d for s, d in zip(starts, dists, strict=True)):
        return None

    def h(pos, fin) -> int:
        return sum(dists[i][pos[i]] for i in range(n) if not fin[i])

    def finishes(pos, fin):
        """Every way of letting agents that stand on their goals finish."""
        can = [i for i in range(n) if not fin[i] and pos[i] == goals[i]]
        for r in range(len(can) + 1):
            for subset in itertools.combinations(can, r):
                yield tuple(f or i in subset for i, f in enumerate(fin))

    best: dict = {}
    heap = []
    for fin in finishes(tuple(starts), (False,) * n):
        key = (tuple(starts), fin)
        best[key] = 0
        heap.append((h(*key), 0, key))
    heapq.heapify(heap)
    while heap:
        _, g, (pos, fin) = heapq.heappop(heap)
        if g > best[(pos, fin)]:
            continue
        if all(fin):
            return g
        step = sum(1 for f in fin if not f)
        options = [[pos[i]] if fin[i] else moves(pos[i]) for i in range(n)]
        for new in itertools.product(*options):
            if len(set(new)) < n:
                continue
            if any(new[i] == pos[j] and new[j] == pos[i] and new[i] != pos[i]
                   for i in range(n) for j in range(i + 1, n)):
                continue
            for fin2 in finishes(new, fin):
                key = (new, fin2)
                g2 = g + step
                if g2 < best.get(key, 1 << 30):
                    best[key] = g2
                    heapq.heappush(heap, (g2 + h(new, fin2), g2, key))
    return None


POCKET = ["###.####",
          "........",
          "######SR"]


# --------------------------------------------------------------------------- basics


def test_module_examples_run():
    result = doctest.testmod(cbs_module)
    assert result.attempted > 0 and result.failed == 0


def test_is_a_planner():
    planner = CBSPlanner()
    assert isinstance(planner, Planner) and planner.name == "cbs"


def first(paths, sizes, t_end=10, cols=4):
    conflicts, count = find_conflicts(paths, sizes, cols, 0, t_end, limit=10)
    return (conflicts[0] if conflicts else None), count


def test_find_conflicts_sees_vertex_swap_footprint_and_rest():
    # Both enter node 2 at tick 1.
    c, n = first([TimedPath(0, 0, ((1, 1), (2, 2), (3, 3))),
                  TimedPath(1, 0, ((3, 3), (2, 2), (1, 1)))], [1, 1])
    assert (c.kind, c.tick, c.cell, n) == ("vertex", 1, 2, 1)
    # Swap between nodes 0 and 1.
    c, _ = first([TimedPath(0, 0, ((0, 0), (1, 1))), TimedPath(1, 0, ((1, 1), (0, 0)))], [1, 1])
    assert (c.kind, c.tick) == ("swap", 1)
    assert c.moves == (((0, 0), (1, 1)), ((1, 1), (0, 0)))
    # A 2x2 AGV at node 0 covers node 5 (both rest: a plain vertex conflict).
    c, _ = first([TimedPath(0, 0, ((0, 0),)), TimedPath(1, 0, ((5, 5),))], [2, 1])
    assert (c.kind, c.cell) == ("vertex", 5)
    # AGV 0 rests at node 1 from tick 1; AGV 1 passes it at tick 3: a target conflict.
    rest = TimedPath(0, 0, ((0, 0), (1, 1)))
    late = TimedPath(1, 0, ((4, 4), (5, 5), (5, 5), (1, 1), (2, 2)))
    c, _ = first([rest, late], [1, 1])
    assert (c.kind, c.tick, c.cell, c.i, c.j) == ("target", 3, 1, 1, 0)
    # ... which a window of two ticks does not see.
    assert first([rest, late], [1, 1], t_end=2)[0] is None
    # Following is no conflict.
    follow = [TimedPath(0, 0, ((0, 0), (1, 1))), TimedPath(1, 0, ((1, 1), (2, 2)))]
    assert first(follow, [1, 1]) == (None, 0)


# --------------------------------------------------------------------------- hand-made cases


def test_head_on_in_corridor_with_pocket_solved_whatever_the_order():
    # A 1-wide corridor with one pocket at (0, 3). Prioritized A* in the bad order (the AGV
    # going right first) fails; CBS plans both.
    layout = make_layout(POCKET)
    cols = layout.cols
    a = AgentRequest(0, 1 * cols + 0, 1 * cols + 7, priority=(0,))
    b = AgentRequest(1, 1 * cols + 6, 1 * cols + 1, priority=(1,))
    prio, _ = plan_all(layout, [a, b], AStarPlanner())
    assert prio.failed
    result, res = plan_all(layout, [a, b])
    assert result.failed == [] and set(result.paths) == {0, 1} and result.budget_hits == 0
    check_result(layout, [a, b], result, res)
    # Someone steps into the pocket.
    assert any(s[1] == 3 for p in result.paths.values() for s in p.states)
    obstacles = layout.obstacles
    assert sum_of_costs(result) == brute_force_soc(obstacles, [a.start, b.start],
                                                   [a.goal, b.goal])


def test_goal_on_the_other_agents_route_is_held_only_after_it_passed():
    # B must pass A's goal (1, 3): (0, 4) and (2, 4) are walls. A may rest there only after.
    layout = make_layout(["....#...",
                          "........",
                          "####.#SR"])
    cols = layout.cols
    a = AgentRequest(0, 1 * cols + 1, 1 * cols + 3)
    b = AgentRequest(1, 1 * cols + 0, 1 * cols + 7)
    result, res = plan_all(layout, [a, b])
    check_result(layout, [a, b], result, res)
    pa, pb = result.paths[0], result.paths[1]
    passes = [pb.start_tick + i for i, s in enumerate(pb.states) if 1 * cols + 3 in s]
    assert passes and pa.end_tick > max(passes)
    assert sum_of_costs(result) == brute_force_soc(layout.obstacles, [a.start, b.start],
                                                   [a.goal, b.goal])


def test_two_by_two_agent_passes_one_by_one_agents():
    layout = make_layout(["........",
                          "........",
                          "........",
                          "......SR"])
    cols = layout.cols
    big = AgentRequest(0, 1 * cols + 0, 1 * cols + 6, k=2)
    s1 = AgentRequest(1, 1 * cols + 7, 1 * cols + 0)
    s2 = AgentRequest(2, 2 * cols + 6, 2 * cols + 1)
    agents = [big, s1, s2]
    result, res = plan_all(layout, agents)
    assert result.failed == [] and result.budget_hits == 0
    check_result(layout, agents, result, res)
    # Plain CBS (no window) too.
    result2, res2 = plan_all(layout, agents, CBSPlanner(horizon=1000))
    assert result2.failed == [] and result2.budget_hits == 0
    check_result(layout, agents, result2, res2)


def test_slow_agent_and_fast_agent_head_on():
    layout = make_layout(POCKET)
    cols = layout.cols
    slow = AgentRequest(0, 1 * cols + 0, 1 * cols + 7, ticks_per_move=2, priority=(0,))
    fast = AgentRequest(1, 1 * cols + 6, 1 * cols + 1, priority=(1,))
    result, res = plan_all(layout, [slow, fast])
    assert result.failed == [] and set(result.paths) == {0, 1}
    check_result(layout, [slow, fast], result, res)
    assert result.paths[0].end_tick >= 7 * 2


def test_fixed_agvs_are_obstacles_and_a_held_goal_means_a_detour():
    layout = make_layout(["........",
                          "........",
                          "......SR"])
    cols = layout.cols
    # AGV 9 is not planned: it crosses row 1 then rests for good on agent 0's goal.
    crossing = TimedPath(9, 0, tuple((1 * cols + c, 1 * cols + c) for c in range(7, 2, -1)))
    agents = [AgentRequest(0, 0, 1 * cols + 3), AgentRequest(1, 1 * cols + 0, 1 * cols + 7)]
    result, res = plan_all(layout, agents, fixed=((crossing, 1),))
    assert result.detours == [0] and result.failed == []
    assert result.paths[0].goal != 1 * cols + 3
    assert res.paths[9] is crossing
    check_result(layout, agents, result, res)


def test_same_goal_twice_detours_the_lower_priority_agent():
    layout = make_layout(["......",
                          "......",
                          "....SR"])
    agents = [AgentRequest(0, 0, 8, priority=(1,)), AgentRequest(1, 5, 8, priority=(0,))]
    result, res = plan_all(layout, agents)
    assert result.detours == [0] and result.paths[1].goal == 8
    check_result(layout, agents, result, res)


def test_unreachable_goal_fails_and_keeps_old_path():
    layout = make_layout(["..#..", "..#SR"])
    agents = [AgentRequest(0, 0, 4), AgentRequest(1, 1, 5)]
    result, res = plan_all(layout, agents)
    assert result.failed == [0] and set(result.paths) == {1}
    assert res.paths[0].states == ((0, 0),)
    check_result(layout, agents, result, res)


def test_small_window_still_commits_conflict_free_paths():
    # With a window of one tick the late conflicts are repaired after the search.
    layout = make_layout(POCKET)
    cols = layout.cols
    a = AgentRequest(0, 1 * cols + 0, 1 * cols + 7)
    b = AgentRequest(1, 1 * cols + 6, 1 * cols + 1)
    for horizon in (0, 1, 2, 4):
        result, res = plan_all(layout, [a, b], CBSPlanner(horizon=horizon))
        check_result(layout, [a, b], result, res)


def test_same_request_same_plan():
    layout = make_layout(["........",
                          "........",
                          "........",
                          "......SR"])
    cols = layout.cols
    agents = [AgentRequest(i, s, g) for i, (s, g) in enumerate(
        [(0, 2 * cols + 7), (2 * cols + 7, 0), (7, 2 * cols), (2 * cols, 7)])]
    first, _ = plan_all(layout, agents)
    second, _ = plan_all(layout, agents)
    assert first.paths == second.paths and first.expansions == second.expansions


# --------------------------------------------------------------------------- budgets


def test_node_budget_falls_back_to_prioritized_planning():
    layout = make_layout(POCKET)
    cols = layout.cols
    a = AgentRequest(0, 1 * cols + 0, 1 * cols + 7, priority=(1,))
    b = AgentRequest(1, 1 * cols + 6, 0 * cols + 3, priority=(0,))
    result, res = plan_all(layout, [a, b], CBSPlanner(max_nodes=1))
    assert result.budget_hits > 0
    assert set(result.paths) == {0, 1}  # the good order: prioritized planning succeeds
    check_result(layout, [a, b], result, res)
    # In the bad order the fallback fails one agent, which keeps its old path: still valid.
    a2 = AgentRequest(0, a.start, 1 * cols + 6, priority=(0,))
    b2 = AgentRequest(1, b.start, 1 * cols + 1, priority=(1,))
    result2, res2 = plan_all(layout, [a2, b2], CBSPlanner(max_nodes=1))
    assert result2.budget_hits > 0 and result2.failed
    check_result(layout, [a2, b2], result2, res2)


def test_past_deadline_keeps_every_old_path():
    layout = make_layout(POCKET)
    cols = layout.cols
    agents = [AgentRequest(0, 1 * cols + 0, 1 * cols + 7), AgentRequest(1, 1 * cols + 6, 3)]
    res = ReservationTable(cols)
    for a in agents:
        res.commit(TimedPath(a.agv, 0, ((a.start, a.start),)), a.k)
    request = PlanRequest(0, agents, GraphSet(layout), res, deadline=time.monotonic() - 1)
    result = CBSPlanner().plan(request)
    assert result.budget_hits == 1 and sorted(result.failed) == [0, 1] and not result.paths
    assert {aid: p.states for aid, p in res.paths.items()} == {
        0: ((1 * cols, 1 * cols),), 1: ((1 * cols + 6, 1 * cols + 6),)}


# --------------------------------------------------------------------------- properties


@st.composite
def instances(draw, max_agents: int = 4, big_and_slow: bool = True):
    rows = draw(st.integers(4, 7))
    cols = draw(st.integers(4, 7))
    density = draw(st.sampled_from([0.1, 0.15, 0.2]))
    seed = draw(st.integers(0, 2**16))
    rng = np.random.default_rng(seed)
    obstacles = rng.random((rows, cols)) < density
    obstacles[rows - 1, cols - 2:] = False
    grid = [["#" if obstacles[r, c] else "." for c in range(cols)] for r in range(rows)]
    grid[rows - 1][cols - 1] = "R"
    grid[rows - 1][cols - 2] = "S"
    layout = make_layout(["".join(r) for r in grid])
    free = [r * cols + c for r in range(rows) for c in range(cols) if not obstacles[r, c]]
    n = draw(st.integers(2, min(max_agents, len(free) // 2)))
    starts, goals = rng.permutation(free)[:n], rng.permutation(free)[:n]
    graph2 = GraphSet(layout).get(2, False)
    agents: list[AgentRequest] = []
    taken: set[int] = set()
    for i in range(n):
        k = 1
        if big_and_slow and i == 0 and draw(st.booleans()) and graph2.expandable(
                int(starts[0])) and graph2.expandable(int(goals[0])):
            k = 2
        fp = {int(starts[i]) + dr * cols + dc for dr in range(k) for dc in range(k)}
        if fp & taken or int(starts[i]) == int(goals[i]):
            continue
        taken |= fp
        m = draw(st.sampled_from([1, 1, 2])) if big_and_slow else 1
        agents.append(AgentRequest(i, int(starts[i]), int(goals[i]), k=k, ticks_per_move=m,
                                   priority=(int(rng.integers(3)),)))
    assume(agents)
    return layout, agents


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(), st.sampled_from([1, 4, 20, 1000]))
def test_cbs_plans_are_valid(instance, horizon):
    layout, agents = instance
    result, res = plan_all(layout, agents, CBSPlanner(horizon=horizon, time_budget_s=0.2))
    check_result(layout, agents, result, res)
    graphs = GraphSet(layout)
    for aid, path in result.paths.items():
        agent = next(a for a in agents if a.agv == aid)
        if aid not in result.detours:
            d = graphs.get(agent.k, False).distance(divmod(agent.start, layout.cols),
                                                    divmod(agent.goal, layout.cols))
            assert path.end_tick >= d * agent.ticks_per_move


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(), st.integers(1, 12), st.data())
def test_replanning_some_agents_mid_course_keeps_plans_valid(instance, t, data):
    """Replan a subset at tick t (the others are fixed) from wherever their paths put them."""
    layout, agents = instance
    _, res = plan_all(layout, agents, CBSPlanner(time_budget_s=0.2))
    again = []
    for a in agents:
        s = res.paths[a.agv].state_at(t)
        if s[0] == s[1] and data.draw(st.booleans()):
            again.append(AgentRequest(a.agv, s[0], a.start, k=a.k,
                                      ticks_per_move=a.ticks_per_move))
    if again:
        result = CBSPlanner(horizon=5, time_budget_s=0.2).plan(
            PlanRequest(t, again, GraphSet(layout), res))
        assert set(result.paths) | set(result.failed) == {a.agv for a in again}
    check_valid(layout, res, {a.agv: a.k for a in agents},
                {a.agv: a.ticks_per_move for a in agents},
                horizon=max(p.end_tick for p in res.paths.values()) + 2 + t, from_tick=t)


def tiny_instance(rows: int, cols: int, walls: list[int], starts: list[int],
                  goals: list[int]):
    grid = [["#" if r * cols + c in walls else "." for c in range(cols)] for r in range(rows)]
    free = [c for c in range(rows * cols) if c not in walls]
    # The station and shelf go on free cells: unloaded AGVs drive over them.
    grid[free[-1] // cols][free[-1] % cols] = "R"
    grid[free[-2] // cols][free[-2] % cols] = "S"
    layout = make_layout(["".join(r) for r in grid])
    agents = [AgentRequest(i, s, g) for i, (s, g) in enumerate(zip(starts, goals, strict=True))]
    return layout, agents


@st.composite
def tiny_instances(draw):
    rows = draw(st.integers(3, 4))
    cols = draw(st.integers(3, 4))
    cells = rows * cols
    walls = draw(st.lists(st.integers(0, cells - 1), max_size=2, unique=True))
    free = [c for c in range(cells) if c not in walls]
    n = draw(st.sampled_from([2, 3, 3]))
    starts = draw(st.permutations(free))[:n]
    goals = draw(st.permutations(free))[:n]
    assume(all(s != g for s, g in zip(starts, goals, strict=True)))
    return tiny_instance(rows, cols, walls, starts, goals)


# CBS is exponential on instances where agents must swap their order in a corridor (it
# branches on one conflict at a time); a node budget keeps such cases short, and the tests
# below check that a budget hit is reported, never passed off as an optimal plan.
TINY_BUDGET = {"horizon": 1000, "max_nodes": 3000, "time_budget_s": 60.0}


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(tiny_instances())
def test_unwindowed_cbs_is_optimal_on_tiny_instances(instance):
    layout, agents = instance
    optimum = brute_force_soc(layout.obstacles, [a.start for a in agents],
                              [a.goal for a in agents])
    assume(optimum is not None)
    result, res = plan_all(layout, agents, CBSPlanner(**TINY_BUDGET))
    check_result(layout, agents, result, res)
    if result.budget_hits == 0:
        # Solved by CBS proper: every agent reaches its goal at the optimal sum of costs.
        assert result.failed == [] and result.detours == []
        assert sum_of_costs(result) == optimum
    else:
        assert result.budget_hits == 1  # one CBS call, one counted fallback


@pytest.mark.slow  # CBS and a brute force on many instances: make test-all
def test_cbs_proves_the_optimum_on_nearly_all_tiny_instances():
    """On 150 seeded random tiny instances, CBS within its budget finds the brute-force
    optimum on at least 97% (the rest are corridor-swap cases, reported as budget hits)."""
    rng = np.random.default_rng(2026)
    solved = optimal = 0
    while solved < 150:
        rows, cols = int(rng.integers(3, 5)), int(rng.integers(3, 5))
        walls = [int(c) for c in rng.choice(rows * cols, int(rng.integers(0, 3)), replace=False)]
        free = [c for c in range(rows * cols) if c not in walls]
        n = int(rng.choice([2, 3, 3]))
        starts = [int(c) for c in rng.permutation(free)[:n]]
        goals = [int(c) for c in rng.permutation(free)[:n]]
        if any(s == g for s, g in zip(starts, goals, strict=True)):
            continue
        optimum = brute_force_soc(np.isin(np.arange(rows * cols), walls).reshape(rows, cols),
                                  starts, goals)
        if optimum is None:
            continue
        layout, agents = tiny_instance(rows, cols, walls, starts, goals)
        result, res = plan_all(layout, agents, CBSPlanner(**TINY_BUDGET))
        check_result(layout, agents, result, res)
        solved += 1
        if result.budget_hits == 0 and not result.failed and sum_of_costs(result) == optimum:
            optimal += 1
    assert optimal >= 0.97 * solved, f"{optimal}/{solved}"
