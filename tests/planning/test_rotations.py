"""Rotation-aware planning (issue 15, ``planner.rotations``): differential-drive AGVs are
planned over (cell, heading), move only straight ahead and turn in place in the ticks the
physics executor needs. Every plan is checked by the independent validator
(``validate_states`` and ``validate_headings``)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from warerover_phys import load_scenario, scenario_from_dict
from warerover_phys.config import AgvTypeSpec
from warerover_phys.errors import ScenarioError
from warerover_phys.outputs import write_outputs
from warerover_phys.planning import (
    AgentRequest,
    AStarPlanner,
    CBSPlanner,
    LaCAMPlanner,
    PIBTPlanner,
    PlanRequest,
)
from warerover_phys.planning.rotation import (
    UNREACHABLE_T,
    agent_turn_ticks,
    quarters,
    rotation_dist,
    turn_ticks,
    turn_towards,
)
from warerover_phys.planning.sweep import DIR_OF
from warerover_phys.sim import Simulation, run_episode
from warerover_phys.testing import check_planner
from warerover_phys.validate import validate_headings, validate_states
from warerover_phys.world import World

DIRS = ((0, 1), (1, 0), (0, -1), (-1, 0))
PLANNERS = {"astar": AStarPlanner, "cbs": CBSPlanner, "pibt": PIBTPlanner,
            "lacam": LaCAMPlanner}


# ----------------------------------------------------------------------------- turn times

def test_turn_ticks_follow_the_turn_rate():
    fast = AgvTypeSpec(max_turn_rate_radps=2.5)  # 0.63 s a quarter, 1.26 s a half turn
    slow = AgvTypeSpec(max_turn_rate_radps=1.0)  # 1.57 s and 3.14 s
    assert (turn_ticks(fast, 1.0, 1), turn_ticks(fast, 1.0, 2)) == (1, 2)
    assert (turn_ticks(slow, 1.0, 1), turn_ticks(slow, 1.0, 2)) == (2, 4)
    assert turn_ticks(slow, 0.5, 1) == 4
    # pi/2 at exactly pi/2 rad/s is one tick, not two
    assert turn_ticks(AgvTypeSpec(max_turn_rate_radps=math.pi / 2), 1.0, 1) == 1
    assert agent_turn_ticks(AgvTypeSpec(drive="omni"), 1.0) is None
    assert agent_turn_ticks(fast, 1.0) == (1, 2)


def test_docstring_examples():
    import doctest

    from warerover_phys.planning import rotation

    result = doctest.testmod(rotation)
    assert result.attempted > 0 and result.failed == 0


def test_planner_without_rotations_is_refused():
    from warerover_phys.planning.base import PlanResult, TimedPath

    sc = load_scenario("layouts/paper_homogeneous.yaml",
                       [("planner.rotations", True), ("orders.oneshot.count", 2)])
    sim = Simulation(sc, 0)
    agv = sim.world.agvs[0]
    flat = PlanResult(paths={0: TimedPath(0, 0, ((agv.node, agv.node),))})
    with pytest.raises(ValueError, match="does not plan rotations"):
        sim._commit(flat, [AgentRequest(agv=0, start=agv.node, goal=agv.node)])


def test_heading_helpers():
    assert [quarters(0, h) for h in range(4)] == [0, 1, 2, 1]
    assert turn_towards(0, 1) == 1 and turn_towards(0, 3) == 3 and turn_towards(0, 0) == 0
    assert turn_towards(0, 2) in (1, 3)


def test_rotation_dist_counts_turns():
    # A 1 x 4 corridor, goal at the east end: facing east it is 3 moves, facing west a
    # half turn first; facing north a quarter turn.
    neighbors = [(1,), (0, 2), (1, 3), (2,)]
    dist = rotation_dist(neighbors, [True] * 4, 4, 3, 1, 1, 2)
    assert dist[0, 0] == 3 and dist[0, 2] == 5 and dist[0, 3] == 4 and dist[3, 2] == 0
    slow = rotation_dist(neighbors, [True] * 4, 4, 3, 2, 2, 3)
    assert slow[0, 0] == 6 and slow[0, 2] == 9
    assert rotation_dist(neighbors, [True] * 4, 4, 9, 1, 1, 2).min() == UNREACHABLE_T


# ----------------------------------------------------------------------------- validator

def test_validate_headings_finds_each_fault():
    cols = 5
    ok_states = [(0, 0), (0, 0), (1, 1), (2, 2)]  # facing east: wait, then two moves east
    assert validate_headings({0: ok_states}, {0: [0, 0, 0, 0]}, cols,
                             turn_ticks={0: (1, 2)}) == []
    against = validate_headings({0: ok_states}, {0: [1, 1, 1, 1]}, cols,
                                turn_ticks={0: (1, 2)})
    assert against and against[0].kind == "against_heading"
    # a quarter turn (south -> east) in one tick, then moves east: fine with 1-tick turns,
    # too fast with 2-tick turns
    turn = [(0, 0), (0, 0), (1, 1)]
    assert validate_headings({0: turn}, {0: [1, 0, 0]}, cols, turn_ticks={0: (1, 2)}) == []
    # a move west, then a half turn in one tick (two needed)
    fast = validate_headings({0: [(1, 1), (0, 0), (0, 0)]}, {0: [2, 2, 0]}, cols,
                             turn_ticks={0: (1, 2)}, start_tick=5)
    assert fast and fast[0].kind == "turn" and fast[0].tick == 7
    assert validate_headings({0: [(1, 1), (0, 0), (0, 0), (0, 0)]}, {0: [2, 2, 2, 0]}, cols,
                             turn_ticks={0: (1, 2)}) == []
    # a half turn needs two ticks standing: a move then an immediate reversal is too fast
    rev = validate_headings({0: [(0, 0), (1, 1), (1, 1), (0, 0)]}, {0: [0, 0, 2, 2]}, cols,
                            turn_ticks={0: (1, 2)})
    assert rev and rev[0].kind == "turn"
    # a slow move that changes heading while under way
    slow = validate_headings({0: [(0, 0), (0, 1), (1, 1)]}, {0: [0, 0, 1]}, cols,
                             turn_ticks={0: (1, 2)})
    assert slow and slow[0].kind == "turn"
    bad = validate_headings({0: ok_states}, {0: [0, 0, 7, 0]}, cols, turn_ticks={})
    assert bad[0].kind == "heading"
    short = validate_headings({0: ok_states}, {0: [0, 0]}, cols, turn_ticks={})
    assert short[0].kind == "heading"


# ----------------------------------------------------------------------------- planners

@pytest.mark.parametrize("name", sorted(PLANNERS))
def test_conformance_with_rotations(name):
    assert "headings" in check_planner(name, rotations=True).passed


@st.composite
def floors(draw):
    """A small open floor with a few obstacles, 2-4 AGVs with random starts, goals and
    headings (all reachable: every free cell of the floor is connected)."""
    rows, cols = draw(st.integers(3, 5)), draw(st.integers(4, 6))
    cells = [(r, c) for r in range(rows) for c in range(cols)]
    blocked = set(draw(st.permutations(cells))[:draw(st.integers(0, 3))])
    blocked -= {(rows - 1, 0), (rows - 1, 1)}  # next to the shelf and station row
    free = [c for c in cells if c not in blocked]
    first = (rows - 1, 1)  # beside the station: the AGVs must reach it
    seen, todo = {first}, [first]
    while todo:  # keep the component of the cell beside the station
        r, c = todo.pop()
        for dr, dc in DIRS:
            n = (r + dr, c + dc)
            if n in free and n not in seen:
                seen.add(n)
                todo.append(n)
    free = sorted(seen)
    assume(len(free) >= 4)  # obstacles may cut that cell off from most of the floor
    n = draw(st.integers(2, min(4, len(free) // 2)))
    starts = draw(st.permutations(free))[:n]  # no rejection sampling: unique by design
    goals = draw(st.permutations(free))[:n]
    heads = draw(st.lists(st.integers(0, 3), min_size=n, max_size=n))
    rate = draw(st.sampled_from([2.5, 1.0]))
    grid = ["".join("#" if (r, c) in blocked or (r, c) not in seen else "."
                    for c in range(cols)) for r in range(rows)]
    return grid, starts, goals, heads, rate


def _plan_floor(name: str, grid, starts, goals, heads, rate, ticks: int = 40):
    """Plan the floor's agents with ``name`` (one call, or one per tick for step
    planners, committing the returned paths as the loop does); return every returned
    path and the turn ticks."""
    # a layout needs a shelf and a station: a row below the floor holds them
    cols = len(grid[0])
    world = World.build(scenario_from_dict({
        "seed": 0, "layout": {"grid": [*grid, "SR" + "#" * (cols - 2)]},
        "fleet": {"types": {"agv": {"max_turn_rate_radps": rate}},
                  "agvs": [{"type": "agv", "count": len(starts),
                            "starts": [list(s) for s in starts]}]},
        "planner": {"name": name, "rotations": True}}))
    planner = PLANNERS[name]()
    tt = agent_turn_ticks(world.agvs[0].spec, 1.0)
    res = world.reservations
    goal_nodes = [world.node(g) for g in goals]
    heading = {i: DIRS[h] for i, h in enumerate(heads)}
    out = []
    rng = np.random.default_rng(0)
    for t in range(ticks if planner.replans_all else 1):
        agents = []
        for a in world.agvs:
            pos = res.paths[a.id].state_at(t)
            h = res.paths[a.id].heading_at(t)
            if h is not None:
                heading[a.id] = DIRS[h]
            agents.append(AgentRequest(agv=a.id, start=pos[1], goal=goal_nodes[a.id],
                                       heading=heading[a.id], turn_ticks=tt,
                                       priority=(t + a.id / 10,)))
        result = planner.plan(PlanRequest(tick=t, agents=agents, graphs=world.graphs,
                                          reservations=res.copy(), rng=rng))
        for a in agents:
            if a.agv in result.paths:
                res.commit(result.paths[a.agv], 1)
                out.append((a, result.paths[a.agv]))
    return world, out, tt


@pytest.mark.parametrize("name", sorted(PLANNERS))
# 15 examples: each example plans a whole floor (per planner)
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                         HealthCheck.data_too_large])
@given(floor=floors())
def test_rotation_plans_never_move_against_the_heading(name, floor):
    grid, starts, goals, heads, rate = floor
    world, paths, tt = _plan_floor(name, grid, starts, goals, heads, rate)
    cols = world.layout.cols
    for agent, path in paths:
        assert path.headings is not None and len(path.headings) == len(path.states)
        assert path.headings[0] == DIR_OF[agent.heading]
        assert validate_headings({agent.agv: path.states}, {agent.agv: path.headings}, cols,
                                 turn_ticks={agent.agv: tt}, start_tick=path.start_tick) == []
        for i in range(1, len(path.states)):  # the property itself, independently
            (a, _), (b, _) = path.states[i - 1], path.states[i]
            if a != b:
                d = (b // cols - a // cols, b % cols - a % cols)
                assert DIRS[path.headings[i - 1]] == d
    # the committed plans of all agents together are conflict-free
    res = world.reservations
    end = max(p.end_tick for p in res.paths.values()) + 1
    states = {a: [p.state_at(t) for t in range(end)] for a, p in res.paths.items()}
    assert validate_states(states, world.layout.obstacles) == []


# ----------------------------------------------------------------------------- the loop

def _checked_run(path: str, planner: str, executor: str, seed: int, extra=()):
    sc = load_scenario(path, [("planner.rotations", True), ("planner.name", planner),
                              ("executor.name", executor), *extra])
    result = run_episode(sc, seed)
    w = result.world
    tt = {a.id: agent_turn_ticks(a.spec, sc.tick_s) for a in w.agvs}
    cols = w.layout.cols
    for p in result.planned:
        if tt[p["agv"]] is None:
            assert "headings" not in p
            continue
        assert validate_headings({p["agv"]: [tuple(s) for s in p["states"]]},
                                 {p["agv"]: p["headings"]}, cols, turn_ticks=tt,
                                 start_tick=p["tick"]) == []
    assert result.headings is not None
    assert set(result.headings) == {a for a, t in tt.items() if t is not None}
    if executor == "grid":
        assert validate_states(result.actual, w.layout.obstacles,
                               sizes={a.id: a.k for a in w.agvs},
                               ticks_per_move={a.id: a.ticks_per_move for a in w.agvs}) == []
        assert validate_headings({a: result.actual[a] for a in result.headings},
                                 result.headings, cols, turn_ticks=tt) == []
    return result


@pytest.mark.parametrize("layout", ["paper_homogeneous", "paper_heterogeneous"])
def test_closed_loop_grid_with_rotations(layout):
    result = _checked_run(f"layouts/{layout}.yaml", "astar", "grid", 3)
    assert result.metrics["success_rate"] == 1.0
    assert result.metrics["collisions"] == 0


@pytest.mark.parametrize("planner", ["cbs", "pibt", "lacam"])
def test_closed_loop_grid_other_planners(planner):
    result = _checked_run("layouts/paper_homogeneous.yaml", planner, "grid", 1,
                          [("orders.oneshot.count", 8)])
    assert result.metrics["success_rate"] == 1.0


def test_closed_loop_physics_with_rotations_short():
    result = _checked_run("layouts/paper_homogeneous.yaml", "astar", "physics", 3,
                          [("orders.oneshot.count", 5)])
    assert result.metrics["success_rate"] == 1.0
    assert result.metrics["collisions"] == 0


@pytest.mark.slow
@pytest.mark.parametrize("layout", ["paper_homogeneous", "paper_heterogeneous"])
@pytest.mark.parametrize("planner", ["astar", "pibt"])
def test_closed_loop_physics_with_rotations(layout, planner):
    result = _checked_run(f"layouts/{layout}.yaml", planner, "physics", 3)
    assert result.metrics["success_rate"] == 1.0
    assert result.metrics["collisions"] == 0


@pytest.mark.parametrize("planner", ["astar", "pibt"])
def test_rotations_are_deterministic(planner):
    sc = load_scenario("layouts/paper_heterogeneous.yaml",
                       [("planner.rotations", True), ("planner.name", planner),
                        ("orders.oneshot.count", 8)])
    a, b = run_episode(sc, 5), run_episode(sc, 5)
    assert a.planned == b.planned and a.actual == b.actual and a.headings == b.headings
    assert a.metrics["ticks"] == b.metrics["ticks"]


def test_omni_agvs_are_planned_as_before():
    sc = load_scenario("layouts/paper_heterogeneous.yaml",
                       [("planner.rotations", True), ("orders.oneshot.count", 4)])
    sim = Simulation(sc, 0)
    omni = [a.id for a in sim.world.agvs if a.spec.drive == "omni"]
    assert omni and not set(omni) & set(sim._rot)


def test_paths_json_has_headings(tmp_path):
    sc = load_scenario("layouts/paper_homogeneous.yaml",
                       [("planner.rotations", True), ("orders.oneshot.count", 3)])
    result = run_episode(sc, 0)
    write_outputs(result, tmp_path / "out")
    paths = json.loads((tmp_path / "out" / "paths.json").read_text())
    assert all(len(p["headings"]) == len(p["states"]) for p in paths["planned"])
    assert set(paths["headings"]) == {str(a.id) for a in result.world.agvs}
    assert all(len(h) == len(paths["actual"][a]) for a, h in paths["headings"].items())


def test_rotations_refuse_bodies_that_sweep_beyond_their_footprint():
    with pytest.raises(ScenarioError, match=r"fleet\.types\.agv\.body_m.*|rotation-aware"):
        scenario_from_dict({"layout": {"grid": ["P..R"]},
                            "fleet": {"types": {"agv": {"body_m": [0.8, 0.8]}},
                                      "agvs": [{"type": "agv", "count": 1}]},
                            "planner": {"name": "astar", "rotations": True}})
    # the same body is fine without rotations, and omnidirectional ones with them
    scenario_from_dict({"layout": {"grid": ["P..R"]},
                        "fleet": {"types": {"agv": {"body_m": [0.8, 0.8]}},
                                  "agvs": [{"type": "agv", "count": 1}]}})
    scenario_from_dict({"layout": {"grid": ["P..R"]},
                        "fleet": {"types": {"agv": {"body_m": [0.8, 0.8], "drive": "omni"}},
                                  "agvs": [{"type": "agv", "count": 1}]},
                        "planner": {"name": "astar", "rotations": True}})


@pytest.mark.slow
def test_planned_turns_give_physics_its_turn_time():
    """Open loop (the grid plan executed unchanged on physics): with rotations a planned
    turn holds the ticks the body needs, so almost no time is lost to turning and the
    executed / planned makespan drops."""
    from warerover_phys.gap.core import open_loop_gap

    sc = load_scenario("layouts/paper_homogeneous.yaml", [("orders.oneshot.count", 4)])
    rot = load_scenario("layouts/paper_homogeneous.yaml",
                        [("orders.oneshot.count", 4), ("planner.rotations", True)])
    plain, turned = open_loop_gap(sc, 3).report, open_loop_gap(rot, 3).report
    assert turned["deadlocks"] == 0 and turned["agv_contacts"] == 0
    assert turned["lost_turning_s_fleet_total"] < 0.25 * plain["lost_turning_s_fleet_total"]
    assert turned["makespan_ratio"] < plain["makespan_ratio"]
