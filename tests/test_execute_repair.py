"""Rotation repair of ``warerover execute``: local detours, then a re-timing that keeps the
plan's order and delays only what waits on a detour.

Plans are built here from rotating 2x2 blocks, trains of agents following one another and
agents standing in the way; every result goes through :func:`validate_plan` and
:func:`find_cycles` and is executed on the grid executor.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys.execute import (
    PlanError,
    _dense,
    _retime,
    execute_plan,
    find_cycles,
    load_fleet,
    load_floor,
    repair_cycles,
    validate_plan,
)
from warerover_phys.plans import Plan

CW = [(0, 0), (0, 1), (1, 1), (1, 0)]  # a 2x2 block's cells in clockwise order


def _floor(tmp_path: Path, rows: int, cols: int):
    p = tmp_path / f"open{rows}x{cols}.map"
    p.write_text(f"type octile\nheight {rows}\nwidth {cols}\nmap\n"
                 + ("." * cols + "\n") * rows)
    return load_floor(p)[0]


def _check_repaired(plan: Plan, layout, sizes=None):
    sizes = sizes or [1] * plan.num_agents
    fixed, repairs = repair_cycles(plan, layout, sizes)
    validate_plan(fixed, layout, sizes)
    assert find_cycles(fixed, layout.cols) == []
    assert [p[0] for p in fixed.paths] == [p[0] for p in plan.paths]
    assert [p[-1] for p in fixed.paths] == [p[-1] for p in plan.paths]
    return fixed, repairs


def test_rotation_hemmed_in_is_repaired_with_neighbours_stepping_aside(tmp_path):
    """A 2x2 block turning with an agent standing on every cell next to it: the block's
    agents alone have nowhere to go; neighbours step aside and back."""
    layout = _floor(tmp_path, 5, 5)
    ring = [(1 + r, 1 + c) for r, c in CW]
    others = [(0, 1), (0, 2), (1, 0), (2, 0), (1, 3), (2, 3), (3, 1), (3, 2)]
    paths = [(cell, ring[(i + 1) % 4]) for i, cell in enumerate(ring)]
    paths += [(cell, cell) for cell in others]
    plan = Plan(tuple(paths), rows=5, cols=5)
    assert len(find_cycles(plan, 5)) == 1
    fixed, repairs = _check_repaired(plan, layout)
    assert len(repairs) == 1
    helpers = set(repairs[0].agents) - {0, 1, 2, 3}
    assert helpers, "the block cannot turn without a neighbour stepping aside"
    # neighbours that stepped aside are back where the plan has them
    for i in helpers:
        assert fixed.paths[i][-1] == plan.paths[i][-1]
    result = execute_plan(fixed, layout, load_fleet(None, plan.num_agents, None, []),
                          executor="grid", given=plan, repairs=repairs)
    m = result.metrics
    assert m["completed"] and m["collisions"] == 0
    assert m["planned_makespan_ticks"] == 1 and m["repaired_makespan_ticks"] == fixed.makespan
    assert m["cycle_repair_moves"] == repairs[0].moves


@pytest.mark.parametrize("holes", [0, 1])
def test_rotation_with_no_way_to_turn_is_refused(tmp_path, holes):
    """A full floor, or a floor with one free cell (a sliding puzzle: a quarter turn of
    four is an odd permutation, which one hole can never make): the error names it."""
    layout = _floor(tmp_path, 3, 3)
    ring = [(1 + r, 1 + c) for r, c in CW]
    others = [(r, c) for r in range(3) for c in range(3) if (r, c) not in ring][holes:]
    paths = [(cell, ring[(i + 1) % 4]) for i, cell in enumerate(ring)]
    plan = Plan(tuple(paths) + tuple((c, c) for c in others), rows=3, cols=3)
    with pytest.raises(PlanError, match=r"cannot repair the rotation of agents"):
        repair_cycles(plan, layout, [1] * plan.num_agents)


@st.composite
def trains(draw):
    """Rows of agents, each row a train that moves right in lockstep (every agent follows
    the one ahead in the same timestep), starting at its own time: no rotation."""
    rows = draw(st.integers(1, 4))
    cols = 8
    paths = []
    for r in range(rows):
        n = draw(st.integers(1, 4))
        start = draw(st.integers(0, 3))
        steps = draw(st.integers(0, cols - n))
        for j in range(n):
            c0 = j
            paths.append(tuple([(r, c0)] * start + [(r, c0 + s) for s in range(steps + 1)]))
    return rows, cols, Plan(tuple(paths), rows=rows, cols=cols)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=trains())
def test_retiming_a_rotation_free_plan_changes_nothing(case):
    """Following (a train) is kept as planned: re-timing without a detour is the identity."""
    rows, cols, plan = case
    pos = _dense(plan)
    paths = _retime(pos, np.arange(len(pos)), [1] * plan.num_agents, cols)
    assert paths == tuple(Plan((p,)).paths[0] for p in plan.paths)


@st.composite
def rotating_blocks(draw):
    """Disjoint 2x2 blocks on a 7x7 floor, each turning 1-3 quarter turns (clockwise or
    not) from its own timestep, and agents standing on other cells."""
    size = 7
    anchors = draw(st.lists(st.tuples(st.integers(0, size - 2), st.integers(0, size - 2)),
                            min_size=1, max_size=4))
    blocks: list[tuple[int, int]] = []
    used: set[tuple[int, int]] = set()
    for r, c in anchors:
        cells = {(r + dr, c + dc) for dr, dc in CW}
        if cells & used:
            continue
        blocks.append((r, c))
        used |= cells
    paths = []
    horizon = 0
    for r, c in blocks:
        turns = draw(st.integers(1, 3))
        t0 = draw(st.integers(0, 3))
        sense = draw(st.sampled_from([1, -1]))
        horizon = max(horizon, t0 + turns)
        cells = [(r + dr, c + dc) for dr, dc in CW]
        for i in range(4):
            path = [cells[i]] * (t0 + 1)
            path += [cells[(i + sense * s) % 4] for s in range(1, turns + 1)]
            paths.append(tuple(path))
    free = [(r, c) for r in range(size) for c in range(size) if (r, c) not in used]
    standing = draw(st.lists(st.sampled_from(free), unique=True, max_size=len(free) // 2))
    paths += [(cell,) for cell in standing]
    return size, Plan(tuple(paths), rows=size, cols=size)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=rotating_blocks())
def test_every_rotation_is_repaired_or_refused_by_name(tmp_path, case):
    size, plan = case
    layout = _floor(tmp_path, size, size)
    validate_plan(plan, layout, [1] * plan.num_agents)
    assert find_cycles(plan, size)
    try:
        fixed, repairs = _check_repaired(plan, layout)
    except PlanError as e:
        assert "cannot repair the rotation" in str(e)
        return
    assert repairs
    result = execute_plan(fixed, layout, load_fleet(None, plan.num_agents, None, []),
                          executor="grid", given=plan)
    assert result.metrics["completed"] and result.metrics["collisions"] == 0
    assert result.executed_finish == list(fixed.costs)
