"""The compiled PIBT steps (:mod:`warerover_phys.planning.pibt.kernels`) against the Python
reference steps: the same next cells, headings and actions on random grids (hypothesis), and
the same output over whole lifelong runs of ``warehouse_small`` with 200 and 400 robots.
Every step is also checked by an independent validator (no shared cells, no swaps, no
jumps, forward moves straight ahead)."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from warerover_phys.planning.dist_store import DistStore
from warerover_phys.planning.oneshot.core import grid_graph
from warerover_phys.planning.pibt import heading_kernels as hk
from warerover_phys.planning.pibt import kernels as pn
from warerover_phys.planning.pibt.heading import (
    STEP,
    Facing,
    heading_pibt_step,
    steps_of,
    turn_first,
)
from warerover_phys.planning.pibt.planner import PIBTPlanner
from warerover_phys.planning.pibt.reference import pibt_step
from warerover_phys.problems.robotrunners import output_json, problem_scenario, read_problem
from warerover_phys.sim import Simulation

pytestmark = pytest.mark.skipif(not pn.AVAILABLE, reason="numba is not installed")

DATA = Path(__file__).parent.parent / "data" / "lorr2023_warehouse_small"


def _valid(graph, cols, config, nxt, heading=None, nh=None, acts=None):
    """An independent check of one step (not the runner's own)."""
    assert len(set(nxt)) == len(nxt), "two robots on one cell"
    moved_into = {v: i for i, v in enumerate(nxt)}
    for i, (a, b) in enumerate(zip(config, nxt, strict=True)):
        j = moved_into.get(a)
        assert not (j is not None and j != i and config[j] == b), "swap"
        assert a == b or b in graph.neighbors[a], "jump"
        if acts is not None and a != b:
            assert acts[i] == "F" and nh[i] == heading[i]
            assert (b // cols - a // cols, b % cols - a % cols) == STEP[heading[i]]


@st.composite
def _instances(draw):
    rows = draw(st.integers(2, 9))
    cols = draw(st.integers(2, 9))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    obstacles = rng.random((rows, cols)) < draw(st.sampled_from([0.0, 0.15, 0.3]))
    free = np.flatnonzero(~obstacles.ravel())
    if len(free) == 0:
        obstacles[0, 0] = False
        free = np.array([0])
    n = draw(st.integers(1, len(free)))
    return obstacles, rng, free, n


@pytest.mark.slow  # 80 random floors through the Python reference: make test-all
@settings(max_examples=80, deadline=None)
@given(_instances())
def test_compiled_steps_match_the_python_steps_on_random_grids(inst):
    obstacles, rng, free, n = inst
    cols = obstacles.shape[1]
    graph = grid_graph(obstacles)
    store = DistStore(graph, budget_mb=4)  # uint16, or int32 where the grid is split
    tab = pn.step_tables(graph.neighbors, cols)
    config = rng.choice(free, n, replace=False).tolist()
    goals = rng.choice(free, n).tolist()
    tables = [store.get(g) for g in goals]
    views = [memoryview(t) for t in tables]
    typed = pn.robot_tables(tables)
    prio = rng.random(n).tolist()
    order = pn.priority_order(prio)
    tie = rng.random(graph.num_nodes) * 0.5
    heading = rng.integers(0, 4, n).tolist()
    escaping = rng.random(n) < 0.3

    # cells, no rotations
    want = pibt_step(graph, config, views, prio, tie.tolist(), goals=goals)
    got = pn.pibt_step_nb(tab, np.array(config), np.array(goals), typed, order, tie).tolist()
    assert got == want
    _valid(graph, cols, config, got)

    # cells with the turn-first costs
    costs = [Facing(views[i], config[i], heading[i], cols) for i in range(n)]
    want = pibt_step(graph, config, costs, prio, tie.tolist(), goals=goals)
    got = pn.pibt_step_nb(tab, np.array(config), np.array(goals), typed, order, tie,
                          heading=np.array(heading)).tolist()
    assert got == want
    acts = ["W"] * n
    hd = list(heading)
    moved = turn_first(config, got, hd, acts, cols)
    c_moved, c_hd, c_acts = hk.turn_first_nb(np.array(config), np.array(got), np.array(heading),
                                             cols, graph.num_nodes)
    assert (c_moved.tolist(), c_hd.tolist(), c_acts.tobytes().decode("ascii")) == (
        moved, hd, "".join(acts))
    _valid(graph, cols, config, moved, heading, hd, acts)

    # cells, some robots held where they are (the reference's forced moves)
    held = rng.random(n) < 0.3
    forced = [(i, config[i]) for i in np.flatnonzero(held).tolist()]
    want = pibt_step(graph, config, views, prio, tie.tolist(), forced=forced, goals=goals)
    got = pn.pibt_step_nb(tab, np.array(config), np.array(goals), typed, order, tie,
                          held=held).tolist()
    assert got == want and all(got[i] == config[i] for i, _ in forced)
    _valid(graph, cols, config, got)

    # cells without cycles of moves (for executors that follow a dependency graph)
    want = pibt_step(graph, config, views, prio, tie.tolist(), goals=goals, acyclic=True)
    got = pn.pibt_step_nb(tab, np.array(config), np.array(goals), typed, order, tie,
                          acyclic=True).tolist()
    assert got == want
    _valid(graph, cols, config, got)
    _no_cycle(config, got)

    # actions forward / turn / wait
    w_nxt, w_nh, w_acts, w_esc = heading_pibt_step(
        graph.neighbors, cols, config, heading, views, prio, tie.tolist(),
        frozenset(np.flatnonzero(escaping).tolist()), steps_of(graph.neighbors, cols))
    g_nxt, g_nh, g_acts, g_esc = hk.heading_step_nb(tab, np.array(config), np.array(heading),
                                                    typed, order, tie, escaping)
    assert g_nxt.tolist() == w_nxt and g_nh.tolist() == w_nh
    assert g_acts.tobytes().decode("ascii") == "".join(w_acts)
    assert set(np.flatnonzero(g_esc).tolist()) == set(w_esc)
    _valid(graph, cols, config, w_nxt, heading, w_nh, w_acts)

    # ... and without cycles
    w_nxt, w_nh, w_acts, w_esc = heading_pibt_step(
        graph.neighbors, cols, config, heading, views, prio, tie.tolist(),
        frozenset(np.flatnonzero(escaping).tolist()), steps_of(graph.neighbors, cols),
        acyclic=True)
    g_nxt, g_nh, g_acts, g_esc = hk.heading_step_nb(tab, np.array(config), np.array(heading),
                                                    typed, order, tie, escaping, acyclic=True)
    assert g_nxt.tolist() == w_nxt and g_nh.tolist() == w_nh
    assert g_acts.tobytes().decode("ascii") == "".join(w_acts)
    _valid(graph, cols, config, w_nxt, heading, w_nh, w_acts)
    _no_cycle(config, w_nxt)


def _no_cycle(config, nxt):
    """No cycle of moves: following each robot into the cell it enters never comes back
    to it (an independent check: the chain of who stood where)."""
    at = {c: i for i, c in enumerate(config)}
    for i in range(len(config)):
        seen, j = {i}, i
        while nxt[j] != config[j]:
            k = at.get(nxt[j])
            if k is None:
                break
            assert k not in seen, f"robots {sorted(seen)} move in a cycle"
            seen.add(k)
            j = k


def _run(problem, ticks: int, rotations: bool, rule: str, engine: str):
    sc = problem_scenario(problem, ticks=ticks, rotations=rotations, rule=rule, seed=7)
    sim = Simulation(sc, planner=PIBTPlanner(rotation=rule, engine=engine))
    result = sim.run()
    doc = output_json(result, problem, rotations=rotations)
    doc.pop("plannerTimes")
    return result, doc


def _same_runs(robots: int, ticks: int, rotations: bool, rule: str, **kw) -> None:
    """Whole lifelong runs in the loop with the compiled steps and with the Python
    references: the same output; every step checked."""
    problem = read_problem(DATA / "warehouse_small_400.json")
    problem = dataclasses.replace(problem, starts=problem.starts[:robots], **kw)
    ref, ref_doc = _run(problem, ticks, rotations, rule, "python")
    fast, fast_doc = _run(problem, ticks, rotations, rule, "numba")
    assert fast_doc["numTaskFinished"] == ref_doc["numTaskFinished"] > 0
    assert hashlib.sha256(json.dumps(fast_doc, sort_keys=True).encode()).hexdigest() == \
        hashlib.sha256(json.dumps(ref_doc, sort_keys=True).encode()).hexdigest()
    graph = grid_graph(problem.grid.obstacles)
    cols = problem.grid.cols
    steps = list(zip(*[[s[1] for s in fast.actual[i]] for i in range(robots)], strict=True))
    heads = list(zip(*[fast.headings[i] for i in range(robots)], strict=True)) \
        if rotations else None
    paths = [p.split(",") for p in fast_doc["actualPaths"]]
    for t in range(ticks):
        acts = [p[t] for p in paths]
        _valid(graph, cols, list(steps[t]), list(steps[t + 1]),
               list(heads[t]) if rotations else None, list(heads[t + 1]) if rotations else None,
               acts if rotations else None)


@pytest.mark.parametrize("rotations,rule", [(False, "actions"), (True, "actions"),
                                           (True, "turn-first")])
def test_lifelong_runs_give_the_same_output_with_either_engine(rotations, rule):
    _same_runs(200, 250, rotations, rule)


def test_the_task_pool_assigns_the_same_with_either_engine():
    """The 2024 pool (nearest open task, compiled with numba in the fast engine)."""
    _same_runs(150, 200, False, "actions", strategy="pool", reveal=1.5, version="2024")


@pytest.mark.slow
@pytest.mark.parametrize("rotations,rule", [(False, "actions"), (True, "actions"),
                                           (True, "turn-first")])
def test_lifelong_runs_give_the_same_output_with_400_robots(rotations, rule):
    _same_runs(400, 400, rotations, rule)


def test_steps_compiled_once_are_loaded_from_the_cache():
    """``cache=True``: numba keeps the compiled steps in its cache (no recompiling in the
    next process): beside the module, or under ``NUMBA_CACHE_DIR`` where that is set."""
    import numba

    pn.warm_up()
    root = Path(numba.config.CACHE_DIR) if numba.config.CACHE_DIR else \
        Path(pn.__file__).parent / "__pycache__"
    # (numba names a cache file after the module that defines the function)
    name = f"{Path(pn.__file__).stem}._pibt_kernel*.nbi"
    assert any(root.rglob(name)), (root, name)


def test_step_tables_and_priority_order():
    tab = pn.step_tables([(1,), (0, 2), (1,)], 3)
    assert tab.nbr.tolist() == [[1, -1, -1, -1], [0, 2, -1, -1], [1, -1, -1, -1]]
    assert tab.ahead.tolist() == [[1, -1, -1, -1], [2, -1, 0, -1], [-1, -1, 1, -1]]
    assert pn.priority_order([0.5, 2.0, 2.0, 1.0]).tolist() == [1, 2, 3, 0]
