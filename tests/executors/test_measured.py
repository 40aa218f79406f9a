"""What the physics executor measures about its own bodies, checked from the outside.

- the rectangle distance against shapely;
- stops brake within the acceleration limit (from poses recorded at every physics step);
- in every shipped scenario the peak speed, acceleration and turn rate, recomputed from the
  recorded trajectory at the physics step, stay within 5% of the limits, and the executor's
  own peaks agree with that recomputation;
- ``min_clearance_m`` is the true edge-to-edge clearance: an outside check builds shapely
  polygons (body, carried shelf) from ``trajectories.npz`` and finds the same figure and no
  overlap;
- ``trajectory_hz`` records up to every physics step and no faster.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely import affinity

from warerover_phys import load_scenario, scenario_from_dict
from warerover_phys.errors import ScenarioError
from warerover_phys.executors.measured import LIMIT_TOLERANCE, rect_distance
from warerover_phys.executors.physics import PhysicsExecutor
from warerover_phys.planning import TimedPath
from warerover_phys.sim import executor_setup, run_episode, step_executor
from warerover_phys.world import World

LAYOUTS = sorted(str(p) for p in Path("layouts").glob("*.yaml"))


# --------------------------------------------------------------------------- outside helpers

def box(cx: float, cy: float, angle: float, length: float, width: float):
    b = shapely.box(-length / 2, -width / 2, length / 2, width / 2)
    return affinity.translate(affinity.rotate(b, angle, use_radians=True), cx, cy)


def outline(x, y, h, body, shelf):
    """An AGV's outline as documented for trajectories.npz: the body rectangle turned by the
    heading, joined by the carried shelf's square with sides along the grid."""
    p = box(x, y, h, *body)
    if shelf[0] > 0:
        p = p.union(box(x, y, 0.0, *shelf))
    return p


def outside_clearance(traj) -> float:
    """Smallest distance between any two AGV outlines over every recorded sample (0 when
    two overlap), with shapely and a STRtree: no code shared with the executor."""
    x, y, h = (np.asarray(traj[k]) for k in ("x", "y", "heading"))
    body, shelf = np.asarray(traj["body_m"]), np.asarray(traj["shelf_m"], dtype=float)
    best = math.inf
    for k in range(len(traj["t"])):
        polys = np.array([outline(x[k, i], y[k, i], h[k, i], body[i], shelf[k, i])
                          for i in range(x.shape[1])])
        tree = shapely.STRtree(polys)
        a, b = tree.query(polys, predicate="dwithin", distance=1.0)
        keep = a < b
        if keep.any():
            best = min(best, float(shapely.distance(polys[a[keep]], polys[b[keep]]).min()))
    return best


def finite_difference_peaks(traj) -> dict[str, np.ndarray]:
    t = np.asarray(traj["t"])
    x, y, h = (np.asarray(traj[k], dtype=float) for k in ("x", "y", "heading"))
    dt = np.diff(t)[:, None]
    vx, vy = np.diff(x, axis=0) / dt, np.diff(y, axis=0) / dt
    dh = (np.diff(h, axis=0) + math.pi) % (2 * math.pi) - math.pi
    ax, ay = np.diff(vx, axis=0) / dt[1:], np.diff(vy, axis=0) / dt[1:]
    return {"speed": np.hypot(vx, vy).max(axis=0), "accel": np.hypot(ax, ay).max(axis=0),
            "turn_rate": (np.abs(dh) / dt).max(axis=0)}


# --------------------------------------------------------------------------- geometry

finite = st.floats(-3, 3, allow_nan=False)
size = st.floats(0.05, 1.5, allow_nan=False)


# 150 examples: one distance per example against shapely, wide inputs
@settings(max_examples=150, deadline=None)
@given(finite, finite, finite, size, size, finite, finite, finite, size, size)
def test_rect_distance_is_shapely_distance_or_minus_a_depth(x1, y1, a1, l1, w1, x2, y2, a2, l2,
                                                            w2):
    d = float(rect_distance(np.array([[x1, y1]]), np.array([a1]), np.array([[l1, w1]]) / 2,
                            np.array([[x2, y2]]), np.array([a2]), np.array([[l2, w2]]) / 2)[0])
    p, q = box(x1, y1, a1, l1, w1), box(x2, y2, a2, l2, w2)
    gap = p.distance(q)
    if gap > 1e-9:
        assert d == pytest.approx(gap, abs=1e-9)
    elif p.intersection(q).area > 1e-9:
        assert d < 0
        depth = -d
        # The depth is the shortest push that separates them: some push of depth + 1 mm
        # separates them, no push of depth - 1 cm in any of 360 directions does.
        pushes = [(math.cos(th), math.sin(th)) for th in np.linspace(0, 2 * math.pi, 360,
                                                                    endpoint=False)]
        normals = [(math.cos(a), math.sin(a)) for a in (a1, a1 + math.pi / 2, a2,
                                                       a2 + math.pi / 2)]
        normals += [(-u, -v) for u, v in normals]
        assert any(not p.intersects(affinity.translate(q, u * (depth + 1e-3), v * (depth + 1e-3)))
                   for u, v in normals)
        if depth > 0.01:
            short = depth - 0.01
            assert all(p.intersects(affinity.translate(q, u * short, v * short))
                       for u, v in pushes)


# --------------------------------------------------------------------------- stops

CORRIDOR = ["P...........R",
            "P.SS.........",
            "P............"]


def one_agv(**exec_spec) -> tuple[World, PhysicsExecutor]:
    w = World.build(scenario_from_dict({
        "layout": {"grid": CORRIDOR},
        "fleet": {"types": {"t": {"max_speed_mps": 1.5, "max_accel_mps2": 1.0,
                                  "max_turn_rate_radps": 2.5}},
                  "agvs": [{"type": "t", "count": 1}]},
        "executor": {"name": "physics", **exec_spec}}))
    ex = PhysicsExecutor(w.scenario.executor)
    ex.bind(executor_setup(w))
    return w, ex


@pytest.mark.parametrize("dt_s", [0.01, 0.02, 0.05])
@pytest.mark.parametrize("cells", [1, 2, 5])
def test_a_stop_brakes_within_the_acceleration_limit(dt_s, cells):
    """On main the last step of every stop braked at up to 2 x max_accel (the reference's
    d/dt term and the switch to the hold controller)."""
    w, ex = one_agv(dt_s=dt_s, trajectory_hz=1 / dt_s)
    nodes = [w.node((0, c)) for c in range(cells + 1)]
    w.reservations.commit(TimedPath(0, 0, tuple((n, n) for n in nodes)), 1)
    for _ in range(12):
        step_executor(w, ex)
        w.tick += 1
    traj = ex.trajectory()
    peaks = finite_difference_peaks(traj)
    assert peaks["accel"][0] <= 1.0 * (1 + LIMIT_TOLERANCE), peaks
    assert peaks["speed"][0] <= 1.5 * (1 + LIMIT_TOLERANCE), peaks
    assert abs(traj["x"][-1, 0] - (cells + 0.5)) < 0.02  # it still stops on the cell centre
    s = ex.summary()
    assert s["limit_violations"] == 0 and s["peak_accel_ratio"] <= 1 + LIMIT_TOLERANCE


# --------------------------------------------------------------------------- shipped scenarios

def short_physics(path: str, ticks: int, dt_s: float = 0.02):
    return load_scenario(path, [("executor.name", "physics"), ("max_ticks", ticks),
                                ("executor.dt_s", dt_s),
                                ("executor.trajectory_hz", 1 / dt_s)])


@pytest.mark.parametrize("path", [p for p in LAYOUTS if "industrial" not in p])
def test_peaks_within_limits_in_every_paper_scenario(path):
    res = run_episode(short_physics(path, 60), seed=0)
    _check_peaks(res)


@pytest.mark.slow
def test_peaks_within_limits_on_the_industrial_floor():
    res = run_episode(short_physics("layouts/industrial.yaml", 25), seed=0)
    _check_peaks(res)


def _check_peaks(res) -> None:
    traj, m = res.trajectory, res.metrics
    outside = finite_difference_peaks(traj)
    names = {"speed": "mps", "accel": "mps2", "turn_rate": "radps"}
    for kind, unit in names.items():
        limit = np.asarray(traj[f"limit_{kind}_mps" if kind == "speed" else
                                f"limit_{kind}_{unit}"])
        peak = np.asarray(traj[f"peak_{kind}_{unit}"])
        assert np.all(outside[kind] <= limit * (1 + LIMIT_TOLERANCE)), (kind, outside[kind])
        # The executor's own peaks are the same finite differences (it also sees the step
        # before the first recorded sample, so it may only be higher).
        assert np.all(peak >= outside[kind] - 1e-6), kind
        assert np.all(peak <= limit * (1 + LIMIT_TOLERANCE)), (kind, peak)
    assert m["limit_violations"] == 0
    assert m["actions_executed"] > 0


# --------------------------------------------------------------------------- clearance

@pytest.mark.slow  # whole physics episodes: make test-all
def test_min_clearance_is_what_an_outside_check_finds_in_trajectories_npz(tmp_path):
    """On main ``min_separation_m`` said 0.51 m (centre to edge, once a tick) where the
    bodies came within 1 cm; now ``min_clearance_m`` is the edge-to-edge figure over every
    physics step, carried shelves included, and shapely agrees."""
    out = tmp_path / "run"
    exe = Path(sys.executable).parent / "warerover"
    r = subprocess.run([str(exe), "run", "layouts/paper_homogeneous.yaml", "--executor",
                        "physics", "--seed", "0", "--set", "max_ticks=50", "--set",
                        "executor.trajectory_hz=50", "--out", str(out), "--quiet"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    m = json.loads((out / "metrics.json").read_text())
    with np.load(out / "trajectories.npz") as f:
        traj = {k: f[k] for k in f.files}
    n, samples = m["agvs"], len(traj["t"])
    assert samples == m["physics_steps"]  # one sample per physics step
    assert traj["shelf_m"].shape == (samples, n, 2) and traj["body_m"].shape == (n, 2)
    carrying = traj["shelf_m"][..., 0] > 0
    assert carrying.any() and np.array_equal(carrying, traj["loaded"].astype(bool))
    outside = outside_clearance(traj)
    assert outside > 0, "AGV outlines overlap in a clean episode"
    assert m["min_clearance_m"] == pytest.approx(outside, abs=1e-5)
    assert m["min_separation_m"] == m["min_clearance_m"]  # deprecated alias


def test_overlapping_bodies_give_a_negative_clearance():
    """Two AGVs pushed into each other by a plan that ignores dependencies (naive
    following, swapped cells): the clearance is the overlap depth, below zero."""
    w = World.build(scenario_from_dict({
        "layout": {"grid": ["......", "R....S"]},
        "fleet": {"types": {"t": {"body_m": [0.9, 0.9]}}, "agvs": [
            {"type": "t", "count": 2, "starts": [[0, 0], [0, 2]]}]},
        "executor": {"name": "physics", "adg": False}}))
    ex = PhysicsExecutor(w.scenario.executor)
    ex.bind(executor_setup(w))
    a, b = (w.node((0, c)) for c in (0, 1)), (w.node((0, c)) for c in (2, 1))
    w.reservations.commit(TimedPath(0, 0, tuple((n, n) for n in a)), 1)
    w.reservations.commit(TimedPath(1, 0, tuple((n, n) for n in b)), 1)
    for _ in range(4):
        step_executor(w, ex)
        w.tick += 1
    s = ex.summary()
    assert s["agv_contacts"] > 0
    assert s["min_clearance_m"] < 0


# --------------------------------------------------------------------------- trajectory_hz

def test_trajectory_hz_above_the_physics_rate_is_refused_with_field_and_value():
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict({"layout": {"grid": ["P..R"]},
                            "fleet": {"types": {"t": {}}, "agvs": [{"type": "t", "count": 1}]},
                            "executor": {"name": "physics", "dt_s": 0.05,
                                         "trajectory_hz": 25.0}})
    text = str(info.value)
    assert "executor.trajectory_hz" in text and "25" in text and "20 Hz" in text


@pytest.mark.parametrize(("dt_s", "hz", "every"), [(0.02, 10.0, 5), (0.02, 50.0, 1),
                                                   (0.05, 20.0, 1), (0.01, 10.0, 10)])
def test_trajectory_hz_records_every_nth_physics_step(dt_s, hz, every):
    w, ex = one_agv(dt_s=dt_s, trajectory_hz=hz)
    for _ in range(2):
        step_executor(w, ex)
        w.tick += 1
    t = np.asarray(ex.trajectory()["t"])
    assert np.allclose(np.diff(t), every * dt_s)
    assert len(t) == ex.acc.steps // every


# --------------------------------------------------------------------------- dt convergence

@pytest.mark.slow
def test_makespan_agrees_across_physics_steps():
    """paper_homogeneous, seed 0: once the makespan was 136 / 117 / 119 ticks at dt
    0.01 / 0.02 / 0.05 s (decisions every 5 steps, a reference that ran up to dt / 2 ahead of
    its continuous profile and stopped with a 2a step). With exact references and deadbeat
    tracking all three agree within 2% (the fast check: ``test_dt_exact.py``)."""
    ticks = {}
    for dt in (0.01, 0.02, 0.05):
        sc = load_scenario("layouts/paper_homogeneous.yaml",
                           [("executor.name", "physics"), ("executor.dt_s", dt)])
        ticks[dt] = run_episode(sc, seed=0).metrics["ticks"]
    assert abs(ticks[0.02] - ticks[0.01]) <= 0.02 * ticks[0.01], ticks
    assert abs(ticks[0.05] - ticks[0.01]) <= 0.02 * ticks[0.01], ticks


def test_monitors_skip_agvs_that_stand_still_without_changing_a_figure():
    """Clearance and limits look only at AGVs whose pose changed (parked AGVs do not move
    at all); fed poses in which most AGVs stand still for long runs, they agree with a
    brute-force recomputation over every pair and every AGV at every step."""
    from warerover_phys.executors.measured import (
        CLEARANCE_HORIZON_M,
        LIMIT_TOLERANCE,
        ClearanceMonitor,
        LimitMonitor,
        rect_distance,
    )

    rng = np.random.default_rng(5)
    n, steps, dt = 12, 120, 0.05
    half = np.full((n, 2), 0.4)
    pos = np.column_stack([np.arange(n) % 4 * 1.1, np.arange(n) // 4 * 1.1]).astype(float)
    ang = np.zeros(n)
    vmax, amax, wmax = np.full(n, 1.0), np.full(n, 1.0), np.full(n, 1.0)
    clear, lim = ClearanceMonitor(half), LimitMonitor(vmax, amax, wmax)
    i, j = np.triu_indices(n, 1)
    best, peak_v, peak_a, peak_w = math.inf, np.zeros(n), np.zeros(n), np.zeros(n)
    prev = prev_v = None
    events = 0
    was_over = {k: np.zeros(n, dtype=bool) for k in ("v", "a", "w")}
    violations = 0

    def over(kind: str, value: np.ndarray) -> None:
        nonlocal violations
        now = value > 1.0 * (1 + LIMIT_TOLERANCE)
        violations += int(np.count_nonzero(now & ~was_over[kind]))
        was_over[kind] = now
    for s in range(steps):
        moving = rng.random(n) < 0.2  # the rest keep their pose exactly
        pos = pos + moving[:, None] * rng.normal(0, 0.06, (n, 2))
        ang = ang + moving * rng.normal(0, 0.08, n)
        t = s * dt
        clear.measure(pos, ang, t)
        events += len(lim.measure(pos, ang, t))
        d = rect_distance(pos[i], ang[i], half[i], pos[j], ang[j], half[j])
        near = d < CLEARANCE_HORIZON_M
        if near.any():
            best = min(best, float(d[near].min()))
        if prev is not None:
            v = (pos - prev[0]) / dt
            speed = np.hypot(v[:, 0], v[:, 1])
            turn = np.abs((ang - prev[1] + math.pi) % (2 * math.pi) - math.pi) / dt
            peak_v, peak_w = np.maximum(peak_v, speed), np.maximum(peak_w, turn)
            over("v", speed)
            over("w", turn)
            if prev_v is not None:
                acc = np.hypot(*(v - prev_v).T) / dt
                peak_a = np.maximum(peak_a, acc)
                over("a", acc)
            prev_v = v
        prev = (pos.copy(), ang.copy())
    assert clear.min_m == pytest.approx(best, abs=1e-12)
    assert np.allclose(lim.peak["speed"], peak_v, rtol=1e-12, atol=0)
    assert np.allclose(lim.peak["accel"], peak_a, rtol=1e-12, atol=0)
    assert np.allclose(lim.peak["turn_rate"], peak_w, rtol=1e-12, atol=0)
    assert lim.violations == events == violations > 0
    assert (peak_v > 1 + LIMIT_TOLERANCE).any()
