"""Parked AGVs with nothing left to do become static pymunk bodies (issue 12's speed-up):
the batch reads still find every AGV by id, a moving AGV that touches a static one still
makes a contact, and unparking gives the body back its mass and this step's command."""

from __future__ import annotations

import numpy as np
import pymunk
import pytest

from warerover_phys.executors.bodies import BodyIO, PhysicalFleet, unsolved_agv_contacts


def fleet_in_space(poses):
    space = pymunk.Space()
    fleet = PhysicalFleet.add_to(space, poses, [(0.7, 0.7)] * len(poses),
                                 [100.0] * len(poses), [1.0] * len(poses))
    return space, fleet, BodyIO(space, fleet)


def test_reads_follow_the_bodies_when_their_order_changes():
    poses = [(0.5 + 1.0 * i, 0.5 + 0.25 * i, 0.1 * i) for i in range(6)]
    space, fleet, io = fleet_in_space(poses)
    for i in (4, 1):
        fleet.park(space, i, poses[i][0], poses[i][1], poses[i][2], static=True)
    io.reorder()
    assert fleet.bodies[4].body_type == pymunk.Body.STATIC
    pos, ang, _, _ = io.read()
    np.testing.assert_allclose(pos, [p[:2] for p in poses])
    np.testing.assert_allclose(ang, [p[2] for p in poses])
    # Commands reach the right control bodies after the reorder.
    vel = np.array([[0.1 * i, -0.05 * i] for i in range(6)])
    io.write(vel, np.zeros(6))
    for i in range(6):
        assert tuple(fleet.ctrl[i].velocity) == pytest.approx(tuple(vel[i]))


def test_a_moving_agv_still_touches_a_static_one():
    space, fleet, io = fleet_in_space([(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)])
    seen = []
    unsolved_agv_contacts(space, fleet.agv_of_shape, lambda a, b, p: seen.append((a, b)))
    fleet.park(space, 0, 0.0, 0.0, 0.0, static=True)
    io.reorder()
    for _ in range(20):  # AGV 1 drives into the parked AGV 0 at 1 m/s
        io.read()
        io.write(np.array([[0.0, 0.0], [-1.0, 0.0]]), np.zeros(2),
                 bodies=np.array([False, True]))
        space.step(0.02)
    assert sorted(seen[0]) == [0, 1]
    assert tuple(fleet.bodies[0].position) == (0.0, 0.0)  # not pushed: contacts unsolved


def test_unparking_restores_mass_and_the_command():
    space, fleet, io = fleet_in_space([(0.0, 0.0, 0.0)])
    fleet.park(space, 0, 0.0, 0.0, 0.0, static=True)
    fleet.set_mass(0, 150.0)  # a shelf picked up while parked
    io.reorder()
    io.read()
    io.write(np.array([[0.3, 0.0]]), np.array([0.2]), bodies=np.array([True]))  # as the executor
    assert fleet.unpark(space, 0) is True
    io.reorder()
    body, ctrl = fleet.bodies[0], fleet.ctrl[0]
    assert body.body_type == pymunk.Body.DYNAMIC and ctrl.body_type == pymunk.Body.KINEMATIC
    assert body.mass == pytest.approx(150.0)
    assert body.moment == pytest.approx(pymunk.moment_for_box(100.0, (0.7, 0.7)) * 1.5)
    assert tuple(ctrl.velocity) == pytest.approx((0.3, 0.0))
    assert ctrl.angular_velocity == pytest.approx(0.2)
    space.step(0.1)
    assert body.position.x == pytest.approx(0.03)
    # A waiting AGV parks without becoming static (no reorder needed to unpark it).
    fleet.park(space, 0, 0.03, 0.0, 0.0, static=False)
    assert body.body_type == pymunk.Body.DYNAMIC and fleet.unpark(space, 0) is False
