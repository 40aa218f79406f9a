"""Prioritized space-time A* and the independent validator."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys.config import LayoutSpec
from warerover_phys.layout import build_layout
from warerover_phys.planning import (
    AgentRequest,
    AStarPlanner,
    GraphSet,
    PlanRequest,
    ReservationTable,
    TimedPath,
)
from warerover_phys.planning.graph import UNREACHABLE
from warerover_phys.validate import validate_states


def make_layout(rows: list[str]):
    # A layout needs a station and a shelf; tests put them where they do not matter.
    return build_layout(LayoutSpec(grid=rows))


def plan_all(layout, agents: list[AgentRequest], tick: int = 0):
    """Commit a resting path for every agent, then plan them all; return (result, table)."""
    res = ReservationTable(layout.cols)
    for a in agents:
        res.commit(TimedPath(a.agv, tick, ((a.start, a.start),)), a.k)
    result = AStarPlanner().plan(PlanRequest(tick, agents, GraphSet(layout), res))
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


# ------------------------------------------------------------------------------- validator


def test_validator_finds_vertex_swap_obstacle_and_jump():
    obstacles = np.zeros((3, 4), dtype=bool)
    obstacles[2, 3] = True
    cols = 4
    # AGV 0 moves 0 -> 1, AGV 1 moves 1 -> 0 in the same tick: a swap.
    swap = validate_states({0: [(0, 0), (1, 1)], 1: [(1, 1), (0, 0)]}, obstacles)
    assert [c.kind for c in swap] == ["swap"]
    # Both move into cell 2: a vertex conflict.
    vertex = validate_states({0: [(1, 1), (2, 2)], 1: [(3, 3), (2, 2)]}, obstacles)
    assert [c.kind for c in vertex] == ["vertex"]
    # Onto the obstacle at (2, 3) = node 11, and a jump of two cells.
    assert validate_states({0: [(7, 7), (11, 11)]}, obstacles)[0].kind == "obstacle"
    assert validate_states({0: [(0, 0), (2, 2)]}, obstacles)[0].kind == "move"
    # A 2x2 AGV at node 0 covers node 5 (1, 1): a 1x1 AGV there is a footprint conflict.
    fp = validate_states({0: [(0, 0)], 1: [(5, 5)]}, obstacles, sizes={0: 2})
    assert fp and fp[0].kind == "vertex"
    # A slow AGV (2 ticks per move) must spend exactly one tick in transit.
    assert validate_states({0: [(0, 0), (0, 1), (1, 1)]}, obstacles,
                           ticks_per_move={0: 2}) == []
    assert validate_states({0: [(0, 0), (1, 1)]}, obstacles, ticks_per_move={0: 2})
    # Following (moving into a cell another AGV leaves in the same tick) is allowed.
    assert validate_states({0: [(0, 0), (1, 1)], 1: [(1, 1), (2, 2)]}, obstacles) == []
    assert cols == obstacles.shape[1]


# ------------------------------------------------------------------------------- A*


def test_single_agent_finds_shortest_path():
    layout = make_layout(["........",
                          ".####...",
                          "......SR"])
    start, goal = 0, 2 * 8 + 0
    result, res = plan_all(layout, [AgentRequest(0, start, goal)])
    path = result.paths[0]
    assert path.states[-1] == (goal, goal)
    assert len(path.states) - 1 == 2  # straight down two cells
    check_valid(layout, res, {0: 1}, {0: 1})


def test_priority_order_decides_who_plans_first():
    # A 1-wide corridor with a side pocket at (0, 3). B (planned first) steps into the pocket;
    # A then passes it. In the other order A's route is blocked by B standing still: a
    # prioritized planner is not complete, and must say so rather than return a bad plan.
    layout = make_layout(["###.####",
                          "........",
                          "######SR"])
    cols = layout.cols
    a = AgentRequest(0, 1 * cols + 0, 1 * cols + 7, priority=(1,))
    b = AgentRequest(1, 1 * cols + 6, 0 * cols + 3, priority=(0,))
    result, res = plan_all(layout, [a, b])
    assert set(result.paths) == {0, 1}
    check_valid(layout, res, {0: 1, 1: 1}, {0: 1, 1: 1})
    a_first = AgentRequest(0, a.start, a.goal, priority=(0,))
    b_second = AgentRequest(1, b.start, b.goal, priority=(1,))
    result2, res2 = plan_all(layout, [a_first, b_second])
    assert 0 in result2.failed
    check_valid(layout, res2, {0: 1, 1: 1}, {0: 1, 1: 1})


def test_slow_agent_spends_ticks_per_move():
    layout = make_layout(["......", "....SR"])
    agent = AgentRequest(0, 0, 5, ticks_per_move=3)
    result, res = plan_all(layout, [agent])
    assert len(result.paths[0].states) - 1 == 5 * 3
    check_valid(layout, res, {0: 1}, {0: 3})


def test_two_by_two_agent_respects_footprint():
    layout = make_layout(["......",
                          "......",
                          "..#...",
                          "......",
                          "....SR"])
    big = AgentRequest(0, 0, 3 * 6 + 4 - 6, k=2)  # (2, 4) anchor -> covers rows 2-3, cols 4-5
    small = AgentRequest(1, 4 * 6 + 0, 0)
    result, res = plan_all(layout, [big, small])
    assert set(result.paths) == {0, 1}
    check_valid(layout, res, {0: 2, 1: 1}, {0: 1, 1: 1})


def test_loaded_agent_never_drives_under_other_shelves():
    layout = make_layout(["R......",
                          ".SSSSS.",
                          "......."])
    graphs = GraphSet(layout)
    loaded = graphs.get(1, True)
    cols = layout.cols
    # From the shelf at (1, 3) to the station (0, 0): out of the sink and around, never
    # through (1, 1) .. (1, 5).
    start, goal = 1 * cols + 3, 0
    res = ReservationTable(cols)
    res.commit(TimedPath(0, 0, ((start, start),)), 1)
    result = AStarPlanner().plan(PlanRequest(0, [AgentRequest(0, start, goal, loaded=True)],
                                             graphs, res))
    cells = {s[1] for s in result.paths[0].states[1:]}
    assert not cells & {1 * cols + c for c in range(1, 6)}
    assert loaded.distance((1, 3), (0, 0)) == 4
    # Unloaded, it may drive under: straight up and left.
    assert graphs.get(1, False).distance((1, 3), (0, 0)) == 4
    assert graphs.get(1, True).distance((2, 1), (1, 1)) == 1  # into a sink as a goal
    assert graphs.get(1, True).distance((1, 1), (1, 3)) == 4  # not through the shelves


def test_unreachable_goal_fails_and_keeps_old_path():
    layout = make_layout(["..#..", "..#SR"])
    result, res = plan_all(layout, [AgentRequest(0, 0, 4)])
    assert result.failed == [0] and not result.paths
    assert res.paths[0].states == ((0, 0),)
    assert GraphSet(layout).get(1, False).distance((0, 0), (0, 4)) == UNREACHABLE


# ------------------------------------------------------------------------------- properties


@st.composite
def instances(draw):
    rows = draw(st.integers(4, 8))
    cols = draw(st.integers(4, 9))
    density = draw(st.sampled_from([0.0, 0.1, 0.2]))
    seed = draw(st.integers(0, 2**16))
    rng = np.random.default_rng(seed)
    obstacles = rng.random((rows, cols)) < density
    grid = [["#" if obstacles[r, c] else "." for c in range(cols)] for r in range(rows)]
    grid[rows - 1][cols - 1] = "R"
    grid[rows - 1][cols - 2] = "S"
    layout = make_layout(["".join(r) for r in grid])
    free = [r * cols + c for r in range(rows) for c in range(cols) if not obstacles[r, c]]
    n = draw(st.integers(1, min(6, len(free) // 2)))
    picks = rng.permutation(free)
    starts, goals = picks[:n], rng.permutation(free)[:n]
    big = draw(st.booleans())
    agents = []
    taken: set[int] = set()
    graph2 = GraphSet(layout).get(2, False)
    for i in range(n):
        k = 1
        if big and i == 0 and graph2.expandable(int(starts[0])) and graph2.expandable(
                int(goals[0])):
            k = 2
        fp = {int(starts[i]) + dr * cols + dc for dr in range(k) for dc in range(k)}
        if fp & taken:
            continue
        taken |= fp
        agents.append(AgentRequest(i, int(starts[i]), int(goals[i]), k=k,
                                   ticks_per_move=draw(st.sampled_from([1, 1, 2]))))
    return layout, agents


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances())
def test_prioritized_astar_plans_are_valid(instance):
    layout, agents = instance
    result, res = plan_all(layout, agents)
    sizes = {a.agv: a.k for a in agents}
    speeds = {a.agv: a.ticks_per_move for a in agents}
    check_valid(layout, res, sizes, speeds)
    graph = GraphSet(layout)
    for aid, path in result.paths.items():
        agent = next(a for a in agents if a.agv == aid)
        assert path.states[0] == (agent.start, agent.start)
        if aid in result.detours:  # its goal was held by an agent standing there for good
            assert path.states[-1][1] != agent.goal
            continue
        assert path.states[-1] == (agent.goal, agent.goal)
        # Never shorter than the static shortest path.
        d = graph.get(agent.k, False).distance(divmod(agent.start, layout.cols),
                                               divmod(agent.goal, layout.cols))
        assert len(path.states) - 1 >= d * agent.ticks_per_move


@settings(max_examples=40, deadline=None)
@given(instances(), st.integers(1, 20))
def test_replanning_mid_course_keeps_plans_valid(instance, t):
    """Replan every agent again at tick t from wherever its path puts it."""
    layout, agents = instance
    result, res = plan_all(layout, agents)
    again = []
    for a in agents:
        s = res.paths[a.agv].state_at(t)
        if s[0] == s[1]:
            again.append(AgentRequest(a.agv, s[0], a.start, k=a.k,
                                      ticks_per_move=a.ticks_per_move))
    AStarPlanner().plan(PlanRequest(t, again, GraphSet(layout), res))
    # Paths committed at tick t say nothing of earlier ticks: check from t on.
    check_valid(layout, res, {a.agv: a.k for a in agents},
                {a.agv: a.ticks_per_move for a in agents},
                horizon=max(p.end_tick for p in res.paths.values()) + 2 + t, from_tick=t)


@pytest.mark.parametrize("k", [1, 2])
def test_distance_tables_match_bfs(k):
    layout = make_layout(["........",
                          ".##..#..",
                          "........",
                          "...#....",
                          "......SR"])
    graph = GraphSet(layout).get(k, False)
    goal = (2, 0)
    assert graph.valid[goal]
    table = graph.dist_to(goal)
    # Plain BFS over valid anchors.
    from collections import deque
    dist = {goal: 0}
    queue = deque([goal])
    while queue:
        r, c = queue.popleft()
        for dr, dc in ((0, 1), (1, 0), (0, -1), (-1, 0)):
            n = (r + dr, c + dc)
            if 0 <= n[0] < layout.rows and 0 <= n[1] < layout.cols and graph.valid[n] \
                    and n not in dist:
                dist[n] = dist[(r, c)] + 1
                queue.append(n)
    for r in range(layout.rows):
        for c in range(layout.cols):
            expected = dist.get((r, c), UNREACHABLE)
            assert table[r * layout.cols + c] == expected, (r, c)


@st.composite
def random_walks(draw):
    rows, cols = draw(st.integers(2, 5)), draw(st.integers(2, 5))
    n = draw(st.integers(1, 4))
    steps = draw(st.integers(1, 6))
    walks = {}
    for agv in range(n):
        r, c = draw(st.integers(0, rows - 1)), draw(st.integers(0, cols - 1))
        states = [(r * cols + c, r * cols + c)]
        for _ in range(steps):
            dr, dc = draw(st.sampled_from([(0, 0), (0, 1), (1, 0), (0, -1), (-1, 0)]))
            r2, c2 = min(max(r + dr, 0), rows - 1), min(max(c + dc, 0), cols - 1)
            r, c = r2, c2
            states.append((r * cols + c, r * cols + c))
        walks[agv] = states
    return np.zeros((rows, cols), dtype=bool), walks


# 200 examples: tiny plans against brute force, cheap
@settings(max_examples=200, deadline=None)
@given(random_walks())
def test_validator_agrees_with_brute_force(case):
    """1x1 random walks: the validator reports a vertex or swap conflict iff a direct
    comparison of every pair of agents at every tick finds one."""
    obstacles, walks = case
    ids = sorted(walks)
    horizon = max(len(w) for w in walks.values())

    def at(a, t):
        return walks[a][min(t, len(walks[a]) - 1)][1]

    expected = set()
    for t in range(horizon):
        for i, a in enumerate(ids):
            for b in ids[i + 1:]:
                if at(a, t) == at(b, t):
                    expected.add(("vertex", t))
                elif t and at(a, t) == at(b, t - 1) and at(b, t) == at(a, t - 1):
                    expected.add(("swap", t))
    found = {(c.kind, c.tick) for c in validate_states(walks, obstacles, max_conflicts=10**6)}
    assert found == expected
