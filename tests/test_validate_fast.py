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


@settings(max_examples=300, deadline=None)
@given(case=plans(), start=st.integers(0, 3))
def test_fast_path_reports_what_the_general_one_does(case, start):
    obstacles, trajectories = case
    fast = _validate_cells(trajectories, obstacles, start, 10_000)
    slow = _validate_general(trajectories, obstacles, {}, {}, start, 10_000)
    assert fast == slow
    assert validate_states(trajectories, obstacles, start_tick=start) == slow[:100]
