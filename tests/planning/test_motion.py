"""The motion model: against the analytic profile (within 1%), against the executor's own
reference law integrated step by step, and against measured physics runs and turns."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from warerover_phys import scenario_from_dict
from warerover_phys.config import AgvTypeSpec
from warerover_phys.executors.control import stop_speed
from warerover_phys.executors.physics import PhysicsExecutor
from warerover_phys.planning import TimedPath
from warerover_phys.planning.motion import MotionModel, quarter_turns
from warerover_phys.sim import executor_setup, step_executor
from warerover_phys.world import World


def analytic(d: float, v: float, a: float) -> float:
    """Rest-to-rest time of ``d`` metres: trapezoid, or triangle below ``v^2 / a``."""
    if d >= v * v / a:
        return d / v + v / a
    return 2 * math.sqrt(d / a)


def reference_run_s(d: float, v: float, a: float, dt: float = 0.001) -> float:
    """The physics executor's reference point (``control.steer``: ``v = min(v_max,
    stop_speed, v + a dt)``, trapezoidal integration) stepped until it stops on ``d``."""
    s = speed = t = 0.0
    one = np.array([a])
    while s < d - 1e-9:
        nv = min(v, float(stop_speed(np.array([d - s]), one, dt, np.array([speed]))[0]),
                 speed + a * dt)
        s = min(s + 0.5 * (speed + nv) * dt, d)
        speed = nv
        t += dt
        if t > 1e4:
            raise AssertionError("reference never stopped")
    return t


speeds = st.floats(0.2, 3.0)
accels = st.floats(0.2, 3.0)
cells = st.integers(1, 30)
cell_m = st.sampled_from([0.5, 1.0, 1.25])


@settings(max_examples=60, deadline=None)
@given(speeds, accels, cells, cell_m)
def test_run_time_is_the_analytic_profile_within_one_percent(v, a, k, c):
    m = MotionModel(v, a, 2.0, cell_m=c)
    want = analytic(k * c, v, a)
    assert abs(m.run_s(k) - want) <= 0.01 * want
    assert m.reach_s(k, k) == pytest.approx(m.run_s(k))
    assert m.reach_s(0, k) == 0.0


@settings(max_examples=60, deadline=None)
@given(speeds, accels, st.integers(2, 30))
def test_a_run_is_cheaper_than_separate_moves_and_reach_is_monotone(v, a, k):
    m = MotionModel(v, a, 2.0)
    assert m.run_s(k) < k * m.run_s(1)
    assert m.run_s(k) >= m.pass_s(k)
    times = [m.reach_s(j, k) for j in range(k + 1)]
    assert all(b > x for x, b in zip(times, times[1:], strict=False))
    # symmetric: braking mirrors accelerating
    for j in range(k + 1):
        assert times[j] + times[k - j] == pytest.approx(m.run_s(k), abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(speeds, accels, cells, st.floats(0.0, 1.0))
def test_state_at_inverts_at_s(v, a, k, share):
    m = MotionModel(v, a, 2.0)
    d = float(k)
    x = share * d
    t = m.at_s(x, d)
    pos, speed = m.state_at(t, d)
    assert pos == pytest.approx(x, abs=1e-7)
    assert 0 <= speed <= v + 1e-9
    assert m.state_at(m.distance_s(d) + 1, d) == (d, 0.0)


@pytest.mark.parametrize(("v", "a", "k"), [(1.5, 1.0, 1), (1.5, 1.0, 2), (1.5, 1.0, 10),
                                           (0.75, 0.5, 1), (0.75, 0.5, 6), (2.0, 0.4, 3)])
def test_run_time_matches_the_executors_reference_law(v, a, k):
    m = MotionModel(v, a, 2.0)
    ref = reference_run_s(k * 1.0, v, a)
    assert abs(m.run_s(k) - ref) <= 0.01 * ref, (m.run_s(k), ref)


def test_turns_and_omni():
    m = MotionModel(1.5, 1.0, 2.5)
    assert m.turn_s(1) == pytest.approx(math.pi / 2 / 2.5)
    assert m.turn_s(2) == pytest.approx(2 * m.turn_s(1))
    assert m.turn_s(3) == m.turn_s(1) and m.turn_s(0) == 0.0
    omni = MotionModel(1.5, 1.0, 2.5, omni=True)
    assert omni.turn_s(1) == omni.turn_s(2) == 0.0
    assert quarter_turns((0, 1), (0, 1)) == 0
    assert quarter_turns((0, 1), (-1, 0)) == 1
    assert quarter_turns((1, 0), (-1, 0)) == 2


def test_of_uses_the_loaded_limit_only_with_payloads():
    spec = AgvTypeSpec(mass_kg=100, payload_kg=100, max_accel_mps2=1.0, drive="omni",
                       footprint=2, body_m=(1.6, 1.6))
    assert MotionModel.of(spec, 1.0).max_accel_mps2 == 1.0
    assert MotionModel.of(spec, 1.0, loaded=True).max_accel_mps2 == 1.0
    loaded = MotionModel.of(spec, 1.0, loaded=True, payload=True)
    assert loaded.max_accel_mps2 == pytest.approx(0.5)
    assert loaded.omni and loaded.footprint == 2
    assert loaded.run_s(4) > MotionModel.of(spec, 1.0).run_s(4)


def test_ticks_rounds_up_with_a_tolerance():
    assert MotionModel.ticks(0.0, 1.0) == 0
    assert MotionModel.ticks(1.0, 1.0) == 1
    assert MotionModel.ticks(1.0000000001, 1.0) == 1
    assert MotionModel.ticks(2.01, 1.0) == 3
    assert MotionModel.ticks(0.2, 0.5) == 1


def test_bad_limits_are_refused():
    with pytest.raises(ValueError, match="max_accel_mps2"):
        MotionModel(1.0, 0.0, 1.0)


# ----------------------------------------------------------------------------- physics

GRID = ["P...........R", "P............", "P............", "P.SS.........", "P............"]


def physics_time(cells: list[tuple[int, int]], **agv) -> tuple[float, MotionModel]:
    """Simulated seconds the physics executor needs for one AGV's path ``cells`` (it starts
    facing east, standing), and the model of its type."""
    spec = {"max_speed_mps": 1.5, "max_accel_mps2": 1.0, "max_turn_rate_radps": 2.5, **agv}
    w = World.build(scenario_from_dict({
        "layout": {"grid": GRID},
        "fleet": {"types": {"t": spec}, "agvs": [{"type": "t", "count": 1,
                                                   "starts": [list(cells[0])]}]},
        "executor": {"name": "physics"}}))
    nodes = [w.node(c) for c in cells]
    w.reservations.commit(TimedPath(0, 0, tuple((n, n) for n in nodes)), w.agvs[0].k)
    ex = PhysicsExecutor(w.scenario.executor)
    ex.bind(executor_setup(w))
    for _ in range(80):
        step_executor(w, ex)
        w.tick += 1
        if ex.adg.done(0) and ex.mode[0] == 0:
            return float(ex.last_finish[0]), MotionModel.of(AgvTypeSpec(**spec), 1.0)
    raise AssertionError("the AGV did not finish")


@pytest.mark.parametrize(("v", "a", "k"), [(1.5, 1.0, 1), (1.5, 1.0, 2), (1.5, 1.0, 5),
                                           (0.75, 0.5, 3)])
def test_physics_runs_take_the_model_time(v, a, k):
    """Measured: within 0.5% (the body arrives within a physics step of the reference)."""
    t, m = physics_time([(1, c) for c in range(1, 2 + k)], max_speed_mps=v, max_accel_mps2=a)
    assert -1e-6 <= t - m.run_s(k) <= 0.005 * m.run_s(k), (t, m.run_s(k))


@pytest.mark.parametrize(("w_max", "cells", "quarters"), [
    (2.5, [(1, 1), (2, 1)], 1), (2.5, [(1, 2), (1, 1)], 2), (1.2, [(1, 1), (2, 1)], 1)])
def test_physics_turns_take_the_model_time(w_max, cells, quarters):
    """Measured: a turn then one move; the turn within +2% (exact since issue 13: to 1e-6 s)."""
    t, m = physics_time(cells, max_turn_rate_radps=w_max)
    turn = t - m.run_s(1)
    assert -1e-6 <= turn - m.turn_s(quarters) <= 0.02 * m.turn_s(quarters), (turn, m.turn_s(quarters))


def test_omni_physics_does_not_turn():
    t, m = physics_time([(1, 1), (2, 1), (2, 2)], drive="omni")
    assert t == pytest.approx(2 * m.run_s(1), rel=0.005)
