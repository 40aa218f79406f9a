"""(anchor, heading) distance tables (issue 15, :mod:`warerover_phys.planning.rotation`):
scipy's Dijkstra over the cached reversed state graph gives exactly the tables of the
reference Dijkstra in Python, and the cache on a motion graph holds a fleet's goals."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from warerover_phys import load_scenario
from warerover_phys.layout import build_layout
from warerover_phys.planning.graph import MotionGraph
from warerover_phys.planning.rotation import (
    UNREACHABLE_T,
    graph_rotation_dist,
    rotation_dist,
    rotation_dist_csr,
    rotation_graph,
)


def _grid(rows: int, cols: int, free: list[bool], expand: list[bool]):
    """4-neighbour moves between free cells (none out of a non-expandable one is still
    listed: :func:`rotation_dist` is what must skip it)."""
    nbrs = []
    for u in range(rows * cols):
        r, c = divmod(u, cols)
        out = []
        if free[u]:
            for dr, dc in ((0, 1), (1, 0), (0, -1), (-1, 0)):
                rr, cc = r + dr, c + dc
                if 0 <= rr < rows and 0 <= cc < cols and free[rr * cols + cc]:
                    out.append(rr * cols + cc)
        nbrs.append(tuple(out))
    return nbrs, expand


@settings(max_examples=60, deadline=None)
@given(rows=st.integers(1, 7), cols=st.integers(1, 7), data=st.data(),
       m=st.integers(1, 3), quarter=st.integers(1, 3), half=st.integers(1, 5))
def test_scipy_tables_equal_the_reference(rows, cols, data, m, quarter, half):
    n = rows * cols
    free = data.draw(st.lists(st.booleans(), min_size=n, max_size=n))
    expand = data.draw(st.lists(st.booleans(), min_size=n, max_size=n))
    nbrs, exp = _grid(rows, cols, free, expand)
    rev = rotation_graph(nbrs, exp, cols, m, quarter, half)
    for goal in (*range(n), -1, n):
        ref = rotation_dist(nbrs, exp, cols, goal, m, quarter, half)
        got = rotation_dist_csr(rev, n, goal)
        assert got.dtype == ref.dtype and got.shape == ref.shape == (n, 4)
        assert np.array_equal(got, ref), goal
        assert got.flags.writeable == ref.flags.writeable


def test_zero_cost_turns_fall_back_to_the_reference():
    """scipy reads an explicit 0 weight as no edge: no state graph is built then."""
    nbrs, exp = _grid(2, 3, [True] * 6, [True] * 6)
    assert rotation_graph(nbrs, exp, 3, 1, 0, 0) is None


def test_graph_tables_on_a_warehouse_layout_and_the_fleet_cache():
    sc = load_scenario("layouts/paper_homogeneous.yaml")
    graph = MotionGraph(build_layout(sc.layout, fleet_size=sum(a.count for a in sc.fleet.agvs)), 1, False)
    n = len(graph.neighbors)
    goals = list(range(0, n, max(1, n // 300)))[:300]
    assert len(goals) == 300
    tables = [graph_rotation_dist(graph, g, 1, 1, 2) for g in goals]
    for g in goals[::37]:
        ref = rotation_dist(graph.neighbors, graph.expandable_flat, graph.cols, g, 1, 1, 2)
        assert np.array_equal(tables[goals.index(g)], ref)
        assert (ref[g] == 0).all() and (ref < UNREACHABLE_T).any()
    # 300 distinct goals (a fleet of 300 AGVs) all stay cached: the same objects come back
    assert all(graph_rotation_dist(graph, g, 1, 1, 2) is t for g, t in zip(goals, tables, strict=True))
