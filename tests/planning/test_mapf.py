"""One-shot MAPF: LaCAM, PIBT and prioritized A* on MovingAI instances and random grids."""

from __future__ import annotations

import json
import subprocess
import sys
from collections import deque
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys.planning.graph import UNREACHABLE
from warerover_phys.planning.oneshot.core import grid_graph, solve
from warerover_phys.problems.movingai import read_map, read_scen
from warerover_phys.validate import validate_states

DATA = Path(__file__).resolve().parents[1] / "data"
MAP = DATA / "warehouse-10-20-10-2-1.map"
SCEN = DATA / "warehouse-10-20-10-2-1-random-1.scen"
CLI = str(Path(sys.executable).parent / "warerover")


def assert_valid(obstacles, starts, goals, result):
    assert result.success
    cols = obstacles.shape[1]
    traj = {i: [(r * cols + c,) * 2 for r, c in p] for i, p in enumerate(result.paths)}
    assert validate_states(traj, obstacles) == []
    for path, s, g in zip(result.paths, starts, goals, strict=True):
        assert path[0] == s and path[-1] == g
    assert result.sum_of_costs >= result.lower_bound


@pytest.mark.parametrize("planner,n", [("lacam", 300), ("pibt", 100), ("astar", 40)])
def test_planners_solve_the_warehouse_map(planner, n):
    grid = read_map(MAP)
    agents = read_scen(SCEN, n, grid)
    starts, goals = [a.start for a in agents], [a.goal for a in agents]
    result = solve(grid.obstacles, starts, goals, planner=planner, time_limit_s=60)
    assert_valid(grid.obstacles, starts, goals, result)
    # The scenario's optimal lengths are octile (8-connected): never longer than ours.
    assert result.lower_bound >= sum(a.optimal_length for a in agents) - 1e-6


def test_same_seed_same_plan():
    grid = read_map(MAP)
    agents = read_scen(SCEN, 150, grid)
    args = (grid.obstacles, [a.start for a in agents], [a.goal for a in agents])
    a, b = solve(*args, planner="lacam", seed=3), solve(*args, planner="lacam", seed=3)
    assert a.paths == b.paths


def joint_solvable(obstacles, starts, goals) -> bool:
    """Brute force: BFS over joint configurations with vertex and swap constraints."""
    graph = grid_graph(obstacles)
    s = tuple(graph.node(c) for c in starts)
    g = tuple(graph.node(c) for c in goals)
    seen = {s}
    queue = deque([s])
    while queue:
        q = queue.popleft()
        if q == g:
            return True
        for nxt in _successors(graph, q):
            if nxt not in seen:
                seen.add(nxt)
                queue.append(nxt)
    return False


def _successors(graph, q, i=0, chosen=()):
    """Every joint move from configuration q without vertex or swap conflicts."""
    if i == len(q):
        yield chosen
        return
    for v in graph.neighbors[q[i]] + (q[i],):
        if v in chosen or any(chosen[j] == q[i] and v == q[j] for j in range(i)):
            continue
        yield from _successors(graph, q, i + 1, chosen + (v,))


@st.composite
def small_instances(draw):
    rows, cols = draw(st.integers(2, 5)), draw(st.integers(2, 5))
    rng = np.random.default_rng(draw(st.integers(0, 10**6)))
    obstacles = rng.random((rows, cols)) < draw(st.sampled_from([0.0, 0.15, 0.3]))
    free = [(r, c) for r in range(rows) for c in range(cols) if not obstacles[r, c]]
    if len(free) < 2:
        obstacles[:] = False
        free = [(r, c) for r in range(rows) for c in range(cols)]
    n = draw(st.integers(1, min(3, len(free) - 1)))
    starts = [free[i] for i in rng.permutation(len(free))[:n]]
    goals = [free[i] for i in rng.permutation(len(free))[:n]]
    graph = grid_graph(obstacles)
    if any(graph.distance(s, g) >= UNREACHABLE for s, g in zip(starts, goals, strict=True)):
        goals = starts[:]  # stay put: always reachable
    return obstacles, starts, goals


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(small_instances())
def test_lacam_is_complete_on_small_instances(instance):
    """LaCAM returns a valid plan iff the brute-force joint search finds one."""
    obstacles, starts, goals = instance
    result = solve(obstacles, starts, goals, planner="lacam", time_limit_s=20)
    solvable = joint_solvable(obstacles, starts, goals)
    assert result.success == solvable
    if solvable:
        assert_valid(obstacles, starts, goals, result)
    else:
        assert result.stats.get("exhausted") is True


@settings(max_examples=40, deadline=None)
@given(small_instances())
def test_pibt_plans_are_valid_when_found(instance):
    obstacles, starts, goals = instance
    result = solve(obstacles, starts, goals, planner="pibt", time_limit_s=5)
    if result.success:
        assert_valid(obstacles, starts, goals, result)


# ------------------------------------------------------------------------------ CLI


def run(*args):
    return subprocess.run([CLI, "solve", *map(str, args)], capture_output=True, text=True,
                          timeout=120)


def test_solve_prints_figures_and_writes_the_plan(tmp_path):
    out = tmp_path / "plan.txt"
    proc = run(MAP, SCEN, "--agents", 60, "--json", "--out", out)
    assert proc.returncode == 0, proc.stderr
    figures = json.loads(proc.stdout)
    assert figures["success"] and figures["conflicts"] == 0
    assert figures["soc_over_lb"] == pytest.approx(figures["sum_of_costs"]
                                                   / figures["lower_bound"], abs=1e-3)
    lines = out.read_text().splitlines()
    assert "solution=" in lines
    steps = lines[lines.index("solution=") + 1:]
    assert len(steps) == figures["makespan"] + 1
    # x = column, y = row: the first agent starts where the scenario says.
    agent0 = read_scen(SCEN, 1)[0]
    first = steps[0].split(":", 1)[1].split("),")[0].strip("(")
    assert tuple(int(v) for v in first.split(",")) == (agent0.start[1], agent0.start[0])
    assert all(s.startswith(f"{t}:") and s.count("(") == 60 for t, s in enumerate(steps))


@pytest.mark.parametrize("case", ["outside", "obstacle", "header", "too-many"])
def test_solve_bad_input_one_line_exit_2(case, tmp_path):
    scen_lines = SCEN.read_text().splitlines()
    map_file, scen_file, n = MAP, tmp_path / "x.scen", 3
    if case == "outside":
        parts = scen_lines[1].split("\t")
        parts[4] = "999"
        scen_lines[1] = "\t".join(parts)
    elif case == "obstacle":
        parts = scen_lines[1].split("\t")
        parts[4], parts[5] = "0", "0"  # the map's border is obstacles
        scen_lines[1] = "\t".join(parts)
    elif case == "header":
        map_file = tmp_path / "bad.map"
        map_file.write_text(MAP.read_text().replace("type octile", "type hex", 1))
    elif case == "too-many":
        n = 5000
    scen_file.write_text("\n".join(scen_lines) + "\n")
    proc = run(map_file, scen_file, "--agents", n)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr
    assert (map_file.name if case == "header" else scen_file.name) in lines[0]
