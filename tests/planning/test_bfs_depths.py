"""The distance tables' breadth-first depths agree with scipy's unweighted Dijkstra."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from warerover_phys.planning.graph import UNREACHABLE, bfs_depths
from warerover_phys.planning.oneshot.core import grid_graph


@settings(max_examples=60, deadline=None)
@given(rows=st.integers(1, 12), cols=st.integers(1, 12), density=st.floats(0, 0.5),
       seed=st.integers(0, 2**16), directed=st.booleans())
def test_depths_equal_dijkstra(rows, cols, density, seed, directed):
    rng = np.random.default_rng(seed)
    if directed:  # random directed graph, some edges one way only
        n = rows * cols
        m = rng.integers(0, 3 * n + 1)
        a, b = rng.integers(0, n, m), rng.integers(0, n, m)
        graph = csr_matrix((np.ones(m, dtype=np.int8), (a, b)), shape=(n, n))
    else:
        obstacles = rng.random((rows, cols)) < density
        graph = grid_graph(obstacles)._rev
        n = rows * cols
    source = int(rng.integers(0, n))
    want = shortest_path(graph, method="D", directed=True, unweighted=True, indices=source)
    want = np.where(np.isfinite(want), want, UNREACHABLE).astype(np.int32)
    assert np.array_equal(bfs_depths(graph, source), want)
