"""The vectorised validator of 1x1 standing states agrees with the general one."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from warerover_phys.validate import _validate_cells, _validate_general, validate_states


@st.composite
def plans(draw):
    rows, cols = draw(st.integers(1, 5)), draw(st.integers(1, 5))
    obstacles = np.array(draw(st.lists(st.booleans(), min_size=rows * cols,
                                       max_size=rows * cols))).reshape(rows, cols)
    n = draw(st.integers(1, 5))
    trajectories = {}
    for agv in draw(st.lists(st.integers(0, 50), min_size=n, max_size=n, unique=True)):
        cells = draw(st.lists(st.integers(-1, rows * cols), min_size=1, max_size=6))
        trajectories[agv] = [(v, v) for v in cells]
    return obstacles, trajectories


# 300 examples: the fast path against the general one, cheap
@settings(max_examples=300, deadline=None)
@given(case=plans(), start=st.integers(0, 3))
def test_fast_path_reports_what_the_general_one_does(case, start):
    obstacles, trajectories = case
    fast = _validate_cells(trajectories, obstacles, start, 10_000)
    slow = _validate_general(trajectories, obstacles, {}, {}, start, 10_000)
    assert fast == slow
    assert validate_states(trajectories, obstacles, start_tick=start) == slow[:100]


@st.composite
def plans_on_the_grid(draw):
    """Plans whose cells are all on the grid (the vectorised pre-check decides alone)."""
    rows, cols = draw(st.integers(1, 4)), draw(st.integers(1, 4))
    n = draw(st.integers(1, 6))
    length = draw(st.integers(1, 6))
    trajectories = {}
    for agv in range(n):
        cells = draw(st.lists(st.integers(0, rows * cols - 1), min_size=1, max_size=length))
        trajectories[agv] = [(v, v) for v in cells]
    return np.zeros((rows, cols), dtype=bool), trajectories


# 300 examples: the fast path against the general one, cheap
@settings(max_examples=300, deadline=None)
@given(case=plans_on_the_grid())
def test_vertex_and_swap_precheck_answers_as_the_loop(case):
    """The all-ticks pre-check of the fast path says "none" exactly when the general
    validator finds no vertex or swap conflict; the conflicts stay the same."""
    from warerover_phys.validate import _any_vertex_or_swap

    obstacles, trajectories = case
    slow = _validate_general(trajectories, obstacles, {}, {}, 0, 10_000)
    assert _validate_cells(trajectories, obstacles, 0, 10_000) == slow
    ids = sorted(trajectories)
    horizon = max(len(t) for t in trajectories.values())
    pos = np.array([[trajectories[a][min(t, len(trajectories[a]) - 1)][0] for a in ids]
                    for t in range(horizon)], dtype=np.int64)
    found = any(c.kind in ("vertex", "swap") for c in slow)
    assert _any_vertex_or_swap(pos, obstacles.size) == found


def test_a_swap_alone_is_found():
    """Two agents exchanging cells (no vertex conflict anywhere), beside a third that waits."""
    obstacles = np.zeros((1, 4), dtype=bool)
    trajectories = {0: [(0, 0), (1, 1), (2, 2)], 1: [(3, 3), (2, 2), (1, 1)],
                    2: [(3, 3)] * 3}
    fast = validate_states({0: trajectories[0], 1: trajectories[1]}, obstacles)
    assert [c.kind for c in fast] == ["swap"]
    assert fast == _validate_general({0: trajectories[0], 1: trajectories[1]}, obstacles,
                                     {}, {}, 0, 100)
    kinds = [c.kind for c in validate_states(trajectories, obstacles)]
    assert "swap" in kinds


@st.composite
def cell_paths(draw):
    """One-shot plans as (row, column) paths, cells on the grid or off it."""
    rows, cols = draw(st.integers(1, 4)), draw(st.integers(1, 4))
    obstacles = np.array(draw(st.lists(st.booleans(), min_size=rows * cols,
                                       max_size=rows * cols))).reshape(rows, cols)
    cell = st.tuples(st.integers(-1, rows), st.integers(0, cols - 1))
    paths = draw(st.lists(st.lists(cell, min_size=1, max_size=6), min_size=1, max_size=6))
    return obstacles, paths


# 300 examples: the fast path against the general one, cheap
@settings(max_examples=300, deadline=None)
@given(case=cell_paths())
def test_cell_paths_are_checked_as_their_states(case):
    """``validate_cell_paths`` (what ``warerover solve`` checks its plans with) reports what
    the general validator reports for the same plan as per-tick states."""
    from warerover_phys.validate import validate_cell_paths

    obstacles, paths = case
    cols = obstacles.shape[1]
    states = {i: [(r * cols + c,) * 2 for r, c in p] for i, p in enumerate(paths)}
    expected = _validate_general(states, obstacles, {}, {}, 0, 10_000)
    assert validate_cell_paths(paths, obstacles, max_conflicts=10_000) == expected
