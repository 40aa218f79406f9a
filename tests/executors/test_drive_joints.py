"""The drive joints of bodies that cannot reach an obstacle within a step stay out of the
pymunk space (issue 12's speed-up): the obstacle test is conservative, and a body that does
touch an obstacle moves exactly as it would with every joint in."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from warerover_phys import scenario_from_dict
from warerover_phys.executors.bodies import ObstacleReach
from warerover_phys.executors.physics import PhysicsExecutor
from warerover_phys.layout import Layout
from warerover_phys.planning import TimedPath
from warerover_phys.sim import apply_report, executor_setup, tick_view
from warerover_phys.world import World

OPEN = ["............",
        "....#.......",
        "P...........",
        "............",
        "..........RS"]


def overlaps_by_hand(layout: Layout, x: float, y: float, hx: float, hy: float) -> bool:
    """Whether the box overlaps an obstacle cell's square or reaches off the map, cell by
    cell (closed boxes: touching counts)."""
    m = layout.cell_m
    if x - hx < 0 or y - hy < 0 or x + hx >= layout.cols * m or y + hy >= layout.rows * m:
        return True
    for r, c in zip(*np.nonzero(layout.obstacles), strict=True):
        if x + hx >= c * m and x - hx <= (c + 1) * m and y + hy >= r * m \
                and y - hy <= (r + 1) * m:
            return True
    return False


def small_world(grid=OPEN) -> World:
    spec = {"max_speed_mps": 1.5, "max_accel_mps2": 1.0, "max_turn_rate_radps": 2.5,
            "mass_kg": 100.0}
    return World.build(scenario_from_dict({
        "layout": {"grid": grid},
        "fleet": {"types": {"t": spec}, "agvs": [{"type": "t", "count": 1}]},
        "executor": {"name": "physics"}}))


# 200 examples: one cheap geometric test per example, wide inputs
@settings(max_examples=200, deadline=None)
@given(x=st.floats(-0.5, 12.5), y=st.floats(-0.5, 5.5), hx=st.floats(0.01, 1.2),
       hy=st.floats(0.01, 1.2))
def test_the_reach_test_finds_every_obstacle_a_box_overlaps(x, y, hx, hy):
    layout = small_world().layout
    got = bool(ObstacleReach(layout).near(np.array([[x, y]]), np.array([[hx, hy]]))[0])
    # Never misses an overlap; a cell merely touched may count either way.
    if overlaps_by_hand(layout, x, y, hx + 1e-9, hy + 1e-9) != \
            overlaps_by_hand(layout, x, y, hx - 1e-9, hy - 1e-9):
        return
    assert got == overlaps_by_hand(layout, x, y, hx, hy)


def wall_run(joints: str) -> tuple[PhysicsExecutor, np.ndarray]:
    """An AGV put turned and off its cell centre, against the map's left wall, drives 8
    cells right and one down; its poses at every tick. ``joints``: ``gated`` (the
    executor's choice), ``all`` (every moving body's joints in) or ``none``."""
    w = small_world()
    nodes = [w.node((2, c)) for c in range(9)] + [w.node((3, 8))]
    w.reservations.commit(TimedPath(0, 0, tuple((n, n) for n in nodes)), w.agvs[0].k)
    ex = PhysicsExecutor(w.scenario.executor)
    ex.bind(executor_setup(w))
    if joints != "gated":
        keep = ~ex.fleet.parked if joints == "all" else np.zeros(ex.n, dtype=bool)
        ex._keep_joints = lambda pos, ang: ex.fleet.set_joints(
            ex.space, keep & ~ex.fleet.parked)
    for body in (ex.fleet.bodies[0], ex.fleet.ctrl[0]):
        body.position = (0.2, 2.2)
        body.angle = 0.5
    poses = []
    for _ in range(20):
        report = ex.step(tick_view(w))
        poses.append(report.poses.copy())
        apply_report(w, report)
        w.tick += 1
    return ex, np.array(poses)


def test_a_body_against_a_wall_moves_as_with_every_joint_in():
    gated, a = wall_run("gated")
    _, b = wall_run("all")
    _, c = wall_run("none")
    assert gated.summary()["static_contacts"] >= 1  # it did touch the wall ...
    assert np.abs(c - b).max() > 0.05  # ... where the joints matter
    np.testing.assert_array_equal(a, b)
    # At the end (parked) its joints are out of the space.
    assert not gated.fleet.jointed[0]
