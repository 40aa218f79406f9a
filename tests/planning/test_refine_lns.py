"""The LNS refiner's compiled search (:mod:`warerover_phys.planning.refine.kernels`): the same
costs as the Python reference searches, valid plans, determinism with a seed."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys.planning.graph import UNREACHABLE
from warerover_phys.planning.oneshot.core import grid_graph, solve
from warerover_phys.planning.refine import kernels as refine_nb
from warerover_phys.planning.refine.lns import _astar, _Plan, _sipp, _trim, refine
from warerover_phys.problems.movingai import read_map, read_scen
from warerover_phys.validate import validate_states

pytestmark = pytest.mark.skipif(not refine_nb.AVAILABLE, reason="numba missing")

DATA = Path(__file__).resolve().parents[1] / "data"
MAP = DATA / "warehouse-10-20-10-2-1.map"
SCEN = DATA / "warehouse-10-20-10-2-1-random-1.scen"


def valid(obstacles, paths) -> bool:
    horizon = max(len(p) for p in paths)
    traj = {i: [(v, v) for v in p] + [(p[-1], p[-1])] * (horizon - len(p))
            for i, p in enumerate(paths)}
    return validate_states(traj, obstacles) == []


@st.composite
def floors(draw):
    """Small random floors (some obstacles) with 2-10 agents and a seed."""
    rows, cols = draw(st.integers(3, 7)), draw(st.integers(3, 7))
    rng = np.random.default_rng(draw(st.integers(0, 10**6)))
    obstacles = rng.random((rows, cols)) < draw(st.sampled_from([0.0, 0.1, 0.2]))
    free = [(r, c) for r in range(rows) for c in range(cols) if not obstacles[r, c]]
    if len(free) < 3:
        obstacles[:] = False
        free = [(r, c) for r in range(rows) for c in range(cols)]
    n = draw(st.integers(2, min(10, len(free) - 1)))
    starts = [free[i] for i in rng.permutation(len(free))[:n]]
    goals = [free[i] for i in rng.permutation(len(free))[:n]]
    graph = grid_graph(obstacles)
    if any(graph.distance(s, g) >= UNREACHABLE for s, g in zip(starts, goals, strict=True)):
        goals = starts[:]
    return obstacles, starts, goals, draw(st.integers(0, 100))


def first_plan(obstacles, starts, goals, seed):
    # a limit no loaded machine reaches (LaCAM returns at its first solution): with 1 s,
    # 60 agents found no plan at load ~20 on 2 cores and the test broke on the None
    first = solve(obstacles, starts, goals, planner="lacam", time_limit_s=60, seed=seed)
    if not first.success:
        return None
    graph = grid_graph(obstacles)
    cols = graph.cols
    nodes = [[r * cols + c for r, c in p] for p in first.paths]
    goal_nodes = [graph.node(g) for g in goals]
    return graph, [_trim(p, g) for p, g in zip(nodes, goal_nodes, strict=True)], goal_nodes


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(floors(), st.integers(0, 30))
def test_compiled_search_finds_the_reference_cost_and_avoids_everybody(instance, slack):
    """Re-planning one agent against the others' paths: the compiled search, the plain
    space-time A* and SIPP find the same cost (or all none) under any bound ``ub``, and
    the compiled path is a path of the graph that avoids every other path."""
    obstacles, starts, goals, seed = instance
    got = first_plan(obstacles, starts, goals, seed)
    if got is None:
        return
    graph, trimmed, goal_nodes = got
    a = seed % len(starts)
    plan = _Plan(graph.num_nodes, trimmed)
    dense = refine_nb.DensePlan(graph.num_nodes, trimmed)
    plan.remove(a)
    dense.remove(a)
    table = graph.dist_to(goals[a])
    dist = table.tolist()
    start = trimmed[a][0]
    ub = dist[start] + slack % 12 if slack < 24 else 10**6
    far = time.monotonic() + 30
    ref = _astar(graph.neighbors, plan, start, goal_nodes[a], dist, ub, far, 10**6)
    ivs = _sipp(graph.neighbors, plan, start, goal_nodes[a], dist, ub, far, 10**6)
    ptr, idx = refine_nb.csr(graph.neighbors)
    work = [0]
    got_path = dense.search(ptr, idx, start, goal_nodes[a], table, ub, 10**6, work)
    assert (ref is None) == (got_path is None) == (ivs is None)
    if got_path is None:
        return
    assert len(got_path) == len(ref) == len(ivs) <= ub + 1
    assert got_path[0] == start and got_path[-1] == goal_nodes[a]
    assert all(u == v or u in graph.neighbors[v] for v, u in zip(got_path, got_path[1:],
                                                                strict=False))
    assert work[0] >= 1 or len(got_path) == 1
    others = [p for i, p in enumerate(trimmed) if i != a]
    assert valid(obstacles, others + [got_path])


def test_dense_plan_add_and_remove_restore_the_table():
    """Taking a path out and putting it back leaves the occupancy as it was; a long path
    grows the horizon and keeps what was there."""
    paths = [[0, 1, 2], [5, 4, 3, 3, 6]]
    plan = refine_nb.DensePlan(9, paths)
    occ, parked = plan.occ.copy(), plan.parked.copy()
    assert plan.who(1, 4) == 1 and plan.who(2, 2) == 0 and plan.who(9, 0) is None
    assert plan.ticks_at(3).tolist() == [2, 3] and int(plan.parked[6]) == 4
    plan.add(1, plan.remove(1))
    assert (plan.occ == occ).all() and (plan.parked == parked).all()
    plan.remove(0)
    plan.add(0, [0] * 40 + [1])
    assert plan.horizon >= 57 and plan.who(1, 4) == 1 and plan.who(40, 1) == 0
    assert plan.ticks_at(2).tolist() == []


def warehouse_plan(n):
    grid = read_map(MAP)
    agents = read_scen(SCEN, n, grid)
    starts = [a.start for a in agents]
    goals = [a.goal for a in agents]
    return grid.obstacles, starts, goals


@pytest.mark.parametrize("search", ["nb", "sipp"])
def test_refinement_keeps_the_plan_valid_and_is_deterministic(search):
    """60 agents on the warehouse map: 40 neighbourhoods with either search lower the sum of
    costs, the plan passes the validator, and the same seed gives the same plan."""
    obstacles, starts, goals = warehouse_plan(60)
    graph, trimmed, goal_nodes = first_plan(obstacles, starts, goals, 0)
    dists = [graph.dist_to(g) for g in goals]
    runs = []
    for _ in range(2):
        res = refine(graph.neighbors, trimmed, goal_nodes, dists, time.monotonic() + 60,
                     np.random.default_rng(3), max_iterations=40, search=search)
        runs.append(res)
    a, b = runs
    assert a.paths == b.paths
    assert [c for _, c in a.history] == [c for _, c in b.history]
    first = sum(len(p) - 1 for p in trimmed)
    assert a.sum_of_costs < first and a.stats["iterations"] == 40
    assert a.sum_of_costs == sum(len(p) - 1 for p in a.paths)
    assert valid(obstacles, a.paths)
    for p, s, g in zip(a.paths, trimmed, goal_nodes, strict=True):
        assert p[0] == s[0] and p[-1] == g
    with pytest.raises(ValueError, match="search"):
        refine(graph.neighbors, trimmed, goal_nodes, dists, time.monotonic() + 1,
               np.random.default_rng(3), max_iterations=1, search="dfs")
