"""Rotations in the open loop: a grid run whose plan turns AGVs round a cycle in one tick
is repaired with the local detour of ``warerover execute`` (inserted as ticks in which the
rest of the fleet stands), executed on physics, and reported: repairs, AGVs, ticks added;
the planned figures stay those of the plan as given, ``repaired_*`` beside them, and the
lost-time parts (``rotation_repair`` among them) still add up for every AGV."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from warerover_phys import load_scenario
from warerover_phys.config import AgvTypeSpec, ExecutorSpec
from warerover_phys.execute import load_floor
from warerover_phys.executors.adg import ADGCycleError, build
from warerover_phys.gap.core import open_loop_gap
from warerover_phys.gap.ideal_plan import (
    Dwell,
    TimedPlan,
    _rotations,
    record_grid_run,
    repair_rotations,
)
from warerover_phys.gap.open_loop import PARTS, execute_timed, open_loop_report
from warerover_phys.planning.paths import TimedPath
from warerover_phys.validate import validate_states

HOMO = "layouts/paper_homogeneous.yaml"
CW = [(1, 1), (1, 2), (2, 2), (2, 1)]  # a 2x2 block's cells, clockwise


def _open_floor(tmp_path: Path, rows: int, cols: int):
    p = tmp_path / f"open{rows}x{cols}.map"
    p.write_text(f"type octile\nheight {rows}\nwidth {cols}\nmap\n" + ("." * cols + "\n") * rows)
    return load_floor(p)[0]


def _rotation_plan(tmp_path: Path) -> TimedPlan:
    """Four AGVs turn a 2x2 block clockwise at tick 1 (after a standing tick), then each
    makes two more moves; AGV 0 picks for two ticks after the turn; AGV 4 elsewhere on
    the floor moves along the top row throughout."""
    layout = _open_floor(tmp_path, 5, 6)
    cols = layout.cols

    def f(rc):
        return rc[0] * cols + rc[1]

    paths = {}
    for i, cell in enumerate(CW):
        nxt = CW[(i + 1) % 4]
        seq = [cell, cell, nxt]
        if i == 0:
            seq += [nxt, nxt]  # the pick
        seq += [nxt, nxt]
        paths[i] = TimedPath(i, 0, tuple((f(c), f(c)) for c in seq))
    # AGVs 1-3 stand after the turn; AGV 0 picks two ticks at (1, 2) (ticks 2-3), then all
    # stand. AGV 4 drives along the bottom row, away from the block.
    row4 = [(4, c) for c in range(6)]
    paths[4] = TimedPath(4, 0, tuple((f(c), f(c)) for c in row4))
    dwells = {0: (Dwell(0, 2, 2, "pick", f(CW[1])),)}
    spec = AgvTypeSpec(body_m=(0.7, 0.7), max_speed_mps=1.0)
    return TimedPlan(layout=layout, types=[spec] * 5, tick_s=1.0, paths=paths,
                     dwells=dwells, source="test rotation")


def _parts_add_up(agents: list[dict]) -> None:
    for a in agents:
        assert math.isclose(sum(a[f"lost_{p}_s"] for p in PARTS), a["lost_s"], abs_tol=1e-9)
        assert math.isclose(a["lost_s"], a["executed_finish_s"] - a["planned_finish_s"],
                            abs_tol=1e-9)
        assert a["lost_rotation_repair_s"] >= 0


def test_small_rotation_is_repaired_and_executed(tmp_path):
    plan = _rotation_plan(tmp_path)
    sizes = {i: 1 for i in range(5)}
    with pytest.raises(ADGCycleError):
        build(plan.paths, sizes, cols=plan.layout.cols)
    fixed = repair_rotations(plan)
    assert fixed is not plan and len(fixed.repairs) == 1
    r = fixed.repairs[0]
    assert r.timestep == 2 and set(r.agents) >= {0, 1, 2, 3} and r.moves >= 4
    # the independent validator and the dependency graph accept it; no rotation is left
    states = {i: list(p.states) for i, p in fixed.paths.items()}
    assert validate_states(states, fixed.layout.obstacles, sizes=sizes) == []
    assert _rotations(states, 5, fixed.layout.cols, 0) == []
    build(fixed.paths, sizes, cols=fixed.layout.cols)
    # same starts and ends; the pick moved with its AGV and kept its length
    for i in range(5):
        assert fixed.paths[i].states[0] == plan.paths[i].states[0]
        assert fixed.paths[i].states[-1] == plan.paths[i].states[-1]
    (d,) = fixed.dwells[0]
    assert d.ticks == 2 and d.tick == 2 + r.moves and d.node == plan.dwells[0][0].node
    assert all(fixed.paths[0].states[t] == (d.node, d.node)
               for t in range(d.tick, d.tick + d.ticks + 1))
    # planned side: the plan as given; the block's AGVs arrive at most the detour's length
    # later (each once its own last detour move is made)
    assert fixed.given_finish == tuple(plan.planned_finish(i) for i in range(5))
    for i in range(4):
        assert plan.planned_finish(i) < fixed.planned_finish(i) <= \
            plan.planned_finish(i) + r.moves
    # AGV 4 was mid-way along its row and stood for the detour
    assert fixed.planned_finish(4) == plan.planned_finish(4) + r.moves
    run = execute_timed(fixed, ExecutorSpec(name="physics"))
    report, agents, _ = open_loop_report(run)
    assert report["completed"] and report["deadlocks"] == 0 and report["agv_contacts"] == 0
    assert report["cycle_repairs"] == 1 and report["cycle_repair_moves"] == r.moves
    assert report["planned_makespan_s"] == max(plan.planned_finish(i) for i in range(5))
    added = sum(fixed.planned_finish(i) - plan.planned_finish(i) for i in range(5))
    assert report["repaired_makespan_s"] == max(fixed.planned_finish(i) for i in range(5))
    assert report["cycle_repair_added_ticks"] == added
    assert report["lost_rotation_repair_s_fleet_total"] == added
    _parts_add_up(agents)


def test_a_plan_without_rotation_comes_back_as_it_is():
    plan = record_grid_run(load_scenario(HOMO).with_seed(1))
    assert repair_rotations(plan) is plan


def test_seed_43_rotation_is_repaired():
    """Regression: seed 43 of paper_homogeneous turns four AGVs round a 2x2 block in one
    tick on the grid; the open loop refused it. The repair replaces the turn by a detour."""
    plan = record_grid_run(load_scenario(HOMO).with_seed(43))
    fixed = repair_rotations(plan)
    (r,) = fixed.repairs
    assert set(r.agents) >= {0, 1, 3, 8} and r.moves >= 4
    sizes = {i: t.footprint for i, t in enumerate(fixed.types)}
    build(fixed.paths, sizes, cols=fixed.layout.cols)  # acyclic now
    states = {i: list(p.states) for i, p in fixed.paths.items()}
    assert validate_states(states, fixed.layout.obstacles, sizes=sizes) == []
    # every dwell is kept, with its length and cell, and orders move with their AGV
    for i in range(plan.num_agents):
        assert [(d.ticks, d.kind, d.node) for d in plan.dwells[i]] == \
            [(d.ticks, d.kind, d.node) for d in fixed.dwells[i]]
    assert [o["given_completed_tick"] for o in fixed.orders] == \
        [o["completed_tick"] for o in plan.orders]
    assert fixed.task_state.shape[0] == plan.task_state.shape[0] + r.moves


@pytest.mark.slow
def test_seed_43_open_loop_gap_reports_the_repair():
    g = open_loop_gap(load_scenario(HOMO), 43)
    rep = g.report
    assert rep["completed"] and rep["deadlocks"] == 0 and rep["cycle_repairs"] == 1
    assert rep["planned_makespan_s"] == 89.0  # the grid run as given
    assert rep["repaired_makespan_s"] > rep["planned_makespan_s"]
    assert rep["cycle_repairs_detail"][0]["timestep"] == 22
    _parts_add_up(g.agents)
