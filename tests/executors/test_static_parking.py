"""Parked AGVs with nothing left to do leave the pymunk space, static stand-ins of their
shapes in their place (issue 12's speed-up): the batch reads still find every AGV by id, a
moving AGV that touches a parked one still makes a contact, and unparking puts the body
back with its mass and this step's command."""

from __future__ import annotations

import numpy as np
import pymunk
import pytest
from hypothesis import given
from hypothesis import strategies as st

from warerover_phys.executors.bodies import BodyIO, PhysicalFleet, unsolved_agv_contacts


def fleet_in_space(poses):
    space = pymunk.Space()
    fleet = PhysicalFleet.add_to(space, poses, [(0.7, 0.7)] * len(poses),
                                 [100.0] * len(poses), [1.0] * len(poses))
    return space, fleet, BodyIO(space, fleet)


def test_reads_follow_the_bodies_when_they_leave_the_space():
    poses = [(0.5 + 1.0 * i, 0.5 + 0.25 * i, 0.1 * i) for i in range(6)]
    space, fleet, io = fleet_in_space(poses)
    for i in (4, 1):
        fleet.park(space, i, poses[i][0], poses[i][1], poses[i][2], static=True)
    io.reorder()
    assert fleet.bodies[4] not in space.bodies and fleet.ctrl[4] not in space.bodies
    assert len(space.bodies) == 8 and fleet.n_parked == 2
    pos, ang, vel, w = io.read()
    np.testing.assert_allclose(pos, [p[:2] for p in poses])
    np.testing.assert_allclose(ang, [p[2] for p in poses])
    assert not vel.any() and not w.any()
    # Commands reach the right control bodies; those out of the space take none.
    vel = np.array([[0.1 * i, -0.05 * i] for i in range(1, 7)])
    io.write(vel, np.zeros(6))
    for i in range(6):
        want = (0.0, 0.0) if i in (1, 4) else tuple(vel[i])
        assert tuple(fleet.ctrl[i].velocity) == pytest.approx(want)


def first_contact(static: bool) -> int:
    """The step at which AGV 1, driving into parked AGV 0, first touches it."""
    space, fleet, io = fleet_in_space([(0.0, 0.0, 0.3), (1.0, 0.0, 0.0)])
    seen = []
    unsolved_agv_contacts(space, fleet.agv_of_shape, lambda a, b, p: seen.append((a, b)))
    fleet.park(space, 0, 0.0, 0.0, 0.3, static=static)
    io.reorder()
    first = None
    for k in range(30):  # AGV 1 drives into the parked AGV 0 at 1 m/s
        io.read()
        io.write(np.array([[0.0, 0.0], [-1.0, 0.0]]), np.zeros(2),
                 bodies=np.array([False, True]))
        space.step(0.02)
        if seen and first is None:
            first = k
    assert sorted(seen[0]) == [0, 1]
    assert tuple(fleet.bodies[0].position) == (0.0, 0.0)  # not pushed: contacts unsolved
    return first


def test_a_moving_agv_still_touches_a_parked_one():
    # Met at the same step whether the parked body stays in the space or not.
    assert first_contact(True) == first_contact(False) is not None


def test_unparking_restores_mass_and_the_command():
    space, fleet, io = fleet_in_space([(0.0, 0.0, 0.0)])
    fleet.park(space, 0, 0.0, 0.0, 0.0, static=True)
    fleet.set_mass(0, 150.0)  # a shelf picked up while parked
    io.reorder()
    io.read()
    assert fleet.unpark(space, 0, (0.3, 0.0), 0.2) is True
    io.reorder()
    body, ctrl = fleet.bodies[0], fleet.ctrl[0]
    assert body in space.bodies and ctrl in space.bodies and not fleet.stand_ins
    assert set(fleet.agv_of_shape.values()) == {0} and len(fleet.agv_of_shape) == 1
    assert body.mass == pytest.approx(150.0)
    assert body.moment == pytest.approx(pymunk.moment_for_box(100.0, (0.7, 0.7)) * 1.5)
    assert tuple(ctrl.velocity) == pytest.approx((0.3, 0.0))
    assert ctrl.angular_velocity == pytest.approx(0.2)
    space.step(0.1)
    assert body.position.x == pytest.approx(0.03)
    # A waiting AGV parks in the space (no reorder needed to unpark it).
    fleet.park(space, 0, 0.03, 0.0, 0.0, static=False)
    assert body in space.bodies and fleet.unpark(space, 0, (0.0, 0.0), 0.0) is False
    assert fleet.n_parked == 0


@given(st.lists(st.tuples(st.integers(0, 7), st.booleans()), min_size=1, max_size=30))
def test_batch_rows_follow_any_sequence_of_leaving_and_coming_back(moves):
    """Bodies leave the space (parked, static) and come back (unparked) in any order, with
    other bodies in the space too: after each re-read of the body order, every AGV's
    read is its own body's pose and velocity, and every command reaches its own control
    body (and its body, where asked)."""
    poses = [(0.5 + 1.5 * i, 0.5 + 0.25 * i, 0.1 * i) for i in range(8)]
    space, fleet, io = fleet_in_space(poses)
    space.add(pymunk.Body(1.0, 1.0))  # a body that is no AGV's
    rng = np.random.default_rng(len(moves))
    for i, leave in moves:
        if leave and not fleet.static[i]:
            if not fleet.parked[i]:
                b = fleet.bodies[i]
                fleet.park(space, i, b.position.x, b.position.y, b.angle, static=True)
            else:
                b = fleet.bodies[i]
                fleet.leave(space, i, b.position.x, b.position.y, b.angle)
        elif not leave and fleet.parked[i]:
            fleet.unpark(space, i, tuple(rng.normal(size=2)), float(rng.normal()))
        io.reorder()
        pos, ang, vel, w = io.read()
        for j, b in enumerate(fleet.bodies):
            assert tuple(pos[j]) == tuple(b.position) and ang[j] == b.angle
            assert tuple(vel[j]) == tuple(b.velocity) and w[j] == b.angular_velocity
        cmd = rng.normal(size=(8, 2))
        cw = rng.normal(size=8)
        mask = rng.random(8) < 0.5
        io.write(cmd, cw, bodies=mask)
        for j in range(8):
            if fleet.static[j]:
                continue
            assert tuple(fleet.ctrl[j].velocity) == tuple(cmd[j])
            assert fleet.ctrl[j].angular_velocity == cw[j]
            if mask[j]:
                assert tuple(fleet.bodies[j].velocity) == tuple(cmd[j])
