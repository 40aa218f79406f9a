"""The distance-table store of lifelong runs (:mod:`warerover_phys.planning.dist_store`):
its tables hold :meth:`MotionGraph.dist_to`'s move counts on every enterable cell, compact
where the map allows, and its cache stays within its budget and counts what it does."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from warerover_phys.planning.dist_store import DistStore
from warerover_phys.planning.graph import UNREACHABLE
from warerover_phys.planning.oneshot.core import grid_graph


@given(st.integers(2, 12), st.integers(2, 12), st.floats(0.0, 0.4), st.integers(0, 2**31))
def test_tables_match_dist_to(rows, cols, density, seed):
    rng = np.random.default_rng(seed)
    obstacles = rng.random((rows, cols)) < density
    free = np.flatnonzero(~obstacles.ravel())
    if len(free) == 0:
        return
    graph = grid_graph(obstacles)
    store = DistStore(graph, budget_mb=1)
    for goal in rng.choice(free, size=min(4, len(free)), replace=False).tolist():
        want = graph.dist_to(divmod(goal, cols))
        got = store.get(goal)
        assert not got.flags.writeable
        if store.dtype is np.uint16:  # one component: every free cell reached
            assert (want[free] < UNREACHABLE).all()
        else:
            assert got.dtype == np.int32
        assert np.array_equal(got[free].astype(np.int64), want[free].astype(np.int64))


def test_split_map_keeps_unreachable_as_int32():
    obstacles = np.zeros((3, 5), dtype=bool)
    obstacles[:, 2] = True  # two rooms
    store = DistStore(grid_graph(obstacles))
    assert store.dtype is np.int32
    table = store.get(0)
    assert table[1] == 1 and table[4] == UNREACHABLE


def test_cache_evicts_least_recent_and_revives_tables_still_held():
    graph = grid_graph(np.zeros((10, 10), dtype=bool))
    store = DistStore(graph, budget_mb=3 * 100 * 2 / 2**20)  # three uint16 tables
    assert store.capacity == 3
    held = store.get(0)
    for g in (1, 2, 3):
        store.get(g)
    assert store.counters()["evictions"] == 1  # goal 0 went out
    assert store.get(0) is held  # still held by a robot: found, not recomputed
    store.get(3)
    c = store.counters()
    assert (c["misses"], c["revived"], c["hits"], c["cached_tables"]) == (4, 1, 1, 3)
    assert c["cached_mb"] <= c["budget_mb"] and c["bfs_s"] > 0


def test_slab_rows_hold_the_same_tables_and_are_reused_once_let_go():
    """``reserve``: tables are rows of one 2-D array (what the compiled PIBT reads); a row
    whose table nobody holds any more (evicted and let go) takes the next new table."""
    graph = grid_graph(np.zeros((10, 10), dtype=bool))
    plain = DistStore(graph, budget_mb=3 * 100 * 2 / 2**20)
    slab = DistStore(graph, budget_mb=3 * 100 * 2 / 2**20, reserve=2)
    assert plain.slab is None and slab.slab.shape == (3 + 2 + 1, 100)
    held = slab.get(7)
    row = slab.slot(held)
    assert np.array_equal(slab.slab[row], held) and np.array_equal(held, plain.get(7))
    assert not held.flags.writeable
    for g in (1, 2, 3):  # 7 is evicted but still held: its row stays
        assert np.array_equal(slab.get(g), plain.get(g))
    assert slab.slab_rows_in_use == 4 and slab.get(7) is held
    for g in (4, 5, 6):  # evict 1, 2, 3 and 7; the first three are let go at once
        slab.get(g)
    assert slab.slab_rows_in_use == 4
    del held  # the last holder of 7 lets go: its row is free
    assert slab.slab_rows_in_use == 3
    fresh = slab.get(9)
    assert slab.slot(fresh) == row and np.array_equal(fresh, plain.get(9))
