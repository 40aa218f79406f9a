"""``executor.reorder`` (executors/reorder.py, reorder_milp.py): the two-robot corridor
shows the switch and its gain; a switch that would not pay is not made; reordered runs
are deterministic per seed, collision-free and drive every plan's cells in order; the
lost-time parts still add up with ``reorder_gain``. (The command line: test_reorder_cli.py.)"""

from __future__ import annotations

import math
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st
from pydantic import ValidationError
from test_adg import instances

from warerover_phys.config import AgvTypeSpec, ExecutorSpec, LayoutSpec
from warerover_phys.executors.base import AgvBody, ExecutorSetup, TickView
from warerover_phys.executors.physics import PhysicsExecutor
from warerover_phys.executors.reorder import check_executed, slowdown
from warerover_phys.gap.open_loop import PARTS
from warerover_phys.layout import build_layout
from warerover_phys.planning.base import TimedPath

REPO = Path(__file__).resolve().parents[2]

# Row 0 is a corridor; AGV 0 enters it from (1, 2) and drives east to (0, 5), AGV 1
# drives east along it behind AGV 0 and leaves it down to (1, 3). The plan lets AGV 0
# pass (0, 2) and (0, 3) first; AGV 1 waits for it at (0, 1).
GRID = ["......", "##..##", "SR####"]
PATHS = {0: TimedPath(0, 0, ((8, 8), (2, 2), (3, 3), (4, 4), (5, 5))),
         1: TimedPath(1, 0, ((0, 0), (1, 1), (1, 1), (2, 2), (3, 3), (9, 9)))}


def corridor(mode: str, delay_s: float, paths=PATHS, delay_at: int = 0, grid=GRID,
             **options) -> PhysicsExecutor:
    """Execute the corridor plan with AGV 0 held by a delay of ``delay_s`` from tick
    ``delay_at`` (0: before it starts)."""
    layout = build_layout(LayoutSpec(grid=grid))
    ex = PhysicsExecutor(ExecutorSpec(name="physics", reorder=mode, **options))
    n = len(paths)
    ex.bind(ExecutorSetup(layout=layout, tick_s=1.0, rng=np.random.default_rng(0),
                          agvs=tuple(AgvBody(i, 1, AgvTypeSpec(), paths[i].states[0])
                                     for i in range(n))))
    ex.delayed_until[0] = 0.0 if delay_at else delay_s
    ex.test_events = []
    plans = MappingProxyType(paths)
    for tick in range(60):
        if delay_at and tick == delay_at:
            ex.delayed_until[0] = tick * 1.0 + delay_s
        rep = ex.step(TickView(tick=tick, plans=plans, behind=(0,) * n, failed=frozenset(),
                               loaded=(False,) * n, carried=(None,) * n,
                               task_state=(0,) * n))
        ex.test_events += rep.events
        if all(ex.adg.done(i) for i in range(n)) and (ex.mode == 0).all():
            return ex
    raise AssertionError("the corridor plan did not finish")


def switches(ex: PhysicsExecutor) -> list[dict]:
    return [f for name, f in ex.test_events if name == "reorder"]


def test_greedy_lets_the_waiting_agv_pass_first_and_wins_its_wait():
    plain = corridor("none", 8.0)
    greedy = corridor("greedy", 8.0)
    assert plain.follow.reorder is None and "reorder_switches" not in plain.summary()
    (sw,) = switches(greedy)
    assert (sw["first"], sw["then"], sw["cells"]) == (1, 0, [[0, 2], [0, 3]])
    assert sw["wait_s"] > 5 and sw["cost_s"] == 0.0
    # AGV 1 no longer waits for the late AGV 0; AGV 0 loses nothing (it was late anyway)
    assert plain.last_finish[1] - greedy.last_finish[1] > 8.0
    assert greedy.last_finish[0] == pytest.approx(plain.last_finish[0], abs=1e-9)
    s = greedy.summary()
    assert s["reorder_switches"] == 1 and s["agv_contacts"] == 0 == plain.summary()[
        "agv_contacts"]
    log = greedy.cause_log()
    won = log.reorder_gain[log.agv == 1]
    assert won.sum() * log.dt_s == pytest.approx(sw["wait_s"], abs=log.dt_s)
    assert not plain.cause_log().reorder_gain.any()


def test_a_driving_agv_is_switched_before_it_stops():
    # AGV 1 drives up to the corridor that the late AGV 0 should pass first. Standing
    # candidates only: it stops at (0, 1), is switched at the next decision and starts
    # again. Driving candidates (reorder_ahead_s): it is switched as it drives up, and
    # goes on without stopping.
    plain = corridor("none", 8.0)
    standing = corridor("greedy", 8.0, reorder_ahead_s=0.0)
    driving = corridor("greedy", 8.0)
    (s1,), (s2,) = switches(standing), switches(driving)
    assert not s1["driving"] and s2["driving"] and s2["t_s"] < s1["t_s"]
    assert (s2["first"], s2["then"], s2["cells"]) == (1, 0, [[0, 2], [0, 3]])
    assert standing.summary()["delay_dependency_wait_s"] > 0.2
    assert driving.summary()["delay_dependency_wait_s"] == 0.0
    assert driving.summary()["reorder_switches_driving"] == 1
    assert standing.summary()["reorder_switches_driving"] == 0
    # it saves the stop (about speed / acceleration) on top of the standing switch's gain
    assert standing.last_finish[1] - driving.last_finish[1] > 1.0
    assert plain.last_finish[1] - driving.last_finish[1] > 10.0
    for ex in (plain, standing, driving):  # AGV 0 was late anyway: it loses nothing
        assert ex.last_finish[0] == pytest.approx(plain.last_finish[0], abs=1e-9)
        assert ex.summary()["agv_contacts"] == 0
    log = driving.cause_log()
    won = log.reorder_gain[log.agv == 1]
    assert won.sum() * log.dt_s == pytest.approx(s2["wait_s"], abs=log.dt_s)


# AGV 0 drives east along row 0 to (0, 5), claiming the cells of its run; AGV 1 crosses
# the row after it: up from (1, 3) to (0, 3), west to (0, 2) and down to (1, 2).
CROSS = {0: TimedPath(0, 0, ((0, 0), (1, 1), (2, 2), (3, 3), (4, 4), (5, 5))),
         1: TimedPath(1, 0, ((9, 9),) * 5 + ((3, 3), (2, 2), (8, 8)))}


def test_a_delayed_driving_agv_gives_back_the_claims_beyond_its_braking():
    # Held from tick 1 (driving, below its braking distance of a cell), AGV 0 can stop at
    # (0, 1): it gives back its claims on (0, 2) and (0, 3), and AGV 1 crosses first.
    plain = corridor("none", 8.0, paths=CROSS, delay_at=1)
    greedy = corridor("greedy", 8.0, paths=CROSS, delay_at=1)
    (sw,) = switches(greedy)
    assert (sw["first"], sw["then"]) == (1, 0) and [0, 3] in sw["cells"]
    assert plain.last_finish[1] - greedy.last_finish[1] > 5.0
    assert greedy.summary()["agv_contacts"] == 0 == plain.summary()["agv_contacts"]
    # AGV 0 stopped on (0, 1), short of the cells it gave back, and finished its plan no
    # sooner (to within the rounding of a run started again: 1e-8 s)
    assert greedy.adg.done(0) and greedy.last_finish[0] >= plain.last_finish[0] - 1e-6
    # Without the delay AGV 0 passes first as planned: nothing to switch
    assert switches(corridor("greedy", 0.0, paths=CROSS)) == []
    # Claims given back but nothing switched: the plain graph's motion to the last digit
    never = corridor("greedy", 8.0, paths=CROSS, delay_at=1, reorder_margin_s=1e6)
    assert switches(never) == []
    np.testing.assert_array_equal(never.last_finish, plain.last_finish)


# AGV 0 drives the whole corridor of row 1 east; AGV 1 crosses it at column 8 after it.
LONG = ["########.###", "............", "########.###", "SR##########"]
LONG_PATHS = {0: TimedPath(0, 0, tuple((12 + c, 12 + c) for c in range(12))),
              1: TimedPath(1, 0, ((8, 8),) * 9 + ((20, 20), (32, 32)))}


def test_a_driving_agv_claims_only_what_its_braking_needs():
    # Far from (1, 8), AGV 0 has not claimed it yet: AGV 1 crosses first and clears the
    # cell before AGV 0 gets there (plain: it waits until AGV 0 has passed).
    plain = corridor("none", 0.0, paths=LONG_PATHS, grid=LONG)
    greedy = corridor("greedy", 0.0, paths=LONG_PATHS, grid=LONG)
    (sw,) = switches(greedy)
    assert (sw["first"], sw["then"], sw["cells"]) == (1, 0, [[1, 8]])
    assert plain.last_finish[1] - greedy.last_finish[1] > 3.0
    assert greedy.last_finish[0] == pytest.approx(plain.last_finish[0], abs=0.5)
    assert greedy.summary()["agv_contacts"] == 0 == plain.summary()["agv_contacts"]
    # Nothing switched: the same motion as the plain graph's, to the last digit
    never = corridor("greedy", 0.0, paths=LONG_PATHS, grid=LONG, reorder_margin_s=1e6)
    np.testing.assert_array_equal(never.last_finish, plain.last_finish)


def test_a_new_plan_stops_an_agv_that_gave_back_its_claims():
    # AGV 0, delayed at full speed, gives back its claims (nothing is switched: margin)
    # but keeps its stop point; a new plan that ends where it will stand must bring its
    # stop point back with it (else it would drive on past its plan once the delay ends).
    layout = build_layout(LayoutSpec(grid=LONG))
    ex = PhysicsExecutor(ExecutorSpec(name="physics", reorder="greedy",
                                      reorder_margin_s=1e6))
    ex.bind(ExecutorSetup(layout=layout, tick_s=1.0, rng=np.random.default_rng(0),
                          agvs=tuple(AgvBody(i, 1, AgvTypeSpec(), LONG_PATHS[i].states[0])
                                     for i in range(2))))
    plans = dict(LONG_PATHS)
    f, st = ex.follow, ex.follow.st

    def step(tick: int) -> None:
        ex.step(TickView(tick=tick, plans=MappingProxyType(dict(plans)), behind=(0, 0),
                         failed=frozenset(), loaded=(False, False), carried=(None, None),
                         task_state=(0, 0)))

    def claims_end() -> float:
        return st.cur_end[0] + len(ex.adg.claimed(0)) * st.cell_m

    for tick in range(3):
        step(tick)
    ex.delayed_until[0] = 3.0 + 5.0
    step(3)
    step(4)
    assert 0 in f._given_back and st.stop_s[0] > claims_end()
    node = ex.adg.cut_node(0)
    plans[0] = TimedPath(0, 5, ((node, node),))
    step(5)
    assert ex.adg.upcoming(0) == ex.adg.claimed(0)
    assert st.stop_s[0] <= claims_end() + 1e-9
    for tick in range(6, 20):
        step(tick)
    assert ex.adg.done(0) and ex.summary()["agv_contacts"] == 0


def test_no_switch_that_does_not_win_the_margin():
    plain = corridor("none", 8.0)
    greedy = corridor("greedy", 8.0, reorder_margin_s=30.0)  # it would win ~10 s
    assert switches(greedy) == []
    assert greedy.summary()["reorder_candidates"] >= 1
    np.testing.assert_array_equal(plain.last_finish, greedy.last_finish)
    # AGV 0 only a moment late: standing, AGV 1 is never a candidate (it has not stopped
    # yet when AGV 0 passes); driving up to the corridor (reorder_ahead_s) it is, and goes
    # first without stopping: AGV 0 waits for it, and the two finish sooner in all
    assert corridor("greedy", 0.5, reorder_ahead_s=0.0).summary()[
        "reorder_candidates"] == 0
    late, plain = corridor("greedy", 0.5), corridor("none", 0.5)
    (sw,) = switches(late)
    assert sw["driving"] and sw["cost_s"] > 0
    assert late.last_finish[0] > plain.last_finish[0]
    assert late.last_finish.sum() < plain.last_finish.sum() - 1.0


def test_milp_chooses_the_switch_and_falls_back_to_greedy_without_an_optimum():
    greedy = corridor("greedy", 8.0)
    milp = corridor("milp", 8.0, reorder_milp_band_s=None)
    assert switches(milp) == switches(greedy)
    assert milp.summary()["reorder_milp_solves"] >= 1
    assert milp.summary()["reorder_milp_fallbacks"] == 0
    # The lone candidate wins ~8 s, far beyond the margin: clear-cut, no program
    clear = corridor("milp", 8.0)
    assert switches(clear) == switches(greedy)
    assert clear.summary()["reorder_milp_solves"] == 0
    assert clear.summary()["reorder_milp_clear"] >= 1
    # A time limit the solver cannot meet: every decision falls back to the greedy rule.
    late = corridor("milp", 8.0, reorder_time_limit_s=1e-9, reorder_milp_band_s=None)
    assert late.summary()["reorder_milp_fallbacks"] >= 1
    assert switches(late) == switches(greedy)
    np.testing.assert_array_equal(late.last_finish, greedy.last_finish)
    # A program over the size limit is not solved: the greedy rule decides.
    large = corridor("milp", 8.0, reorder_milp_max_vars=1, reorder_milp_band_s=None)
    assert large.summary()["reorder_milp_solves"] == 0
    assert large.summary()["reorder_milp_large"] >= 1
    assert switches(large) == switches(greedy)
    np.testing.assert_array_equal(large.last_finish, greedy.last_finish)


@pytest.mark.parametrize("limit", [None, 1])
def test_milp_programs_over_the_size_limit_are_decided_as_greedy_decides(plan40, limit,
                                                                         monkeypatch):
    # With every program over the limit, milp decides as greedy does, run for run; with
    # no limit it solves programs.
    from warerover_phys.executors.reorder import Reorderer

    init = Reorderer.__init__

    def spec_set(self, st, adg, spec, *args, **kwargs):
        spec = spec.model_copy(update={"reorder_milp_max_vars": limit,
                                       "reorder_milp_band_s": None})
        init(self, st, adg, spec, *args, **kwargs)

    greedy = gap(plan40, "greedy", seed=3)
    monkeypatch.setattr(Reorderer, "__init__", spec_set)
    milp = gap(plan40, "milp", seed=3)
    s = milp.run.summary
    if limit == 1:
        assert s["reorder_milp_solves"] == 0 and s["reorder_milp_large"] >= 1
        assert milp.run.executed == greedy.run.executed
    else:
        assert s["reorder_milp_solves"] >= 1 and s["reorder_milp_large"] == 0


def audit(ex: PhysicsExecutor) -> dict[str, float]:
    s = ex.summary()
    return {k[len("reorder_audit_"):-2]: v for k, v in s.items()
            if k.startswith("reorder_audit_")}


def test_the_audit_splits_the_waits_by_what_holds_them():
    # declined: a switch was possible but not worth the margin; the whole wait is there
    declined = corridor("greedy", 8.0, reorder_margin_s=30.0)
    got = audit(declined)
    wait = declined.summary()["delay_dependency_wait_s"]
    # (then it waits while AGV 0 drives off the cells: held_moving)
    assert set(got) == {"declined", "held_moving"} and got["declined"] > 5
    assert sum(got.values()) == pytest.approx(wait, abs=1.0)
    # switched: the wait ends at the first decision that finds it; switched as it drives
    # up (reorder_ahead_s), AGV 1 does not wait at all
    assert set(audit(corridor("greedy", 8.0, reorder_ahead_s=0.0))) == {"switched"}
    assert audit(corridor("greedy", 8.0)) == {}
    # held: AGV 1 drives right behind AGV 0, which is delayed standing on the next cell
    behind = {0: TimedPath(0, 0, ((1, 1), (2, 2), (3, 3), (4, 4), (5, 5))),
              1: TimedPath(1, 0, ((0, 0), (0, 0), (1, 1), (2, 2), (3, 3), (4, 4)))}
    held = corridor("greedy", 8.0, paths=behind)
    got = audit(held)
    assert got["held_delayed"] > 5 and not got.get("declined") and not got.get("switched")
    assert sum(got.values()) == pytest.approx(held.summary()["delay_dependency_wait_s"],
                                              abs=1.0)
    assert held.summary()["reorder_switches"] == 0
    # a chain: AGV 2 waits behind AGV 1, which waits behind the delayed AGV 0
    chain = {0: TimedPath(0, 0, ((2, 2), (3, 3), (4, 4), (5, 5))),
             1: TimedPath(1, 0, ((1, 1), (1, 1), (2, 2), (3, 3), (4, 4))),
             2: TimedPath(2, 0, ((0, 0), (0, 0), (0, 0), (1, 1), (2, 2), (3, 3)))}
    got = audit(corridor("greedy", 8.0, paths=chain))
    assert got["chain_held_delayed"] > 5 and got["held_delayed"] > 5 and not got.get("switched")


def test_reorder_settings_are_checked():
    with pytest.raises(ValidationError):
        ExecutorSpec(name="physics", reorder="sometimes")
    with pytest.raises(ValidationError):
        ExecutorSpec(name="physics", reorder="milp", reorder_node_limit=0)


def test_slowdown_is_the_expected_share_of_time_held_by_delays():
    from warerover_phys.execute import parse_delays

    assert slowdown(parse_delays(None)) == 1.0
    # a delay starts with p = 0.1 per free tick and lasts 5.5 ticks on average
    assert slowdown(parse_delays("bernoulli:0.1")) == pytest.approx(1.55)
    assert slowdown(parse_delays("poisson:0.1:2:2")) == pytest.approx(
        1 + 2 * (1 - math.exp(-0.1)))


# --------------------------------------------------------------------------- fleets


@pytest.fixture(scope="module")
def plan40(tmp_path_factory):
    """A LaCAM plan of 40 agents on random-32-32-10 (the project's planner)."""
    from warerover_phys.planning.oneshot.core import solve, write_plan
    from warerover_phys.problems.movingai import read_map, read_scen

    m = read_map(REPO / "tests" / "data" / "random-32-32-10.map")
    agents = read_scen(REPO / "tests" / "data" / "random-32-32-10-random-1.scen", 40)
    res = solve(m.obstacles, [a.start for a in agents], [a.goal for a in agents],
                planner="lacam", time_limit_s=30)
    out = tmp_path_factory.mktemp("reorder") / "plan40.txt"
    write_plan(out, res)
    return out


def gap(plan_file, mode: str, seed: int = 1):
    from warerover_phys.gap.core import plan_gap

    return plan_gap(REPO / "tests" / "data" / "random-32-32-10.map", plan_file,
                    delays="bernoulli:0.2", reorder=mode, seed=seed)


@pytest.mark.parametrize("mode", ["greedy", "milp"])
def test_reordered_runs_are_deterministic_safe_and_in_plan_order(plan40, mode):
    a, b = gap(plan40, mode), gap(plan40, mode)
    s = a.run.summary
    assert s["reorder_switches"] >= 1 and s["agv_contacts"] == 0 and s["deadlocks"] == 0
    assert a.report["completed"]
    assert a.run.executed == b.run.executed
    assert [e for e in a.run.events if e["event"] == "reorder"] == \
        [e for e in b.run.events if e["event"] == "reorder"]
    assert [r["executed_finish_s"] for r in a.agents] == \
        [r["executed_finish_s"] for r in b.agents]
    plan = a.run.plan
    assert check_executed({i: p.states for i, p in plan.paths.items()}, a.run.executed,
                          plan.layout.cols) == []
    # the space-time check of the recorded bodies: no two met, between samples too
    from warerover_phys.spacetime import from_trajectory, validate_spacetime

    assert validate_spacetime(from_trajectory(a.run.trajectory)).colliding_pairs == 0
    # the lost-time parts still add up for every AGV, the gain is <= 0 and counted
    for row in a.agents:
        assert math.isclose(sum(row[f"lost_{p}_s"] for p in PARTS), row["lost_s"],
                            abs_tol=1e-9)
        assert row["lost_reorder_gain_s"] <= 0 <= row["lost_dependency_s"]
    assert a.report["lost_reorder_gain_s_fleet_total"] < 0


def test_check_executed_finds_a_wrong_order_and_a_shared_cell(plan40):
    g = gap(plan40, "none")
    plan = g.run.plan
    planned = {i: p.states for i, p in plan.paths.items()}
    cols = plan.layout.cols
    assert check_executed(planned, g.run.executed, cols) == []
    movers = [i for i, s in g.run.executed.items() if len({a for a, _ in s}) > 2]
    i, j = movers[:2]
    wrong = dict(g.run.executed)
    wrong[i] = wrong[i][:1] + wrong[i][2:][::-1]  # the same cells, another order
    assert any(f"AGV {i} " in p for p in check_executed(planned, wrong, cols))
    clash = dict(g.run.executed)
    clash[j] = [g.run.executed[i][0]] * len(clash[j])  # j stands where i starts
    assert any("both hold cell" in p for p in check_executed(planned, clash, cols))


# --------------------------------------------------------------------------- property


def execute_with_delays(layout, paths, sizes, mode: str, p: float, seed: int):
    """Execute ``paths`` on physics with random delays; executed states per tick."""
    from warerover_phys.config import DelaySpec

    n = len(paths)
    ids = sorted(paths)
    assert ids == list(range(n))
    spec = ExecutorSpec(name="physics", reorder=mode,
                        delays=DelaySpec(model="bernoulli", prob=p, max_ticks=6))
    ex = PhysicsExecutor(spec)
    ex.bind(ExecutorSetup(layout=layout, tick_s=1.0, rng=np.random.default_rng(seed),
                          agvs=tuple(AgvBody(i, sizes[i], AgvTypeSpec(footprint=sizes[i]),
                                             paths[i].states[0]) for i in ids)))
    plans = MappingProxyType(dict(paths))
    executed = {i: [paths[i].states[0]] for i in ids}
    for tick in range(400):
        rep = ex.step(TickView(tick=tick, plans=plans, behind=(0,) * n, failed=frozenset(),
                               loaded=(False,) * n, carried=(None,) * n,
                               task_state=(0,) * n))
        for i, s in rep.states.items():
            executed[i].append(s)
        if all(ex.adg.done(i) for i in ids) and (ex.mode == 0).all():
            return ex, executed
    raise AssertionError("not finished in 400 ticks")


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(instances(), st.integers(0, 2**32 - 1), st.floats(0.1, 0.4),
       st.sampled_from(["greedy", "milp"]))
def test_reordered_physics_runs_keep_every_plan_and_never_collide(instance, seed, p, mode):
    from test_adg import rotation_agvs

    layout, paths, sizes, _, trajs = instance
    assume(rotation_agvs(trajs, sizes, layout.cols) is None)  # (no order exists)
    ex, executed = execute_with_delays(layout, paths, sizes, mode, p, seed)
    s = ex.summary()
    event(f"{mode}: {'switched' if s['reorder_switches'] else 'no switch'}")
    assert s["agv_contacts"] == 0 and s["deadlocks"] == 0
    assert check_executed({i: q.states for i, q in paths.items()}, executed, layout.cols,
                          sizes) == []
    ex.adg.check_acyclic()


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(15, 40), st.integers(0, 2**32 - 1), st.floats(0.1, 0.3),
       st.sampled_from(["greedy", "milp"]))
def test_reordered_fleets_keep_every_plan_and_never_collide(plan40, n, seed, p, mode):
    from warerover_phys.execute import load_floor, plan_to_paths
    from warerover_phys.plans import read_plan

    layout, _, _ = load_floor(REPO / "tests" / "data" / "random-32-32-10.map")
    full = plan_to_paths(read_plan(plan40), layout.cols)
    paths = {i: TimedPath(i, full[i].start_tick, full[i].states) for i in range(n)}
    ex, executed = execute_with_delays(layout, paths, dict.fromkeys(range(n), 1), mode, p,
                                       seed)
    s = ex.summary()
    event(f"{mode}: {'switched' if s['reorder_switches'] else 'no switch'}")
    assert s["agv_contacts"] == 0 and s["deadlocks"] == 0
    assert check_executed({i: q.states for i, q in paths.items()}, executed,
                          layout.cols) == []



@pytest.mark.parametrize("mode", ["greedy", "milp"])
def test_kept_candidates_and_early_refusals_agree_with_a_fresh_look(plan40, mode,
                                                                    monkeypatch):
    # With the check on, every kept candidate is compared with a fresh one, every cycle
    # the early search finds must be found by the insertions too, and the graph is
    # checked acyclic after every switch; the run is the same as without the check.
    from functools import partial

    from warerover_phys.executors import reorder

    plain = gap(plan40, mode, seed=3)
    monkeypatch.setattr(reorder, "SwitchableGraph",
                        partial(reorder.SwitchableGraph, check=True))
    checked = gap(plan40, mode, seed=3)
    s = checked.run.summary
    assert s["reorder_switches"] >= 1 and s["reorder_refused"] >= 1
    assert checked.run.executed == plain.run.executed
    assert s["reorder_refused"] == plain.run.summary["reorder_refused"]

def test_a_group_refused_for_a_cycle_is_not_tried_again(plan40, monkeypatch):
    from warerover_phys.executors.switch import SwitchableGraph

    refused: list[tuple] = []
    switch = SwitchableGraph.switch

    def spy(self, group):
        before = self.refused
        done = switch(self, group)
        if self.refused > before:
            refused.append(group.pairs)  # (the visits themselves: identity)
        return done

    monkeypatch.setattr(SwitchableGraph, "switch", spy)
    a = gap(plan40, "greedy", seed=3)
    s = a.run.summary
    assert len(refused) == s["reorder_refused"] >= 1
    # (the plan does not change in the run: every group kept lives to its end)
    assert len(set(refused)) == len(refused)
    assert s["agv_contacts"] == 0 and s["deadlocks"] == 0 and a.report["completed"]


@pytest.mark.parametrize("seed", [0, 1])
def test_in_the_lifelong_loop_no_agv_drives_towards_a_cell_not_released_to_it(
        monkeypatch, seed):
    """``warerover run`` with reordering: the planner changes plans every tick while
    delayed AGVs give back claims and others are switched ahead. After every plan
    hand-over and every decision, each driving AGV's stop point lies within the actions
    released to it (else it would drive into a cell another AGV may take first)."""
    from warerover_phys import load_scenario
    from warerover_phys.config import parse_override
    from warerover_phys.executors.fleet_state import DRIVE
    from warerover_phys.executors.follow import LOOKAHEAD, PlanFollower
    from warerover_phys.sim import Simulation

    bad: list[tuple] = []
    checks = {"n": 0, "given_back": 0}

    def check(f: PlanFollower) -> None:
        st = f.st
        checks["n"] += 1
        checks["given_back"] += len(f._given_back)
        for i in np.flatnonzero(st.mode == DRIVE).tolist():
            room = st.cur_end[i] + len(f.adg.released(i, LOOKAHEAD)) * st.cell_m
            if st.stop_s[i] > room + 1e-6:
                bad.append((i, float(st.stop_s[i]), float(room)))

    sync, advance = PlanFollower.sync_plans, PlanFollower.advance

    def sync_checked(self, view):
        sync(self, view)
        check(self)

    def advance_checked(self, pos, ang, delayed, decide):
        advance(self, pos, ang, delayed, decide)
        if decide:
            check(self)

    monkeypatch.setattr(PlanFollower, "sync_plans", sync_checked)
    monkeypatch.setattr(PlanFollower, "advance", advance_checked)
    ov = [parse_override(x) for x in (
        "executor=physics", "executor.reorder=greedy", "executor.delays.model=bernoulli",
        "executor.delays.prob=0.2", "max_ticks=150")]
    sim = Simulation(load_scenario(REPO / "layouts" / "warerover_basic.yaml", ov), seed)
    m = sim.run().metrics
    assert bad == []
    assert checks["given_back"] > 0 and m["reorder_switches"] > 0
    assert m["agv_contacts"] == 0 and m["static_contacts"] == 0


# --------------------------------------------------------------------- clairvoyant estimates


def test_foresight_foretells_every_delay_the_executor_draws(plan40):
    """``reorder_estimates: clairvoyant``: the replayed draws are the executor's delays,
    each start and end bit for bit, and the run stays safe and in plan order."""
    from warerover_phys.execute import parse_delays
    from warerover_phys.gap.ideal_plan import plan_from_file
    from warerover_phys.gap.open_loop import execute_timed

    plan, _ = plan_from_file(str(REPO / "tests" / "data" / "random-32-32-10.map"),
                             str(plan40), None)
    spec = ExecutorSpec(name="physics", delays=parse_delays("bernoulli:0.2"),
                        trajectory_hz=1.0, reorder="greedy",
                        reorder_estimates="clairvoyant")
    seen: set[tuple[int, float]] = set()
    last: dict[int, float] = {}
    box = {}

    def spy(tick, ex):
        box["ex"], box["t"] = ex, ex.state.sim_s
        for a, until in enumerate(ex.state.delayed_until.tolist()):
            if until > 0 and last.get(a) != until:
                seen.add((a, until))
                last[a] = until

    runs = [execute_timed(plan, spec, seed=3, before_tick=spy) for _ in range(2)]
    fore = box["ex"].follow.reorder.foresight
    told = {(a, e) for a in range(plan.num_agents) for s, e in fore.intervals(a)
            if s < box["t"]}  # drawn before the last look
    assert len(seen) > 100 and told == seen
    assert runs[0].executed == runs[1].executed
    assert runs[0].summary["reorder_switches"] >= 1 and runs[0].summary["agv_contacts"] == 0
    assert check_executed({i: p.states for i, p in plan.paths.items()}, runs[0].executed,
                          plan.layout.cols) == []


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.05, 0.5), st.floats(0, 80), st.floats(0, 30))
def test_foresight_after_is_the_first_time_with_that_much_time_not_held(seed, p, t0, d):
    """``DelayForesight.after(a, t0, d)``: the first time by which AGV ``a`` has had ``d``
    seconds not held by a delay since ``t0``, against the intervals it foretells."""
    from warerover_phys.execute import parse_delays
    from warerover_phys.executors.delays import DelayForesight

    fore = DelayForesight(np.random.default_rng(seed), parse_delays(f"bernoulli:{p}"), 3,
                          t0_s=0.0, tick_s=1.0, dt_s=0.02)
    for a in range(3):
        t = fore.after(a, t0, d)
        held = fore.intervals(a)

        def free(x, y, held=held):
            return (y - x) - sum(max(0.0, min(e, y) - max(s, x)) for s, e in held)

        assert t >= t0 + d - 1e-9 and fore.horizon_s >= t
        assert math.isclose(free(t0, t), d, abs_tol=1e-6)
        if d > 1e-6:  # the first such time: a millisecond earlier, less is free
            assert free(t0, t - 1e-3) < d
