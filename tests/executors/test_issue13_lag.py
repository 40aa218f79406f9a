"""Issue 13, the default-dt makespans that moved with exact references (tools/README,
``dt_convergence.py``): what changed between the two runs of one episode, and the lag figure.

- A move from rest over one 1 m cell (a 1 m/s^2, 1.5 m/s AGV) takes exactly 2 s on the
  analytic triangle profile: started on a tick, it ends on the tick boundary two ticks later,
  and the loop's look at that tick sees the AGV standing on its new cell. Before exact
  references the body lagged its reference by a few millimetres and the same look saw it
  still moving (one physics step later it stood): on paper_homogeneous seed 0 this is the
  first decision that differs (AGV 7 at tick 10 is replanned from where it stands), and the
  closed loop goes another way from there.
- ``kinematic_lag_mean_s`` counted the down time of an AGV that failed in the middle of a
  move (40 s per failure on paper_fault) as kinematic lag.
"""

from __future__ import annotations

import pytest

from warerover_phys import scenario_from_dict
from warerover_phys.executors.physics import PhysicsExecutor
from warerover_phys.planning import TimedPath
from warerover_phys.sim import executor_setup, step_executor
from warerover_phys.world import World

CORRIDOR = ["P...........R",
            "P.SS.........",
            "P............"]


def one_agv(dt_s: float = 0.02) -> tuple[World, PhysicsExecutor]:
    w = World.build(scenario_from_dict({
        "layout": {"grid": CORRIDOR},
        "fleet": {"types": {"t": {"max_speed_mps": 1.5, "max_accel_mps2": 1.0,
                                  "max_turn_rate_radps": 2.5}},
                  "agvs": [{"type": "t", "count": 1}]},
        "executor": {"name": "physics", "dt_s": dt_s}}))
    ex = PhysicsExecutor(w.scenario.executor)
    ex.bind(executor_setup(w))
    return w, ex


def run(w: World, ex: PhysicsExecutor, ticks: int) -> None:
    for _ in range(ticks):
        step_executor(w, ex)
        w.tick += 1


def test_a_move_from_rest_ends_on_the_tick_boundary_at_the_analytic_time():
    for dt_s in (0.01, 0.02, 0.05):
        w, ex = one_agv(dt_s)
        a, b = w.node((0, 0)), w.node((0, 1))
        w.reservations.commit(TimedPath(0, 0, ((a, a), (b, b))), 1)
        run(w, ex, 1)
        assert w.agvs[0].pos == (a, b)  # under way after 1 s (half-way on the triangle)
        run(w, ex, 1)
        # 2 s: standing on the new cell at the look of tick 2, not a step later.
        assert w.agvs[0].pos == (b, b), dt_s
        assert ex.acc.kin_lag == [pytest.approx(1.0, abs=1e-6)]  # 2 s against the plan's 1 s


def test_time_down_in_the_middle_of_a_move_is_not_kinematic_lag():
    """On main the first move's lag was 15.7 s: its 15 s down time counted as lag."""
    w, ex = one_agv()
    nodes = [w.node((r, 0)) for r in range(3)]
    w.reservations.commit(TimedPath(0, 0, tuple((n, n) for n in nodes)), 1)
    run(w, ex, 1)  # it turns south (0.63 s) and has just started its first move
    w.fail(0, None)
    run(w, ex, 15)
    w.repair(0)
    run(w, ex, 10)
    assert w.agvs[0].pos == (nodes[-1], nodes[-1])
    s = ex.summary()
    assert s["actions_executed"] == 2
    # Brake, stand 15 s, start again from rest: what is lag is the braking and restart only
    # (under the 1 s of a stop-and-start move), not the 15 s down.
    assert max(ex.acc.kin_lag) < 1.0, ex.acc.kin_lag
    assert s["kinematic_lag_mean_s"] < 1.0
    assert s["delay_kinematic_s"] < 3.0
