"""Footprint-aware PIBT and LaCAM: 1x1 and 2x2 agents, fast and slow, on random small maps.

Every plan is checked by the independent validator; LaCAM's answers are checked against a
brute-force search over joint poses on tiny instances.
"""

from __future__ import annotations

import itertools
import time
from collections import deque

import numpy as np
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from warerover_phys.config import LayoutSpec
from warerover_phys.layout import build_layout
from warerover_phys.planning.base import footprint_nodes
from warerover_phys.planning.graph import UNREACHABLE, GraphSet
from warerover_phys.planning.lacam.footprint import footprint_lacam, update_footprint_priorities
from warerover_phys.planning.pibt.footprint import (
    Mover,
    footprint_step,
    pose_cells,
    pose_states,
    successor,
)
from warerover_phys.validate import validate_states

# --------------------------------------------------------------------------- instances


def make_instance(rows: int, cols: int, density: float, specs: list[tuple[int, int]],
                  seed: int):
    """A random map (the station and shelf of every layout sit in the bottom-right corner;
    unloaded agents drive over them) and agents of the given (k, m) with distinct start
    footprints and distinct goal footprints. Agents that find no room are left out."""
    rng = np.random.default_rng(seed)
    obstacles = rng.random((rows, cols)) < density
    obstacles[rows - 1, cols - 2:] = False
    grid = [["#" if obstacles[r, c] else "." for c in range(cols)] for r in range(rows)]
    grid[rows - 1][cols - 1] = "R"
    grid[rows - 1][cols - 2] = "S"
    layout = build_layout(LayoutSpec(grid=["".join(r) for r in grid]))
    graphs = GraphSet(layout)
    movers, starts = [], []
    taken: set[int] = set()
    goal_taken: set[int] = set()
    for k, m in specs:
        graph = graphs.get(k, False)
        valid = [v for v in range(rows * cols) if graph.expandable(v)]
        for s, g in zip(rng.permutation(valid)[:8].tolist(), rng.permutation(valid)[:8].tolist(),
                        strict=False):
            fs, fg = set(footprint_nodes(s, k, cols)), set(footprint_nodes(g, k, cols))
            dist = graph.dist_to(divmod(g, cols))
            if fs & taken or fg & goal_taken or dist[s] >= UNREACHABLE:
                continue
            taken |= fs
            goal_taken |= fg
            movers.append(Mover(k, m, graph.neighbors, dist, g))
            starts.append((s, s, 0))
            break
    return layout, movers, starts


@st.composite
def instances(draw, max_side: int = 7, max_agents: int = 5):
    rows, cols = draw(st.integers(3, max_side)), draw(st.integers(3, max_side))
    density = draw(st.sampled_from([0.0, 0.1, 0.2]))
    n = draw(st.integers(1, max_agents))
    specs = [(draw(st.sampled_from([1, 1, 2])), draw(st.sampled_from([1, 1, 2, 3])))
             for _ in range(n)]
    layout, movers, starts = make_instance(rows, cols, density, specs,
                                           draw(st.integers(0, 2**16)))
    assume(movers)
    return layout, movers, starts


def check(layout, movers, configs):
    """Validate per-tick states of a configuration sequence; return them."""
    traj = {i: list(pose_states([c[i] for c in configs])) for i in range(len(movers))}
    conflicts = validate_states(traj, layout.obstacles,
                                sizes={i: mv.k for i, mv in enumerate(movers)},
                                ticks_per_move={i: mv.m for i, mv in enumerate(movers)})
    assert conflicts == [], [str(c) for c in conflicts[:5]]
    return traj


def brute_force_solvable(movers, starts, cols, cap: int = 40_000) -> bool | None:
    """Breadth-first search over joint poses: every agent at rest waits or starts a move to
    a neighbouring anchor, agents in a move go on; no shared cell, no swap. None if the
    search grows past ``cap`` configurations."""
    goal = tuple((mv.goal, mv.goal, 0) for mv in movers)
    start = tuple(starts)
    seen = {start}
    queue = deque([start])
    while queue:
        config = queue.popleft()
        if config == goal:
            return True
        options = []
        for mv, p in zip(movers, config, strict=True):
            targets = [p[1]] if p[2] else [v for v in (*mv.neighbors[p[1]], p[1])
                                           if mv.dist[v] < UNREACHABLE]
            options.append([successor(p, v, mv.m) for v in targets])
        before = [set(pose_cells(p, mv.k, cols)) for mv, p in zip(movers, config, strict=True)]
        for nxt in itertools.product(*options):
            after = [set(pose_cells(p, mv.k, cols)) for mv, p in zip(movers, nxt, strict=True)]
            if any(after[i] & after[j] or (after[i] & before[j] and after[j] & before[i])
                   for i, j in itertools.combinations(range(len(nxt)), 2)):
                continue
            if nxt not in seen:
                seen.add(nxt)
                queue.append(nxt)
        if len(seen) > cap:
            return None
    return False


# --------------------------------------------------------------------------- PIBT step


def test_slow_agent_commits_to_its_move_and_covers_both_footprints():
    layout, movers, starts = make_instance(3, 6, 0.0, [], 0)
    graph = GraphSet(layout).get(2, False)
    mover = Mover(2, 3, graph.neighbors, graph.dist_to((0, 4)), 4)
    configs = [((0, 0, 0),)]
    for _ in range(12):
        configs.append(tuple(footprint_step([mover], configs[-1], [1.0],
                                            np.zeros(18), layout.cols)))
    assert configs[1] == ((0, 1, 2),) and configs[2] == ((0, 1, 1),) and configs[3] == (
        (1, 1, 0),)
    assert configs[-1] == ((4, 4, 0),)
    assert set(pose_cells(configs[1][0], 2, 6)) == {0, 1, 2, 6, 7, 8}
    check(layout, [mover], configs)


def test_pushes_every_agent_under_the_wanted_footprint():
    """A 2x2 agent heading right pushes both 1x1 agents in front of it out of the way."""
    layout, _, _ = make_instance(3, 5, 0.0, [], 0)
    graphs = GraphSet(layout)
    big, small = graphs.get(2, False), graphs.get(1, False)
    movers = [Mover(2, 1, big.neighbors, big.dist_to((0, 3)), 3),
              Mover(1, 1, small.neighbors, small.dist_to((0, 2)), 2),
              Mover(1, 1, small.neighbors, small.dist_to((1, 2)), 7)]
    start = ((0, 0, 0), (2, 2, 0), (7, 7, 0))
    nxt = footprint_step(movers, start, [5.0, 1.0, 0.5], np.zeros(15), layout.cols)
    assert nxt is not None and nxt[0] == (1, 1, 0)
    assert nxt[1] != start[1] and nxt[2] != start[2]
    check(layout, movers, [start, tuple(nxt)])


def test_forced_targets_are_taken_or_rejected():
    layout, _, _ = make_instance(3, 4, 0.0, [], 0)
    small = GraphSet(layout).get(1, False)
    movers = [Mover(1, 1, small.neighbors, small.dist_to((0, 3)), 3),
              Mover(1, 1, small.neighbors, small.dist_to((0, 0)), 0)]
    start = ((0, 0, 0), (1, 1, 0))
    nxt = footprint_step(movers, start, [1.0, 0.5], np.zeros(12), layout.cols, forced={1: 5})
    assert nxt is not None and nxt[1] == (5, 5, 0)
    # Two agents forced onto one node, or through each other: no configuration.
    assert footprint_step(movers, start, [1.0, 0.5], np.zeros(12), layout.cols,
                          forced={0: 4, 1: 4}) is None
    assert footprint_step(movers, start, [1.0, 0.5], np.zeros(12), layout.cols,
                          forced={0: 1, 1: 0}) is None


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(), st.integers(0, 2**16), st.integers(1, 40))
def test_pibt_steps_never_conflict(instance, seed, steps):
    """Roll footprint-aware PIBT out for a while (priorities aging as in the loop, some
    agents held now and then): every state sequence passes the validator."""
    layout, movers, starts = instance
    rng = np.random.default_rng(seed)
    prio = list(rng.random(len(movers)))
    configs = [tuple(starts)]
    for _ in range(steps):
        held = {i: p[1] for i, p in enumerate(configs[-1])
                if p[2] == 0 and rng.random() < 0.1}
        nxt = footprint_step(movers, configs[-1], prio, rng.random(layout.rows * layout.cols)
                             * 0.5, layout.cols, forced=held)
        assert nxt is not None  # holds and moves under way never contradict
        for i, v in held.items():
            assert nxt[i] == (v, v, 0)
        configs.append(tuple(nxt))
        prio = update_footprint_priorities(prio, movers, configs[-1])
    check(layout, movers, configs)


# --------------------------------------------------------------------------- LaCAM


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(max_side=7, max_agents=5), st.integers(0, 2**16))
def test_lacam_plans_are_valid_and_reach_every_goal(instance, seed):
    layout, movers, starts = instance
    configs, stats = footprint_lacam(movers, starts, layout.cols, time.monotonic() + 5,
                                     np.random.default_rng(seed))
    if configs is None:
        return
    traj = check(layout, movers, configs)
    for i, mv in enumerate(movers):
        assert traj[i][0] == starts[i][:2] and traj[i][-1] == (mv.goal, mv.goal)
    assert configs[0] == tuple(starts)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(max_side=4, max_agents=3), st.integers(0, 2**16))
def test_lacam_is_complete_on_tiny_instances(instance, seed):
    """LaCAM solves a tiny instance iff the brute-force search can, and says "exhausted"
    when it cannot."""
    layout, movers, starts = instance
    solvable = brute_force_solvable(movers, starts, layout.cols)
    assume(solvable is not None)
    configs, stats = footprint_lacam(movers, starts, layout.cols, time.monotonic() + 30,
                                     np.random.default_rng(seed))
    assert (configs is not None) == solvable, stats
    if configs is None:
        assert stats["exhausted"] is True
    else:
        check(layout, movers, configs)


def test_lacam_solves_a_head_on_of_a_slow_2x2_agent_and_a_1x1_agent():
    """They meet head-on in a corridor the 2x2 agent fills: the 1x1 agent can only let it
    pass from the one pocket."""
    grid = ["#####.####",
            "..........",
            "........SR"]
    layout = build_layout(LayoutSpec(grid=grid))
    graphs = GraphSet(layout)
    big, small = graphs.get(2, False), graphs.get(1, False)
    cols = layout.cols
    movers = [Mover(2, 2, big.neighbors, big.dist_to((1, 8)), 1 * cols + 8),
              Mover(1, 1, small.neighbors, small.dist_to((1, 0)), 1 * cols + 0)]
    starts = [(1 * cols + 2, 1 * cols + 2, 0), (1 * cols + 6, 1 * cols + 6, 0)]
    assert brute_force_solvable(movers, starts, cols) is True
    configs, _ = footprint_lacam(movers, starts, cols, time.monotonic() + 10,
                                 np.random.default_rng(0))
    assert configs is not None
    check(layout, movers, configs)
