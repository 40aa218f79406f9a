"""The ideal grid executor: blocked moves and collisions are told apart."""

from __future__ import annotations

from warerover_phys import scenario_from_dict
from warerover_phys.executors import GridExecutor
from warerover_phys.planning import TimedPath
from warerover_phys.sim import executor_setup, step_executor
from warerover_phys.validate import validate_states
from warerover_phys.world import World

GRID = ["P......R",
        "P.SS....",
        "P......."]


def world(n: int = 2) -> World:
    return World.build(scenario_from_dict({"layout": {"grid": GRID},
                                           "fleet": {"agvs": [{"count": n}]}}))


def force(w: World, agv: int, cells: list[tuple[int, int]]) -> None:
    """Commit a path without asking the planner (it may be invalid on purpose)."""
    nodes = [w.node(c) for c in cells]
    w.reservations.commit(TimedPath(agv, w.tick, tuple((n, n) for n in nodes)), 1)


def run(w: World, ticks: int) -> tuple[int, int, dict]:
    ex = GridExecutor()
    ex.bind(executor_setup(w))
    blocked = collisions = 0
    actual = {a.id: [a.pos] for a in w.agvs}
    for _ in range(ticks):
        report = step_executor(w, ex)
        w.tick += 1
        blocked += len(report.blocked)
        collisions += report.collisions
        for a in w.agvs:
            actual[a.id].append(a.pos)
    return blocked, collisions, actual


def test_valid_plans_execute_exactly():
    w = world()
    force(w, 0, [(0, 0), (0, 1), (0, 2), (0, 3)])
    force(w, 1, [(1, 0), (1, 1), (0, 1), (0, 2)])  # follows AGV 0 one cell behind
    blocked, collisions, actual = run(w, 4)
    assert (blocked, collisions) == (0, 0)
    assert w.cell(w.agvs[0].node) == (0, 3) and w.cell(w.agvs[1].node) == (0, 2)
    assert validate_states(actual, w.layout.obstacles) == []


def test_moving_into_a_standing_agv_is_a_blocked_move_not_a_collision():
    w = world()
    force(w, 0, [(0, 0), (1, 0), (1, 1)])  # (1, 0) holds AGV 1, which stays
    force(w, 1, [(1, 0)])
    blocked, collisions, actual = run(w, 3)
    assert blocked == 3 and collisions == 0
    assert w.agvs[0].delay == 3 and w.cell(w.agvs[0].node) == (0, 0)
    assert validate_states(actual, w.layout.obstacles) == []


def test_a_chain_behind_a_blocked_agv_is_blocked_too():
    w = world(3)
    force(w, 2, [(2, 0), (2, 1)])
    w.reservations.commit(TimedPath(2, 0, ((w.node((2, 0)), w.node((2, 0))),)), 1)  # stays
    force(w, 1, [(1, 0), (2, 0)])  # into AGV 2, which stays
    force(w, 0, [(0, 0), (1, 0)])  # into AGV 1, which is blocked
    blocked, collisions, _ = run(w, 1)
    assert (blocked, collisions) == (2, 0)


def test_invalid_plans_show_up_as_collisions():
    w = world()
    force(w, 0, [(0, 0), (0, 0), (0, 1)])
    force(w, 1, [(1, 0), (1, 1), (0, 1)])  # both enter the free cell (0, 1) at tick 2
    _, collisions, actual = run(w, 2)
    assert collisions >= 1
    assert any(c.kind == "vertex" for c in validate_states(actual, w.layout.obstacles))
    # A swap: both move through each other.
    w = world()
    force(w, 0, [(0, 0), (1, 0)])
    force(w, 1, [(1, 0), (0, 0)])
    _, collisions, actual = run(w, 1)
    assert collisions == 1
    assert [c.kind for c in validate_states(actual, w.layout.obstacles)] == ["swap"]
