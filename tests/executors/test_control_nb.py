"""The compiled control law (:mod:`warerover_phys.executors.control_nb`) against the numpy
reference (:mod:`warerover_phys.executors.control`): the same numbers bit for bit (signed
zeros included) on random rows, and the same executed episode."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys import scenario_from_dict
from warerover_phys.executors import control, control_nb
from warerover_phys.executors.fleet_state import DRIVE, HOLD, TURN, FleetState
from warerover_phys.sim import Simulation

DT = 0.05


def same(a, b) -> bool:
    """Bit for bit (float arrays compared as their bytes: -0.0 is not 0.0)."""
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def test_constants_match_the_reference():
    assert control_nb.EVENT_EPS_S == control.EVENT_EPS_S
    assert control_nb.HOLD_SPEED == control.HOLD_SPEED


def test_tie_helpers_pick_numpys_operand():
    """numpy's maximum / minimum / clip (with an array bound, as in the control law) / sign
    on ties of signed zeros, and on nan, as the kernels copy them."""
    z, m, nan = 0.0, -0.0, float("nan")
    cases = [(z, m), (m, z), (1.0, 2.0), (2.0, 1.0), (nan, 1.0), (1.0, nan)]
    for x, y in cases:
        ax, ay = np.array([x] * 3), np.array([y] * 3)
        assert same(np.maximum(ax, ay)[0], control_nb._mx(x, y))
        assert same(np.maximum(ax, y)[0], control_nb._mx(x, y))
        assert same(np.minimum(ax, ay)[0], control_nb._mn(x, y))
        assert same(np.sign(ax)[0], control_nb._sign(x))
        if y != y:
            continue
        five = np.full(3, 5.0)
        assert same(np.clip(ax, y, five)[0], control_nb._clip(x, y, 5.0))
        assert same(np.clip(ax, ay, five)[0], control_nb._clip(x, y, 5.0))
        assert same(np.clip(ax, -five, ay)[0], control_nb._clip(x, -5.0, y))
        assert same(np.clip(ax, -5.0, ay)[0], control_nb._clip(x, -5.0, y))


def fleet(n: int, vmax, amax, wmax) -> FleetState:
    return FleetState(cols=10, cell_m=1.0, tick_s=1.0, dt=DT, k=np.ones(n, dtype=np.int64),
                      vmax=np.asarray(vmax, dtype=float), amax=np.asarray(amax, dtype=float),
                      wmax=np.asarray(wmax, dtype=float), omni=np.zeros(n, dtype=bool),
                      origin=np.zeros((n, 2)))


_SPEEDS = st.one_of(st.floats(0.0, 2.5), st.sampled_from([0.0, -0.0, 1.0, 1.5, 2.0, 5e-324]))
_DIST = st.one_of(st.floats(0.0, 12.0), st.sampled_from([0.0, 1.0, 2.0, 1e-13, 5e-324]))


@st.composite
def reference_rows(draw):
    """Random AGVs: turning (near the end of the turn or not), driving (accelerating,
    cruising, on or above the braking curve, braking, at or past the stop point, an action
    that ends exactly at, just before or just after the step's end) or standing."""
    n = draw(st.integers(1, 12))
    vmax = [draw(st.sampled_from([0.75, 1.0, 1.5, 2.0])) for _ in range(n)]
    amax = [draw(st.sampled_from([0.5, 1.0, 2.0])) for _ in range(n)]
    wmax = [draw(st.sampled_from([1.0, 2.5])) for _ in range(n)]
    f = fleet(n, vmax, amax, wmax)
    h = np.empty(n)
    braking = np.zeros(n, dtype=bool)
    for i in range(n):
        mode = draw(st.sampled_from([HOLD, TURN, DRIVE, DRIVE, DRIVE]))
        f.mode[i] = mode
        # A physics step, part of one, or a long one (it crosses the profile's phases).
        h[i] = draw(st.one_of(st.just(DT), st.floats(0.0, DT), st.floats(0.0, 3.0)))
        braking[i] = draw(st.booleans())
        if mode == TURN:
            f.ang_ref[i] = draw(st.floats(-4.0, 4.0))
            near = draw(st.sampled_from([None, 0.0, 1e-10, -1e-10, 2e-9]))
            if near is None:
                f.heading[i] = f.ang_ref[i] + draw(st.floats(-math.pi, math.pi))
            else:  # the turn ends about at the step's end
                sign = draw(st.sampled_from([1.0, -1.0]))
                f.heading[i] = f.ang_ref[i] + sign * (wmax[i] * h[i] + near)
        elif mode == DRIVE:
            s0 = draw(st.one_of(st.just(0.0), st.floats(0.0, 5.0)))
            f.s_ref[i] = s0
            f.speed[i] = draw(_SPEEDS)
            f.stop_s[i] = s0 + draw(_DIST)
            if draw(st.booleans()):  # on the braking curve
                d = f.stop_s[i] - s0
                f.speed[i] = math.sqrt(2 * amax[i] * d)
            end = draw(st.sampled_from(["stop", "before", "near"]))
            if end == "stop":
                f.cur_end[i] = f.stop_s[i]
            elif end == "before":
                f.cur_end[i] = s0 + draw(st.floats(0.0, 1.0)) * (f.stop_s[i] - s0)
            else:  # the action ends about where the reference is at the step's end
                g = fleet(1, vmax[i:i + 1], amax[i:i + 1], wmax[i:i + 1])
                g.mode[0], g.s_ref[0], g.speed[0] = DRIVE, s0, f.speed[i]
                g.stop_s[0] = g.cur_end[0] = f.stop_s[i]
                ph = control._phases(g.stop_s - s0, g.speed, g.vmax, g.amax, braking[i:i + 1])
                s, _ = control._eval(ph, g.amax, h[i:i + 1])
                f.cur_end[i] = min(s0 + float(s[0]) + draw(st.sampled_from(
                    [0.0, 1e-12, -1e-12, 1e-10, -1e-10])), f.stop_s[i])
    return f, h, braking


def batch(rng: np.random.Generator, n: int) -> tuple[FleetState, np.ndarray, np.ndarray]:
    """``n`` random rows at once (the same kinds as :func:`reference_rows`, more of them)."""
    f = fleet(n, rng.choice([0.75, 1.0, 1.5, 2.0], n), rng.choice([0.5, 1.0, 2.0], n),
              rng.choice([1.0, 2.5], n))
    f.mode[:] = rng.choice([HOLD, TURN, DRIVE, DRIVE], n)
    h = np.where(rng.random(n) < 0.3, DT, rng.uniform(0.0, 3.0, n))
    braking = rng.random(n) < 0.3
    f.ang_ref[:] = rng.uniform(-4, 4, n)
    f.heading[:] = f.ang_ref + np.where(rng.random(n) < 0.5, rng.uniform(-4, 4, n),
                                        f.wmax * h * rng.choice([1.0, -1.0], n))
    f.s_ref[:] = np.where(rng.random(n) < 0.3, 0.0, rng.uniform(0, 5, n))
    f.stop_s[:] = f.s_ref + np.where(rng.random(n) < 0.1, 0.0, rng.uniform(0, 12, n))
    f.speed[:] = np.where(rng.random(n) < 0.3, np.sqrt(2 * f.amax * (f.stop_s - f.s_ref)),
                          rng.uniform(0, 2.5, n))
    f.cur_end[:] = np.where(rng.random(n) < 0.4, f.stop_s,
                            f.s_ref + rng.random(n) * (f.stop_s - f.s_ref))
    return f, h, braking


def test_run_references_compiled_on_many_random_rows():
    rng = np.random.default_rng(12)
    for _ in range(5):
        f, h, braking = batch(rng, 20_000)
        idx = np.flatnonzero(rng.random(f.n) < 0.9)
        a, b = _copy(f), _copy(f)
        used_a, ev_a = control.run_references(a, idx, h[idx], braking[idx])
        used_b, ev_b = control.run_references_compiled(b, idx, h[idx], braking[idx])
        assert ev_a.any() and not ev_a.all()
        assert same(used_a, used_b) and same(ev_a, ev_b)
        for name in ("ang_ref", "s_ref", "speed"):
            assert same(getattr(a, name), getattr(b, name)), name


def _copy(f: FleetState) -> FleetState:
    g = fleet(f.n, f.vmax, f.amax, f.wmax)
    for name in ("mode", "heading", "ang_ref", "cur_end", "stop_s", "speed", "s_ref",
                 "origin", "direction", "hold_xy"):
        setattr(g, name, getattr(f, name).copy())
    return g


# 200 examples: a kernel against its reference, cheap, wide inputs
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(reference_rows(), st.data())
def test_run_references_compiled_is_the_numpy_reference(rows, data):
    f, h, braking = rows
    idx = np.array(sorted(data.draw(st.sets(st.integers(0, f.n - 1), min_size=1))),
                   dtype=np.int64)
    a, b = _copy(f), _copy(f)
    with np.errstate(over="ignore"):  # subnormal speeds: a division overflows to inf
        used_a, ev_a = control.run_references(a, idx, h[idx], braking[idx])
    used_b, ev_b = control.run_references_compiled(b, idx, h[idx], braking[idx])
    assert same(used_a, used_b) and same(ev_a, ev_b)
    for name in ("ang_ref", "s_ref", "speed"):
        assert same(getattr(a, name), getattr(b, name)), name


def _vec(data, n: int, elements) -> np.ndarray:
    return np.array(data.draw(st.lists(elements, min_size=n, max_size=n)), dtype=float)


def steer_inputs(f: FleetState, data) -> tuple:
    """Run origins and directions, hold points, and bodies on, near or far from their
    references, moving slowly or fast, at any angle; some rows no-slip."""
    n = f.n
    fl = st.floats(-3.0, 3.0)
    f.origin = _vec(data, 2 * n, fl).reshape(n, 2)
    f.hold_xy = f.origin + _vec(data, 2 * n, fl).reshape(n, 2)
    f.direction = np.array(data.draw(st.lists(st.sampled_from(
        [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)]), min_size=n, max_size=n)))
    ref0 = f.ref_xy()
    off = st.one_of(st.just(0.0), st.floats(-1e-3, 1e-3), st.floats(-2.0, 2.0))
    pos = ref0 + _vec(data, 2 * n, off).reshape(n, 2)
    ang = _vec(data, n, st.floats(-7.0, 7.0))
    raw = np.zeros((n, 3))
    raw[:, 0:2] = _vec(data, 2 * n, st.one_of(st.just(0.0), st.floats(-2.5, 2.5))).reshape(n, 2)
    f.no_slip = np.array(data.draw(st.lists(st.booleans(), min_size=n, max_size=n))) \
        if data.draw(st.booleans()) else None
    return pos, ang, raw[:, 0:2], ref0  # a strided velocity view, as BodyIO.read gives it


@settings(max_examples=75, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(reference_rows(), st.data())
def test_steer_compiled_is_the_numpy_reference(rows, data):
    f = rows[0]
    pos, ang, v_now, ref0 = steer_inputs(f, data)
    cmd_a, w_a = control.steer_numpy(f, pos, ang, v_now, ref0)
    cmd_b, w_b = control.steer_compiled(f, pos, ang, v_now, ref0)
    assert same(cmd_a, cmd_b) and same(w_a, w_b)


def test_steer_compiled_on_many_random_rows():
    rng = np.random.default_rng(13)
    for no_slip in (False, True):
        f, _, _ = batch(rng, 20_000)
        n = f.n
        f.origin = rng.uniform(-3, 3, (n, 2))
        f.hold_xy = f.origin + rng.uniform(-3, 3, (n, 2))
        f.direction = np.array([(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)])[
            rng.integers(0, 4, n)]
        f.no_slip = rng.random(n) < 0.5 if no_slip else None
        ref0 = f.ref_xy()
        scale = rng.choice([0.0, 1e-3, 0.05, 2.0], (n, 1))
        pos = ref0 + scale * rng.uniform(-1, 1, (n, 2))
        ang = rng.uniform(-7, 7, n)
        v_now = rng.choice([0.0, 0.1, 2.5], (n, 1)) * rng.uniform(-1, 1, (n, 2))
        cmd_a, w_a = control.steer_numpy(f, pos, ang, v_now, ref0)
        cmd_b, w_b = control.steer_compiled(f, pos, ang, v_now, ref0)
        assert same(cmd_a, cmd_b) and same(w_a, w_b)


def _episode(no_slip: bool) -> Simulation:
    grid = ["P.....R.",
            "P.S.S...",
            "P.......",
            "P...#..R"]
    sc = scenario_from_dict({
        "max_ticks": 90,
        "layout": {"grid": grid},
        "fleet": {"types": {"fast": {"max_speed_mps": 1.5, "drive": "diff"},
                            "slow": {"max_speed_mps": 0.75, "max_accel_mps2": 0.5,
                                     "drive": "omni"}},
                  "agvs": [{"type": "fast", "count": 3}, {"type": "slow", "count": 1}]},
        "orders": {"pattern": "oneshot", "oneshot": {"count": 5}},
        "executor": {"name": "physics", "dt_s": 0.05, "no_slip": no_slip,
                     "delays": {"model": "bernoulli", "prob": 0.05, "max_ticks": 6},
                     "speed_scale": [0.8, 1.0]},
        "seed": 3,
    })
    sim = Simulation(sc, 3)
    sim.result = sim.run()
    return sim


@pytest.mark.parametrize("no_slip", [False, True])
def test_an_episode_is_the_same_with_either_control_law(monkeypatch, no_slip):
    """Turns, runs, delays, hand-overs: the compiled law executes exactly what the numpy
    reference does (every recorded pose, every metric but the timings)."""
    with monkeypatch.context() as m:
        m.setattr(control, "COMPILED", False)
        ref = _episode(no_slip).result
    got = _episode(no_slip).result
    assert ref.metrics["actions_executed"] > 20  # it did drive and turn
    timing = ("ct_", "wall", "real_time_factor", "_ms", "_per_s")
    clean = [{k: v for k, v in r.metrics.items() if not any(t in k for t in timing)}
             for r in (ref, got)]
    assert clean[0] == clean[1]
    assert ref.actual == got.actual
    assert ref.trajectory.keys() == got.trajectory.keys()
    for k in ref.trajectory:
        assert same(ref.trajectory[k], got.trajectory[k]), k
