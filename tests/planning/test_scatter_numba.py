"""The compiled one-shot engine (``engine="numba"``: :mod:`warerover_phys.planning.oneshot.scatter_kernels`,
:mod:`warerover_phys.planning.lacam.kernels`) against the Python reference: the same guide paths,
collision counts and rounds, the same LaCAM configurations (forced moves, held agents, guide
paths, swaps), every plan through the validator; and ``warerover solve``'s own process loads
the compiled code without scipy.linalg.

The first run on a machine compiles the kernels (about 20-30 s, then numba's on-disk cache)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys.planning.graph import UNREACHABLE
from warerover_phys.planning.lacam.reference import lacam, lacam_nodes
from warerover_phys.planning.oneshot.core import goal_tables, grid_graph
from warerover_phys.planning.oneshot.scatter import guide_paths
from warerover_phys.problems.movingai import read_map, read_scen
from warerover_phys.validate import validate_states

REPO = Path(__file__).resolve().parents[2]
DATA = REPO / "tests" / "data"
MAP = DATA / "warehouse-10-20-10-2-1.map"
SCEN = DATA / "warehouse-10-20-10-2-1-random-1.scen"


@st.composite
def instances(draw, max_side=9, max_agents=10):
    """A random grid (obstacles), distinct starts and distinct goals on free cells that
    reach each other (one connected component of the start)."""
    rows = draw(st.integers(2, max_side))
    cols = draw(st.integers(2, max_side))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    obstacles = rng.random((rows, cols)) < draw(st.sampled_from([0.0, 0.15, 0.3]))
    graph = grid_graph(obstacles)
    free = [(r, c) for r in range(rows) for c in range(cols) if not obstacles[r, c]]
    if len(free) < 2:
        obstacles[:] = False
        graph = grid_graph(obstacles)
        free = [(r, c) for r in range(rows) for c in range(cols)]
    # the component of one free cell (all free cells when it is too small)
    table = graph.dist_to(free[int(rng.integers(len(free)))])
    cells = [c for c in free if table[graph.node(c)] < UNREACHABLE]
    if len(cells) < 2:
        obstacles[:] = False
        graph = grid_graph(obstacles)
        cells = [(r, c) for r in range(rows) for c in range(cols)]
    n = draw(st.integers(1, max(1, min(max_agents, len(cells) - 1))))
    starts = [cells[i] for i in rng.permutation(len(cells))[:n]]
    goals = [cells[i] for i in rng.permutation(len(cells))[:n]]
    return obstacles, graph, starts, goals, seed


def _valid(obstacles, starts, goals, paths):
    cols = obstacles.shape[1]
    traj = {i: [(r * cols + c,) * 2 for r, c in p] for i, p in enumerate(paths)}
    assert validate_states(traj, obstacles) == []
    for path, s, g in zip(paths, starts, goals, strict=True):
        assert path[0] == s and path[-1] == g


@pytest.mark.slow  # the Python reference on many instances: make test-all
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(max_side=12, max_agents=24), st.integers(0, 6), st.integers(1, 3))
def test_compiled_guide_paths_are_the_reference_paths(inst, margin, rounds):
    obstacles, graph, starts, goals, seed = inst
    s = [graph.node(c) for c in starts]
    g = [graph.node(c) for c in goals]
    arrays = [graph.dist_to(c) for c in goals]
    out = {}
    for engine in ("python", "numba"):
        out[engine] = guide_paths(graph.neighbors, s, g, arrays, np.random.default_rng(seed),
                                  margin=margin, max_rounds=rounds, engine=engine)
    ref, nb = out["python"], out["numba"]
    assert nb.paths == ref.paths and nb.next == ref.next
    for key in ("rounds", "collisions", "stopped", "unplanned"):
        assert nb.stats[key] == ref.stats[key], key
    for i, path in enumerate(nb.paths):  # and they are paths within the margin
        assert path[0] == s[i] and path[-1] == g[i]
        assert all(b in graph.neighbors[a] for a, b in zip(path, path[1:], strict=False))
        assert len(path) - 1 <= arrays[i][s[i]] + margin


@pytest.mark.parametrize("rows,cols,blocked,pairs", [
    (1, 6, [], [((0, 0), (0, 5)), ((0, 5), (0, 0))]),  # head-on in a corridor: a swap
    (1, 7, [], [((0, 0), (0, 6)), ((0, 6), (0, 1)), ((0, 3), (0, 0))]),
    (3, 5, [(0, 1), (0, 3), (2, 1), (2, 3)],  # a corridor with side pockets
     [((1, 0), (1, 4)), ((1, 4), (1, 0)), ((0, 2), (2, 2)), ((2, 2), (0, 0))]),
])
def test_compiled_guide_paths_count_the_same_swaps(rows, cols, blocked, pairs):
    """Instances whose guide paths must cross head-on: the same collision counts (swaps,
    vertex collisions, passing a parked agent) and the same paths."""
    obstacles = np.zeros((rows, cols), dtype=bool)
    for cell in blocked:
        obstacles[cell] = True
    graph = grid_graph(obstacles)
    s = [graph.node(a) for a, _ in pairs]
    g = [graph.node(b) for _, b in pairs]
    arrays = [graph.dist_to(b) for _, b in pairs]
    for seed in range(4):
        ref, nb = (guide_paths(graph.neighbors, s, g, arrays, np.random.default_rng(seed),
                               margin=2, max_rounds=3, engine=engine)
                   for engine in ("python", "numba"))
        assert ref.stats["collisions"][0] > 0
        assert nb.paths == ref.paths and nb.stats["collisions"] == ref.stats["collisions"]


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(max_agents=14), st.booleans())
def test_compiled_lacam_gives_the_reference_plan(inst, guide):
    """LaCAM's search with either step, the guide paths or none: the same configurations
    and counts, within 3,000 iterations (some random instances have no solution)."""
    obstacles, graph, starts, goals, seed = inst
    s = [graph.node(c) for c in starts]
    g = [graph.node(c) for c in goals]
    arrays = [graph.dist_to(c) for c in goals]
    nxt = None
    if guide:
        nxt = guide_paths(graph.neighbors, s, g, arrays, np.random.default_rng(seed)).next
    far = time.monotonic() + 600
    ref = lacam_nodes(graph, s, g, [a.tolist() for a in arrays], far,
                      np.random.default_rng(seed), guide=nxt, max_iterations=3000)
    nb = lacam_nodes(graph, s, g, arrays, far, np.random.default_rng(seed), guide=nxt,
                     max_iterations=3000, engine="numba")
    assert nb == ref
    if ref[0] is not None:
        cols = graph.cols
        _valid(obstacles, starts, goals, [[divmod(q[i], cols) for q in ref[0]]
                                          for i in range(len(s))])


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(max_agents=10), st.integers(1, 4))
def test_compiled_lacam_nodes_with_held_agents(inst, held_count):
    """Held agents (goal = start, never move) are forced moves of every step."""
    obstacles, graph, starts, goals, seed = inst
    k = min(held_count, len(starts))
    goals = list(starts[:k]) + list(goals[k:])
    if len(set(goals)) < len(goals):
        return
    s = [graph.node(c) for c in starts]
    g = [graph.node(c) for c in goals]
    arrays = [graph.dist_to(c) for c in goals]
    lists = [a.tolist() for a in arrays]
    far = time.monotonic() + 60
    ref = lacam_nodes(graph, s, g, lists, far, np.random.default_rng(seed), held=range(k),
                      max_iterations=2000)
    nb = lacam_nodes(graph, s, g, arrays, far, np.random.default_rng(seed), held=range(k),
                     max_iterations=2000, engine="numba")
    assert nb == ref
    if ref[0] is not None:
        cols = graph.cols
        paths = [[divmod(q[i], cols) for q in ref[0]] for i in range(len(s))]
        _valid(obstacles, starts, goals, paths)
        assert all(p[0] == p[-1] for p in paths[:k]) and all(len(set(p)) == 1 for p in paths[:k])


def test_compiled_lacam_on_the_warehouse_map():
    """120 agents of MovingAI warehouse random-1: the same plan either way and twice with
    the same seed, valid."""
    grid = read_map(MAP)
    agents = read_scen(SCEN, 120, grid)
    graph = grid_graph(grid.obstacles)
    starts, goals = [a.start for a in agents], [a.goal for a in agents]
    far = time.monotonic() + 120
    ref, ref_stats = lacam(graph, starts, goals, far, 3, guide=True, engine="python")
    nb, nb_stats = lacam(graph, starts, goals, far, 3, guide=True, engine="numba")
    again, _ = lacam(grid_graph(grid.obstacles), starts, goals, far, 3, guide=True,
                     engine="numba")
    assert ref is not None and nb == ref and again == nb  # and the same seed, the same plan
    assert nb_stats["guide"]["collisions"] == ref_stats["guide"]["collisions"]
    _valid(grid.obstacles, starts, goals, nb)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(1, 12), st.integers(1, 12), st.integers(0, 2**31 - 1),
       st.sampled_from([0.0, 0.2, 0.4]), st.integers(1, 6))
def test_compiled_goal_tables_are_the_bit_parallel_ones(rows, cols, seed, density, count):
    """``goal_tables(engine="numba")`` against the bit-parallel search and ``dist_to``,
    goals on obstacles (reached from nowhere) included."""
    rng = np.random.default_rng(seed)
    obstacles = rng.random((rows, cols)) < density
    goals = [(int(rng.integers(rows)), int(rng.integers(cols))) for _ in range(count)]
    ref = goal_tables(grid_graph(obstacles), goals)
    nb = goal_tables(grid_graph(obstacles), goals, engine="numba")
    graph = grid_graph(obstacles)
    for a, b, goal in zip(ref, nb, goals, strict=True):
        assert b.dtype == a.dtype and np.array_equal(a, b)
        assert np.array_equal(b, graph.dist_to(goal))
        assert not b.flags.writeable


def test_auto_compiles_only_with_time_for_it(monkeypatch):
    """``auto``: Python below NUMBA_MIN_AGENTS; above, the compiled kernels when numba's cache
    holds them, else only with COLD_COMPILE_S seconds left (a short limit stays honoured)."""
    from warerover_phys.planning.oneshot import scatter
    from warerover_phys.planning.oneshot import scatter_kernels as scatter_numba

    n = scatter.NUMBA_MIN_AGENTS
    now = time.monotonic()
    assert not scatter.use_numba(n - 1, None)
    monkeypatch.setattr(scatter_numba, "compiled_ready", lambda also=(): True)
    assert scatter.use_numba(n, now + 1.0)
    monkeypatch.setattr(scatter_numba, "compiled_ready", lambda also=(): False)
    assert not scatter.use_numba(n, now + 0.5 * scatter.COLD_COMPILE_S)
    assert scatter.use_numba(n, now + 2 * scatter.COLD_COMPILE_S)
    assert scatter.use_numba(n, None)


def test_the_kernels_are_in_numbas_cache_once_warmed_up():
    from warerover_phys.planning.lacam.reference import lacam_kernels
    from warerover_phys.planning.oneshot import scatter_kernels as scatter_numba
    from warerover_phys.planning.oneshot.core import warm_up

    assert warm_up() >= 0
    assert scatter_numba.compiled_ready(lacam_kernels())


def test_engine_names_are_checked():
    graph = grid_graph(np.zeros((2, 2), dtype=bool))
    with pytest.raises(ValueError, match="engine"):
        lacam(graph, [(0, 0)], [(1, 1)], time.monotonic() + 5, engine="fast")
    with pytest.raises(ValueError, match="engine"):
        guide_paths(graph.neighbors, [0], [3], [graph.dist_to((1, 1))],
                    np.random.default_rng(0), engine="fast")


def test_solve_loads_the_compiled_engine_without_scipy(tmp_path):
    """``warerover solve`` at 300 agents (the compiled engine) in its own process: no
    scipy.linalg (numba's BLAS probe skipped), a valid plan, the Python engine's plan."""
    out = tmp_path / "plan.txt"
    probe = (
        "import json, sys\n"
        "from warerover_phys.cli.solve import fast_main\n"
        "try:\n"
        f"    fast_main(['solve', {str(MAP)!r}, {str(SCEN)!r}, '--agents', '300', '--json',\n"
        f"               '--time-limit', '600', '--out', {str(out)!r}])\n"
        "except SystemExit as exit_:\n"
        "    code = exit_.code\n"
        "mods = sorted(m for m in sys.modules if m.split('.')[0] in ('scipy', 'numba'))\n"
        "print(json.dumps({'code': code, 'modules': mods}), file=sys.stderr)\n")
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          timeout=300, cwd=REPO)
    report = json.loads(proc.stderr.strip().splitlines()[-1])
    assert report["code"] == 0, proc.stderr
    figures = json.loads(proc.stdout)
    assert figures["success"] and figures["conflicts"] == 0
    assert "numba" in report["modules"] and "numba.np.arraymath" in report["modules"]
    # numba imports the scipy package itself (a version check), not scipy.linalg
    assert not [m for m in report["modules"] if m.startswith("scipy.linalg")]
    grid = read_map(MAP)
    agents = read_scen(SCEN, 300, grid)
    graph = grid_graph(grid.obstacles)
    ref, _ = lacam(graph, [a.start for a in agents], [a.goal for a in agents],
                   time.monotonic() + 120, 0, guide=True, engine="python")
    lines = out.read_text().splitlines()
    steps = lines[lines.index("solution=") + 1:]
    assert len(steps) == len(ref[0])
    for t, line in enumerate(steps):
        cells = [tuple(int(x) for x in xy.split(",")) for xy in line.split(":")[1][1:-2].split("),(")]
        assert [(y, x) for x, y in cells] == [p[t] for p in ref]
