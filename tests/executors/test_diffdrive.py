"""Differential drive without side slip (issue 37): the unicycle law of
``executors/diffdrive.py`` keeps speed, acceleration, turn rate and wheel speeds within
their limits at every physics step, never slips sideways, and stops where it must from any
heading; ``robot: diffdrive`` turns it on in one line."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys import load_scenario, scenario_from_dict
from warerover_phys.errors import ScenarioError
from warerover_phys.executors import diffdrive
from warerover_phys.executors.physics import PhysicsExecutor
from warerover_phys.planning import TimedPath
from warerover_phys.sim import apply_report, executor_setup, tick_view
from warerover_phys.world import World

TOL = 1e-6
"""Measured / limit may exceed 1 by float error only."""
TYPE = {"max_speed_mps": 1.5, "max_accel_mps2": 1.0, "max_turn_rate_radps": 2.5,
        "body_m": [0.7, 0.7], "wheel_base_m": 0.6, "max_wheel_speed_mps": 1.5}
FLOOR = ["S.........",
         "..#....#..",
         "..........",
         "....P.....",
         "..........",
         "..#.....#R"]


def world(grid: list[str], executor: dict | None = None, **agv) -> World:
    return World.build(scenario_from_dict({
        "layout": {"grid": grid},
        "fleet": {"types": {"t": {**TYPE, **agv}}, "agvs": [{"type": "t", "count": 1}]},
        "executor": {"name": "physics", "no_slip": True, **(executor or {})}}))


def run(w: World, cells: list[tuple[int, int]], pose: tuple[float, float, float] | None = None,
        max_ticks: int = 200, hook=None) -> PhysicsExecutor:
    """Commit ``cells`` (one per tick) for AGV 0, put its body at ``pose`` (x, y, angle;
    default: as placed) and tick until it has nothing left and stands."""
    w.reservations.commit(TimedPath(0, 0, tuple((w.node(c), w.node(c)) for c in cells)), 1)
    ex = PhysicsExecutor(w.scenario.executor)
    ex.bind(executor_setup(w))
    if pose is not None:
        for body in (ex.fleet.bodies[0], ex.fleet.ctrl[0]):
            body.position = pose[:2]
            body.angle = pose[2]
    for _ in range(max_ticks):
        apply_report(w, ex.step(tick_view(w)))
        w.tick += 1
        if hook is not None:
            hook(ex, w.tick)
        if ex.adg.done(0) and ex.mode[0] == 0:
            return ex
    raise AssertionError("AGV did not finish")


def step_figures(tr: dict, skip: int = 0) -> dict[str, np.ndarray]:
    """Per physics step, from the recorded poses alone (every step recorded): speed,
    acceleration, turn rate, wheel speed and lateral speed of AGV 0 (from sample ``skip``)."""
    t = np.asarray(tr["t"])[skip:]
    x, y = np.asarray(tr["x"])[skip:, 0], np.asarray(tr["y"])[skip:, 0]
    h = np.asarray(tr["heading"])[skip:, 0]
    keep = np.concatenate([[True], np.diff(t) > 0])
    t, x, y, h = t[keep], x[keep], y[keep], h[keep]
    dt = np.diff(t)
    vx, vy = np.diff(x) / dt, np.diff(y) / dt
    dh = (np.diff(h) + math.pi) % (2 * math.pi) - math.pi
    mid = h[:-1] + dh / 2
    turn = np.abs(dh) / dt
    along = vx * np.cos(mid) + vy * np.sin(mid)
    return {"speed": np.hypot(vx, vy), "accel": np.hypot(np.diff(vx), np.diff(vy)) / dt[1:],
            "turn": turn, "wheel": np.abs(along) + turn * float(tr["wheel_base_m"][0]) / 2,
            "lateral": np.abs(vy * np.cos(mid) - vx * np.sin(mid))}


def assert_within_limits(ex: PhysicsExecutor, skip: int = 0) -> None:
    """Every step from sample ``skip`` on within the limits, no contact; the executor's
    counters agree (unless the test moved the body itself: ``skip``)."""
    f = step_figures(ex.trajectory(), skip)
    assert f["speed"].max() <= 1.5 * (1 + TOL)
    assert f["accel"].max() <= 1.0 * (1 + TOL)
    assert f["turn"].max() <= 2.5 * (1 + TOL)
    assert f["wheel"].max() <= 1.5 * (1 + TOL)
    assert f["lateral"].max() < 1e-9
    s = ex.summary()
    assert s["static_contacts"] == 0 and s["agv_contacts"] == 0
    if not skip:
        assert s["limit_violations"] == 0 and s["peak_wheel_speed_ratio"] <= 1 + TOL


# ------------------------------------------------------------------------------- the limiter


@settings(max_examples=400, deadline=None)
@given(st.floats(0, 1.5), st.floats(-2.5, 2.5), st.floats(-math.pi, math.pi),
       st.floats(-5, 5), st.floats(-5, 5), st.sampled_from([0.01, 0.02, 0.05]),
       st.sampled_from([(0.0, math.inf), (0.3, 1.5), (0.3, 0.8)]))
def test_the_limiter_keeps_every_limit_from_any_state_it_made(u0, w0, th0, u_t, w_t, dt,
                                                              wheels):
    """From a state its own command made (the body moved at ``u0`` along its chord while it
    turned at ``w0``), any wanted speed and turn rate come out within every limit."""
    half_base, wheel_max = wheels
    vmax, amax, wmax = 1.5, 1.0, 2.5
    if half_base and u0 + abs(w0) * half_base > wheel_max:
        u0 = wheel_max - abs(w0) * half_base
    if u0 < 0:
        return
    m0 = th0 + 0.5 * w0 * dt
    vx, vy = u0 * math.cos(m0), u0 * math.sin(m0)
    th = th0 + w0 * dt
    u, w, hx, hy = diffdrive.limit_unicycle.py_func(u_t, w_t, th, vx, vy, vmax, amax, wmax,
                                                     wheel_max, half_base, dt)
    assert abs(u) <= vmax * (1 + 1e-12) and abs(w) <= wmax * (1 + 1e-12)
    assert abs(u) + abs(w) * half_base <= wheel_max * (1 + 1e-12)
    assert math.hypot(u * hx - vx, u * hy - vy) <= amax * dt * (1 + 1e-9)
    m = th + 0.5 * w * dt
    assert (hx, hy) == pytest.approx((math.cos(m), math.sin(m)), abs=1e-15)
    # The compiled kernel gives the same numbers.
    assert diffdrive.limit_unicycle(u_t, w_t, th, vx, vy, vmax, amax, wmax, wheel_max,
                                    half_base, dt) == (u, w, hx, hy)


def test_the_limiter_brakes_before_it_steers():
    """Moving at 1.5 m/s and asked to stop as hard as it may and to turn at full rate: the
    turn is cut back so that the speed still drops by the full a dt."""
    dt = 0.02
    u, w, _, _ = diffdrive.limit_unicycle(0.0, 2.5, 0.0, 1.5, 0.0, 1.5, 1.0, 2.5, math.inf,
                                          0.0, dt)
    assert u == pytest.approx(1.5 - 1.0 * dt, abs=1e-9)
    assert abs(w) < 1e-6
    # Cruising, the turn takes what the acceleration limit leaves (u w dt <= a dt).
    u, w, _, _ = diffdrive.limit_unicycle(1.5, 2.5, 0.0, 1.5, 0.0, 1.5, 1.0, 2.5, math.inf,
                                          0.0, dt)
    assert 0 < w < 2.5 and u <= 1.5


# ------------------------------------------------------------------------------- executions


@st.composite
def walks(draw) -> list[tuple[int, int]]:
    """A random walk over FLOOR's free cells from its parking spot, with waits."""
    rows, cols = len(FLOOR), len(FLOOR[0])
    cell = (3, 4)
    cells = [cell]
    for _ in range(draw(st.integers(1, 14))):
        r, c = cell
        options = [(r + dr, c + dc) for dr, dc in ((0, 1), (1, 0), (0, -1), (-1, 0), (0, 0))
                   if 0 <= r + dr < rows and 0 <= c + dc < cols and FLOOR[r + dr][c + dc] != "#"]
        cell = draw(st.sampled_from(options))
        cells.append(cell)
    return cells


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(walks(), st.floats(0.0, 0.4), st.integers(1, 4), st.sampled_from([0.01, 0.02, 0.05]),
       st.floats(-math.pi, math.pi), st.floats(-0.004, 0.004), st.floats(-0.004, 0.004))
def test_random_paths_and_delays_never_exceed_a_limit_at_any_step(cells, prob, longest, dt,
                                                                  angle, dx, dy):
    """Any path (turns, reversals, waits) with random delays, from any start heading and
    a few millimetres off the cell centre: at every physics step the speed, acceleration,
    turn rate and wheel speeds measured from the poses are within their limits, the body
    never moves sideways, and it touches nothing."""
    w = world(FLOOR, {"dt_s": dt, "trajectory_hz": 1.0 / dt,
                      "delays": {"model": "bernoulli", "prob": prob, "max_ticks": longest}})
    ex = run(w, cells, pose=(4.5 + dx, 3.5 + dy, angle))
    assert_within_limits(ex)
    x, y = ex.fleet.bodies[0].position
    r, c = cells[-1]
    assert math.hypot(x - (c + 0.5), y - (r + 0.5)) < 0.01


@pytest.mark.parametrize("deg", range(0, 360, 10))
def test_a_wall_approach_from_every_heading_stops_clear_of_the_wall(deg):
    """Standing at any heading three cells from the map's east wall, the AGV turns in place
    and drives to the cell next to the wall: it stops on that cell's centre, touches
    nothing, keeps every limit and never slips."""
    grid = ["S.......",
            "....P...",
            ".......R"]
    w = world(grid, {"trajectory_hz": 50.0})
    ex = run(w, [(1, 4), (1, 5), (1, 6), (1, 7)], pose=(4.5, 1.5, math.radians(deg)))
    assert_within_limits(ex)
    x, y = ex.fleet.bodies[0].position
    assert (x, y) == pytest.approx((7.5, 1.5), abs=1e-6)
    assert x + 0.35 < 8.0  # the body's front is clear of the wall at x = 8 m


@pytest.mark.parametrize("err", [-0.3, -0.1, 0.1, 0.3])
def test_a_heading_error_at_speed_is_steered_out_and_the_stop_kept(err):
    """Driving at speed towards the wall, the body is knocked ``err`` radians off its
    heading (its velocity turned with it): it steers back onto its line and still stops on
    its last cell without touching the wall, every step after the knock within limits."""
    grid = ["S........",
            "P........",
            "........R"]
    w = world(grid, {"trajectory_hz": 50.0})
    knocked = []

    def knock(ex: PhysicsExecutor, tick: int) -> None:
        if tick == 3 and not knocked:
            b = ex.fleet.bodies[0]
            knocked.append(len(ex.trajectory()["t"]))
            b.angle += err
            speed = math.hypot(*b.velocity)
            for body in (b, ex.fleet.ctrl[0]):
                body.velocity = (speed * math.cos(b.angle), speed * math.sin(b.angle))
                body.angle = b.angle

    ex = run(w, [(1, c) for c in range(9)], hook=knock)
    assert knocked
    assert_within_limits(ex, skip=knocked[0] + 1)
    x, y = ex.fleet.bodies[0].position
    assert abs(x - 8.5) < 1e-3 and abs(y - 1.5) < 0.02


def test_a_body_pushed_back_along_its_run_does_not_lag_its_reference():
    """The reference starts from the body: a body set 5 cm back mid-run goes on from there
    (no off-reference hold-up, no catching up beyond the limits) and arrives."""
    w = world(["P........", "S.......R"], {"trajectory_hz": 50.0})
    pushed = []

    def push(ex: PhysicsExecutor, tick: int) -> None:
        if tick == 2 and not pushed:
            pushed.append(len(ex.trajectory()["t"]))
            for body in (ex.fleet.bodies[0], ex.fleet.ctrl[0]):
                body.position = (body.position[0] - 0.05, body.position[1])

    ex = run(w, [(0, c) for c in range(9)], hook=push)
    assert pushed and ex.off_reference == 0
    assert_within_limits(ex, skip=pushed[0] + 1)


# ------------------------------------------------------------------------------- the preset


def test_robot_diffdrive_turns_no_slip_on_and_fills_wheel_limits():
    sc = load_scenario("paper_heterogeneous", [("robot", "diffdrive")])
    assert sc.robot == "diffdrive" and sc.executor.no_slip is True
    small, large = sc.fleet.types["small"], sc.fleet.types["large"]
    assert small.wheel_base_m == pytest.approx(0.85 * 0.7)
    assert small.max_wheel_speed_mps == pytest.approx(1.5)  # 2.5 x 0.2975 < 1.5
    assert large.drive == "omni" and large.wheel_base_m is None
    plain = load_scenario("paper_heterogeneous")
    assert plain.robot == "default" and not plain.executor.no_slip
    assert plain.fleet.types["small"].wheel_base_m is None
    # Given wheel limits are kept.
    sc = scenario_from_dict({"robot": "diffdrive", "layout": {"grid": ["P.S.R"]},
                             "fleet": {"types": {"t": dict(TYPE, max_wheel_speed_mps=2.0)},
                                       "agvs": [{"type": "t"}]}})
    assert sc.fleet.types["t"].max_wheel_speed_mps == 2.0


@pytest.mark.parametrize("data, field, words", [
    ({"robot": "diffdrive", "executor": {"no_slip": False}}, "executor.no_slip", "contradicts"),
    ({"robot": "tank"}, "robot", "diffdrive"),
    ({"fleet": {"types": {"t": {"wheel_base_m": 0.6}}, "agvs": [{"type": "t"}]}},
     "fleet.types.t", "go together"),
    ({"fleet": {"types": {"t": {"wheel_base_m": 0.6, "max_wheel_speed_mps": 1.0}},
                "agvs": [{"type": "t"}]}}, "fleet.types.t", "max_wheel_speed_mps 1 is below"),
    ({"fleet": {"types": {"t": {"wheel_base_m": 0.9, "max_wheel_speed_mps": 2.0}},
                "agvs": [{"type": "t"}]}}, "fleet.types.t", "wider than the body"),
    ({"fleet": {"types": {"t": {"drive": "omni", "wheel_base_m": 0.5,
                                "max_wheel_speed_mps": 2.0}}, "agvs": [{"type": "t"}]}},
     "fleet.types.t", "drive: diff"),
])
def test_bad_robot_settings_name_the_field(data, field, words):
    base = {"layout": {"grid": ["P.S.R"]}, "fleet": {"agvs": [{"count": 1}]}}
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict({**base, **data})
    assert err.value.field == field and words in str(err.value)


def test_execute_takes_robot_diffdrive_and_bad_values_exit_2(tmp_path):
    """``warerover execute --set robot=diffdrive``: no-slip drive and the preset's wheel
    limits on a plan made elsewhere; a bad value, or ``no_slip=false`` beside it, exits 2."""
    from typer.testing import CliRunner

    from warerover_phys.cli import app
    from warerover_phys.execute import DEFAULT_TYPE, robot_model
    from warerover_phys.plans import Plan, write_plan

    opts, types = robot_model({"robot": "diffdrive", "park": False}, [DEFAULT_TYPE] * 2)
    assert opts == {"no_slip": True, "park": False}
    assert types[0] == types[1] and types[0].wheel_base_m == pytest.approx(0.85 * 0.7)
    assert robot_model({}, [DEFAULT_TYPE]) == ({}, [DEFAULT_TYPE])
    floor = tmp_path / "open.map"
    floor.write_text("type octile\nheight 3\nwidth 5\nmap\n.....\n.....\n.....\n")
    plan = tmp_path / "plan.txt"
    write_plan(Plan((((0, 0), (0, 1), (0, 2), (1, 2), (2, 2)),
                     ((2, 4), (2, 4), (1, 4), (0, 4), (0, 3))), rows=3, cols=5), plan, "lacam")
    base = ["execute", str(floor), "--plan", str(plan), "--json", "-q"]
    runner = CliRunner()
    r = runner.invoke(app, [*base, "--out", str(tmp_path / "a"), "--set", "robot=diffdrive"])
    assert r.exit_code == 0, r.output
    m = json.loads(r.output)
    assert m["no_slip"] is True and m["limit_violations"] == 0 and m["agv_contacts"] == 0
    assert 0.99 < m["peak_wheel_speed_ratio"] <= 1 + TOL
    for bad in (["--set", "robot=tank"], ["--set", "robot=diffdrive", "--set", "no_slip=false"]):
        r = runner.invoke(app, [*base, "--out", str(tmp_path / "b"), *bad])
        assert r.exit_code == 2 and "robot" in r.output, r.output
