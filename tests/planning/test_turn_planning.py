"""Planners reserve turns in place (issue 13, fault 2): AGVs whose swept disc leaves their
cell never turn next to each other at the same tick, never turn where the disc reaches a
wall, and keep other AGVs off the cells a turn sweeps. Checked by an independent geometric
test over the planned and executed states, and by the sweep validator."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys import scenario_from_dict
from warerover_phys.planning import (
    AgentRequest,
    AStarPlanner,
    CBSPlanner,
    LaCAMPlanner,
    PIBTPlanner,
    PlanRequest,
)
from warerover_phys.planning.base import TimedPath
from warerover_phys.planning.sweep import EAST, Sweep, no_turn_anchors, turn_fields, turn_sweeps
from warerover_phys.planning.sweep_checks import heading_after, sweep_conflicts
from warerover_phys.sim import run_episode
from warerover_phys.validate import validate_states
from warerover_phys.world import World

# A floor with a free ring around the work cells: a 0.8 m body may turn everywhere except
# in the ring (its disc would reach the map edge) and next to the obstacle.
RING = [".........",
        ".R..S..P.",
        "....#....",
        ".R..S..P.",
        ".......P.",
        ".R..S..P.",
        "........."]


def _scenario(planner: str, body: float = 0.8, count: int = 3, executor: str = "grid",
              orders: int = 4) -> dict:
    return {"seed": 0, "max_ticks": 300, "layout": {"grid": RING},
            "fleet": {"types": {"agv": {"body_m": [body, body]}},
                      "agvs": [{"type": "agv", "count": count}]},
            "orders": {"pattern": "oneshot", "oneshot": {"count": orders}},
            "tasks": {"pick_ticks": 1, "handover_ticks": 1, "place_ticks": 1},
            "planner": planner, "executor": executor}


def geometric_turn_faults(states: dict[int, list], rows: int, cols: int,
                          obstacles: np.ndarray, radius: float, cell: float = 1.0,
                          ) -> list[tuple]:
    """Independent of the planners' reservations: every turn in place (a move whose
    direction differs from the AGV's previous move; east at first) as a disc of
    ``radius`` at its anchor's centre. Faults: two discs at one tick that overlap, a disc
    that reaches the map edge or an obstacle cell."""
    turns: dict[int, list[tuple[int, float, float]]] = {}
    out = []
    for agv, s in states.items():
        for i, anchor in turn_sweeps(s, cols, EAST):
            r, c = divmod(anchor, cols)
            x, y = (c + 0.5) * cell, (r + 0.5) * cell
            turns.setdefault(i, []).append((agv, x, y))
            if min(x, y) < radius or x + radius > cols * cell or y + radius > rows * cell:
                out.append(("edge", i, agv))
            for rr in range(r - 1, r + 2):
                for cc in range(c - 1, c + 2):
                    if 0 <= rr < rows and 0 <= cc < cols and obstacles[rr, cc]:
                        dx = max(cc * cell - x, 0, x - (cc + 1) * cell)
                        dy = max(rr * cell - y, 0, y - (rr + 1) * cell)
                        if math.hypot(dx, dy) < radius - 1e-9:
                            out.append(("obstacle", i, agv))
    for i, group in turns.items():
        for x, (a, ax, ay) in enumerate(group):
            for b, bx, by in group[x + 1:]:
                if math.hypot(ax - bx, ay - by) < 2 * radius - 1e-9:
                    out.append(("turns touch", i, a, b))
    return out


@pytest.mark.parametrize("planner", ["astar", "cbs", "pibt", "lacam"])
def test_planners_never_turn_0_8_m_bodies_into_each_other_or_a_wall(planner):
    """Regression (fails on main before this fix: planners ignored headings, so two
    0.8 m AGVs turned side by side at one tick and turned next to the walls)."""
    sc = scenario_from_dict(_scenario(planner, count=4, orders=6))
    res = run_episode(sc)
    w = res.world
    rows, cols = w.layout.rows, w.layout.cols
    assert res.metrics["success_rate"] == 1.0
    assert validate_states(res.actual, w.layout.obstacles) == []
    radius = math.hypot(0.8, 0.8) / 2
    assert geometric_turn_faults(res.actual, rows, cols, w.layout.obstacles, radius) == []
    # The planned paths, one by one from their start, agree with the validator.
    fields = turn_fields(w.layout, [a.spec for a in w.agvs])
    assert fields and all(sw is not None and sw.locks for sw, _ in fields.values())
    found = sweep_conflicts(res.actual, rows, cols, {a.id: a.k for a in w.agvs},
                            {a: sw.cells for a, (sw, _) in fields.items()},
                            locks={a: sw.locks for a, (sw, _) in fields.items()},
                            no_turn={a: nt for a, (_, nt) in fields.items()})
    assert found == []


def test_default_bodies_plan_exactly_as_before():
    """0.7 m bodies on 1 m cells: no AGV is turn-aware, the requests carry no turn fields,
    and plans do not depend on headings."""
    w = World.build(scenario_from_dict(_scenario("astar", body=0.7)))
    assert turn_fields(w.layout, [a.spec for a in w.agvs]) == {}
    a = AgentRequest(0, 0, 5)
    assert a.sweep is None and a.no_turn == frozenset() and a.heading == EAST


# ----------------------------------------------------------------------------- planners

def _world(body: float, starts: list[tuple[int, int]], grid: list[str] | None = None):
    return World.build(scenario_from_dict({
        "layout": {"grid": grid or RING},
        "fleet": {"types": {"agv": {"body_m": [body, body]}},
                  "agvs": [{"type": "agv", "count": len(starts), "starts": starts}]}}))


def _requests(w: World, goals: dict[int, int], headings: dict[int, tuple],
              tick: int) -> list[AgentRequest]:
    fields = turn_fields(w.layout, [a.spec for a in w.agvs])
    out = []
    n = len(w.agvs)
    for agv in w.agvs:
        if agv.id not in goals:
            continue
        state = w.reservations.paths[agv.id].state_at(tick)
        sw, nt = fields.get(agv.id, (None, frozenset()))
        out.append(AgentRequest(agv.id, state[1], goals[agv.id], priority=(
            tick + (n - agv.id) / (n + 1),), heading=headings[agv.id], sweep=sw, no_turn=nt))
    return out


def _drive(planner, w: World, goals: dict[int, int], ticks: int = 40) -> dict[int, list]:
    """Plan as the loop does (every tick for step planners, once otherwise), committing
    the returned paths with each AGV's heading; return the planned states per tick."""
    fields = turn_fields(w.layout, [a.spec for a in w.agvs])
    res = w.reservations
    res.configure_turns({a: sw for a, (sw, _) in fields.items() if sw is not None},
                        w.layout.rows)
    headings = {a.id: EAST for a in w.agvs}
    cols = w.layout.cols
    rng = np.random.default_rng(0)
    history: dict[int, list] = {a.id: [] for a in w.agvs}
    t = 0
    for t in range(ticks if planner.replans_all else 1):
        agents = _requests(w, goals, headings, t)
        if planner.replans_all and all(
                res.paths[a.agv].state_at(t) == (a.goal, a.goal) for a in agents):
            break
        result = planner.plan(PlanRequest(t, agents, w.graphs, res.copy(), rng=rng,
                                          keep_clear=w.keep_clear()))
        for a in agents:
            if a.agv in result.paths:
                res.commit(result.paths[a.agv], 1, a.heading)
        for agv, p in res.paths.items():  # the state now, the heading one tick later
            history[agv].append(p.state_at(t))
            headings[agv] = heading_after(p.states[:t - p.start_tick + 2], cols,
                                          res.heading_at_start(agv))
    horizon = max(p.end_tick for p in res.paths.values()) + 2
    return {agv: history[agv] + [p.state_at(u) for u in range(t + 1, horizon)]
            for agv, p in res.paths.items()}


PLANNERS = {"astar": AStarPlanner, "cbs": CBSPlanner, "pibt": PIBTPlanner,
            "lacam": LaCAMPlanner}


def _check_plan(w: World, states: dict[int, list]) -> None:
    rows, cols = w.layout.rows, w.layout.cols
    assert validate_states(states, w.layout.obstacles) == []
    fields = turn_fields(w.layout, [a.spec for a in w.agvs])
    found = sweep_conflicts(states, rows, cols, {a.id: 1 for a in w.agvs},
                            {a: sw.cells for a, (sw, _) in fields.items() if sw},
                            locks={a: sw.locks for a, (sw, _) in fields.items() if sw},
                            no_turn={a: nt for a, (_, nt) in fields.items()})
    assert found == [], found[:3]


@pytest.mark.parametrize("name", sorted(PLANNERS))
def test_two_neighbours_that_both_go_north_do_not_turn_at_once(name):
    """AGVs side by side facing east, both sent north: one of them turns first."""
    w = _world(0.8, [(5, 3), (5, 4)])
    goals = {0: w.node((1, 3)), 1: w.node((1, 5))}
    states = _drive(PLANNERS[name](), w, goals)
    _check_plan(w, states)
    assert states[0][-1][0] == goals[0] and states[1][-1][0] == goals[1]


@pytest.mark.parametrize("name", sorted(PLANNERS))
def test_no_turn_at_the_wall_and_no_dead_end(name):
    """An AGV in the ring must not turn there: it drives straight out of the ring first.
    A goal in the ring it could only reach facing the wall (where it could never turn to
    leave) is not driven to."""
    w = _world(0.8, [(5, 0)])  # left ring cell, facing east
    goal = w.node((1, 3))
    states = _drive(PLANNERS[name](), w, {0: goal}, ticks=30)
    _check_plan(w, states)
    assert states[0][-1][0] == goal
    w = _world(0.8, [(3, 2)])
    states = _drive(PLANNERS[name](), w, {0: w.node((3, 0))}, ticks=10)
    _check_plan(w, states)
    assert all(s[1] != w.node((3, 0)) for s in states[0])


# 25 examples: each example plans with every planner, then validates
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_random_instances_pass_the_sweep_validator(data):
    """Random starts and goals for 2-4 AGVs with 0.8 m or 0.9 m bodies (the latter also
    sweep the neighbouring cells): every planner's plan passes the validators."""
    body = data.draw(st.sampled_from([0.8, 0.9]))
    w0 = _world(body, [(1, 1)])
    free = [n for n in range(w0.layout.rows * w0.layout.cols)
            if not w0.layout.obstacles.ravel()[n]]
    inner = sorted(set(free) - no_turn_anchors(w0.layout, _shape(body)))
    n = data.draw(st.integers(2, 4))
    starts = data.draw(st.lists(st.sampled_from(inner), min_size=n, max_size=n, unique=True))
    goals = data.draw(st.lists(st.sampled_from(inner), min_size=n, max_size=n, unique=True))
    name = data.draw(st.sampled_from(sorted(PLANNERS)))
    w = _world(body, [divmod(s, w0.layout.cols) for s in starts])
    states = _drive(PLANNERS[name](), w, dict(enumerate(goals)), ticks=40)
    _check_plan(w, states)


def _shape(body: float):
    from warerover_phys.planning.sweep import BodyShape
    return BodyShape(1, body, body, True)


# ----------------------------------------------------------------------------- pieces

def test_reservation_table_holds_committed_turns():
    from warerover_phys.planning import ReservationTable

    cols = 5
    res = ReservationTable(cols)
    res.configure_turns({0: Sweep(((-1, 0), (0, -1), (0, 1), (1, 0)),
                                  ((-1, 0), (0, -1), (0, 0), (0, 1), (1, 0)))}, 4)
    # AGV 0 at (2, 2) facing east goes north at tick 1: a turn at tick 1.
    res.commit(TimedPath(0, 0, ((12, 12), (12, 12), (7, 7))), 1, EAST)
    assert not res.free(13, 1, 1) and not res.free(13, 2, 1) and res.free(13, 3, 1)
    assert not res.locks_free((13,), 1, 1) and res.locks_free((13,), 2, 1)
    # Facing north already: no turn, nothing held beyond its cells.
    res.commit(TimedPath(0, 0, ((12, 12), (12, 12), (7, 7))), 1, (-1, 0))
    assert res.free(13, 1, 1) and res.locks_free((13,), 1, 1)
    copy = res.copy()
    copy.release(0)
    assert 0 in res.paths and 0 not in copy.paths


def test_sweep_validator_reports_turn_locks_and_walls():
    cols = 5
    locks = ((-1, 0), (0, -1), (0, 0), (0, 1), (1, 0))
    traj = {0: [(12, 12), (7, 7)], 1: [(13, 13), (8, 8)]}  # side by side, both north
    found = sweep_conflicts(traj, 4, cols, {}, {}, locks={0: locks, 1: locks})
    assert [c.kind for c in found] == ["turn_lock"] and "turn lock" in str(found[0])
    walls = sweep_conflicts({0: [(10, 10), (5, 5)]}, 4, cols, {}, {},
                            no_turn={0: frozenset({10})})
    assert [c.kind for c in walls] == ["turn_wall"] and "(2, 0)" in str(walls[0])


def test_check_accepts_0_8_m_bodies_where_they_can_turn(tmp_path):
    """`warerover check` rejects paper_homogeneous with 0.8 m bodies (its stations and
    parking touch the walls, where such a body cannot turn, so an AGV there could never
    leave) and accepts the same map with a free cell around it."""
    from typer.testing import CliRunner

    from warerover_phys.cli import app

    runner = CliRunner()
    bad = runner.invoke(app, ["check", "layouts/paper_homogeneous.yaml", "--set",
                              "fleet.types.agv.body_m=[0.8,0.8]"])
    text = " ".join(bad.output.split())
    assert bad.exit_code != 0 and "Traceback" not in bad.output
    assert "stations (3, 0), (4, 0), (5, 0) and 5 more" in text
    assert "parking spots (14, 6)" in text and "starts (14, 6), (14, 7), (14, 8) and 6 more (facing east)" in text
    assert "cannot turn" in text
    grid = tmp_path / "ring.yaml"
    grid.write_text("layout:\n  grid:\n" + "".join(f"    - '{r}'\n" for r in RING) +
                    "fleet:\n  types:\n    agv: {body_m: [0.8, 0.8]}\n"
                    "  agvs:\n    - {type: agv, count: 3}\n")
    ok = runner.invoke(app, ["check", str(grid)])
    assert ok.exit_code == 0, ok.output
