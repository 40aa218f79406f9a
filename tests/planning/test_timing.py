"""Duration-aware timing: the schedule keeps every dependency (no two AGVs on a cell at once),
a lone AGV takes its motion-model time, AGVs that never meet are timed as if alone, and the
paper scenarios' plans are scheduled."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from warerover_phys import load_scenario
from warerover_phys.config import AgvTypeSpec
from warerover_phys.executors.adg import ADGCycleError, path_moves
from warerover_phys.gap.ideal_plan import record_grid_run
from warerover_phys.planning.base import TimedPath, footprint_nodes
from warerover_phys.planning.motion import MotionModel, quarter_turns
from warerover_phys.planning.oneshot.core import solve
from warerover_phys.planning.timing import SCHEDULE_FORMAT, schedule, schedule_plan
from warerover_phys.validate import validate_states

EPS = 1e-9
SMALL = AgvTypeSpec(max_speed_mps=1.5, max_accel_mps2=1.0, max_turn_rate_radps=2.5)
OMNI = AgvTypeSpec(max_speed_mps=1.0, max_accel_mps2=0.5, drive="omni")


def occupancy(sched, paths, fleet, cols) -> dict[int, list[tuple[float, float, int]]]:
    """Per cell, the intervals ``(from_s, to_s, agv)`` each AGV's footprint covers it in the
    schedule: from the start of the move that enters it (0 for its start cells) to the
    finish of the move that leaves it (infinity for its last cells)."""
    out: dict[int, list[tuple[float, float, int]]] = {}
    for i, path in paths.items():
        k = fleet[i].footprint
        since = dict.fromkeys(footprint_nodes(path.states[0][0], k, cols), 0.0)
        for a in sched.actions[i]:
            src, dst = set(footprint_nodes(a.src, k, cols)), set(footprint_nodes(a.dst, k, cols))
            for c in dst - src:
                since[c] = a.start_s
            for c in src - dst:
                out.setdefault(c, []).append((since.pop(c), a.finish_s, i))
        for c, t in since.items():
            out.setdefault(c, []).append((t, math.inf, i))
    return out


def assert_no_shared_cell(sched, paths, fleet, cols) -> None:
    """The independent check: no two AGVs hold a cell at the same time (touching ends are
    fine: one leaves as the next enters)."""
    for c, spans in occupancy(sched, paths, fleet, cols).items():
        spans.sort()
        for (a0, a1, i), (b0, b1, j) in zip(spans, spans[1:], strict=False):
            assert i == j or b0 >= a1 - 1e-7, (divmod(c, cols), (a0, a1, i), (b0, b1, j))


def assert_consistent(sched) -> None:
    for row in sched.actions.values():
        prev = 0.0
        for a in row:
            assert a.start_s >= prev + a.turn_s - 1e-7
            assert a.start_s >= a.ready_s - 1e-7  # every dependency respected
            assert a.finish_s > a.start_s
            prev = a.finish_s


def alone_time(path: TimedPath, spec: AgvTypeSpec, cols: int) -> float:
    """A lone AGV: its runs from rest to rest plus its turns (facing east at the start)."""
    m = MotionModel.of(spec, 1.0)
    moves = path_moves(path, cols)
    total, heading, run = 0.0, (0, 1), 0
    for src, dst, _, _ in moves:
        d = divmod(dst, cols)[0] - divmod(src, cols)[0], divmod(dst, cols)[1] - divmod(src, cols)[1]
        if d != heading:
            total += m.run_s(run) + m.turn_s(quarter_turns(heading, d))
            run = 0
        heading = d
        run += 1
    return total + m.run_s(run)


def to_paths(result, cols: int) -> dict[int, TimedPath]:
    return {i: TimedPath(i, 0, tuple((r * cols + c,) * 2 for r, c in p))
            for i, p in enumerate(result.paths)}


@st.composite
def instances(draw):
    rows, cols = draw(st.integers(3, 7)), draw(st.integers(3, 7))
    free = [(r, c) for r in range(rows) for c in range(cols)]
    n = draw(st.integers(1, min(6, len(free) // 2)))
    cells = draw(st.permutations(free))
    return np.zeros((rows, cols), dtype=bool), list(cells[:n]), list(cells[n:2 * n])


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(), st.sampled_from(["pibt", "astar"]), st.booleans())
def test_every_dependency_is_respected(inst, planner, omni):
    obstacles, starts, goals = inst
    result = solve(obstacles, starts, goals, planner=planner, time_limit_s=5)
    assume(result.success)
    rows, cols = obstacles.shape
    paths = to_paths(result, cols)
    assert validate_states({i: list(p.states) for i, p in paths.items()}, obstacles) == []
    fleet = [OMNI if omni and i % 2 else SMALL for i in range(len(paths))]
    try:
        sched = schedule(paths, fleet, cols=cols, rows=rows)
    except ADGCycleError:
        assume(False)  # a rotation: no execution order (the gap refuses such plans too)
    assert_consistent(sched)
    assert_no_shared_cell(sched, paths, fleet, cols)
    # Never faster than each AGV alone, and a lower bound of every AGV's finish.
    for i, p in paths.items():
        assert sched.finish_s[i] >= alone_time(p, fleet[i], cols) - 1e-7


@settings(max_examples=40, deadline=None)
@given(st.lists(st.sampled_from([(0, 1), (1, 0), (0, -1), (-1, 0)]), min_size=1,
                max_size=14), st.sampled_from([SMALL, OMNI]))
def test_a_single_agv_takes_its_motion_model_time(steps, spec):
    size = 31
    r = c = 15
    states = [(r * size + c,) * 2]
    for dr, dc in steps:
        r, c = r + dr, c + dc
        states.append((r * size + c,) * 2)
        states.append(states[-1])  # a plan wait: dropped like the executor drops it
    path = TimedPath(0, 0, tuple(states))
    sched = schedule({0: path}, [spec], cols=size, rows=size)
    assert sched.finish_s[0] == pytest.approx(alone_time(path, spec, size))
    assert sched.splits == 0 and sched.dependencies == 0
    assert sched.makespan_unit_s == 2 * len(steps) - 1  # the unit plan, waits included


@given(st.lists(st.lists(st.sampled_from([(0, 1), (1, 0), (0, -1), (-1, 0)]), min_size=1,
                         max_size=4), min_size=2, max_size=4))
def test_agvs_that_never_meet_are_timed_alone(walks):
    size = 10 * len(walks)
    paths, fleet = {}, []
    for i, steps in enumerate(walks):
        r, c = 5, 5 + 10 * i  # far apart: no cell in common
        states = [(r * size + c,) * 2]
        for dr, dc in steps:
            r, c = r + dr, c + dc
            states.append((r * size + c,) * 2)
        paths[i] = TimedPath(i, 0, tuple(states))
        fleet.append(SMALL if i % 2 == 0 else OMNI)
    both = schedule(paths, fleet, cols=size, rows=size)
    for i, p in paths.items():
        alone = schedule({0: TimedPath(0, 0, p.states)}, [fleet[i]], cols=size, rows=size)
        assert both.finish_s[i] == pytest.approx(alone.finish_s[0])
        assert [a.start_s for a in both.actions[i]] == pytest.approx(
            [a.start_s for a in alone.actions[0]])


def test_a_follower_waits_for_the_leader_and_a_run_is_split():
    """A 1 x 8 corridor: AGV 0 at column 2 goes to 7, AGV 1 follows from 0 to 5 one cell
    behind. The follower may enter a cell only once the leader's move out of it finished."""
    cols = 8
    lead = TimedPath(0, 0, tuple((c, c) for c in (2, 3, 4, 5, 6, 7)) + ((7, 7),))
    follow = TimedPath(1, 0, ((0, 0),) + tuple((c, c) for c in (1, 2, 3, 4, 5)) + ((5, 5),))
    slow = AgvTypeSpec(max_speed_mps=0.5, max_accel_mps2=0.5)
    sched = schedule({0: lead, 1: follow}, [slow, SMALL], cols=cols, rows=1)
    assert_consistent(sched)
    assert_no_shared_cell(sched, {0: lead, 1: follow}, [slow, SMALL], cols)
    assert sched.dependencies > 0
    # the slow leader alone; the fast follower is held back by it
    assert sched.finish_s[0] == pytest.approx(MotionModel.of(slow, 1.0).run_s(5))
    assert sched.finish_s[1] > MotionModel.of(SMALL, 1.0).run_s(5)


def test_a_communication_latency_delays_every_dependency():
    cols = 8
    lead = TimedPath(0, 0, tuple((c, c) for c in (2, 3, 4, 5, 6, 7)) + ((7, 7),))
    follow = TimedPath(1, 0, ((0, 0),) + tuple((c, c) for c in (1, 2, 3, 4, 5)) + ((5, 5),))
    paths = {0: lead, 1: follow}
    slow = AgvTypeSpec(max_speed_mps=0.5, max_accel_mps2=0.5)
    base = schedule(paths, [slow, SMALL], cols=cols, rows=1)
    late = schedule(paths, [slow, SMALL], cols=cols, rows=1, comm_latency_s=0.5)
    assert late.finish_s[0] == base.finish_s[0]  # the leader waits for no one
    assert late.finish_s[1] > base.finish_s[1]
    for a in late.actions[1]:
        assert a.start_s >= a.ready_s - 1e-9


def test_dwells_hold_and_turns_overlap_them():
    cols = 5
    # east 2 cells, dwell 3 ticks, then south 1 cell (a quarter turn during the dwell)
    path = TimedPath(0, 0, ((0, 0), (1, 1), (2, 2), (2, 2), (2, 2), (2, 2), (7, 7)))
    sched = schedule({0: path}, [SMALL], cols=cols, rows=3, dwells={0: ((3, 3),)}, tick_s=1.0)
    m = MotionModel.of(SMALL, 1.0)
    a = sched.actions[0]
    assert a[2].dwell_s == 3.0 and a[2].turn_s == pytest.approx(m.turn_s(1))
    assert a[2].start_s == pytest.approx(m.run_s(2) + 3.0)  # the turn fits in the dwell
    # a trailing dwell ends the AGV's plan
    s2 = schedule({0: path}, [SMALL], cols=cols, rows=3, dwells={0: ((3, 3), (7, 2))})
    assert s2.finish_s[0] == pytest.approx(sched.finish_s[0] + 2.0)


def test_payload_slows_loaded_moves_only_with_payloads():
    spec = AgvTypeSpec(mass_kg=100, payload_kg=100)
    path = TimedPath(0, 0, tuple((c, c) for c in range(5)))
    loaded = np.ones((5, 1), dtype=bool)
    plain = schedule({0: path}, [spec], cols=5, rows=1, loaded=loaded)
    heavy = schedule({0: path}, [spec], cols=5, rows=1, loaded=loaded, payload=True)
    assert heavy.finish_s[0] > plain.finish_s[0]
    assert heavy.finish_s[0] == pytest.approx(
        MotionModel.of(spec, 1.0, loaded=True, payload=True).run_s(4))


def test_a_rotation_has_no_schedule():
    # Four AGVs on a 2 x 2 square each move into the cell the next one leaves.
    cols = 2
    ring = [0, 1, 3, 2]
    paths = {i: TimedPath(i, 0, ((ring[i],) * 2, (ring[(i + 1) % 4],) * 2)) for i in range(4)}
    with pytest.raises(ADGCycleError):
        schedule(paths, [SMALL] * 4, cols=cols, rows=2)


@pytest.mark.parametrize(("path", "seed"), [("layouts/paper_homogeneous.yaml", 1),
                                            ("layouts/paper_heterogeneous.yaml", 1)])
def test_paper_plans_are_scheduled(path, seed):
    plan = record_grid_run(load_scenario(path).with_seed(seed))
    sched = schedule_plan(plan)
    fleet = plan.types
    assert_consistent(sched)
    assert_no_shared_cell(sched, plan.paths, fleet, plan.layout.cols)
    assert sched.dependencies > 0 and sched.splits > 0
    # motion timing costs more than one cell per tick here (acceleration, turns, 2x2 AGVs
    # at 0.75 m/s) and keeps the unit figures beside it
    assert sched.makespan_s > sched.makespan_unit_s
    assert sched.makespan_unit_s == max(plan.planned_finish(i) for i in range(plan.num_agents)) \
        * plan.tick_s
    for i in range(plan.num_agents):
        assert sched.finish_unit_s[i] == plan.planned_finish(i) * plan.tick_s
    data = sched.to_json(plan.layout.cols, plan.source)
    assert data["format"] == SCHEDULE_FORMAT and data["timing"] == "motion"
    assert len(data["agvs"]) == plan.num_agents
    assert data["makespan_s"] == sched.makespan_s
    # deterministic
    assert schedule_plan(plan).finish_s == sched.finish_s
    # A pass limit that cuts the search short falls back to splitting wherever a move is
    # late: still every dependency kept, never earlier than the settled schedule.
    lay = plan.layout
    cut = schedule(plan.paths, plan.types, cols=lay.cols, rows=lay.rows, cell_m=lay.cell_m,
                   tick_s=plan.tick_s, dwells=dict(plan.dwell_view), max_passes=1)
    assert_consistent(cut)
    assert_no_shared_cell(cut, plan.paths, fleet, lay.cols)
    assert cut.makespan_s >= sched.makespan_s - 1e-9


def test_downtime_holds_a_run_and_delays_what_follows():
    path = TimedPath(0, 0, tuple((c, c) for c in range(7)))
    m = MotionModel.of(SMALL, 1.0)
    base = schedule({0: path}, [SMALL], cols=7, rows=1)
    # down before it starts: the run starts when it is up again
    before = schedule({0: path}, [SMALL], cols=7, rows=1, downtime={0: [(0.0, 3.0)]})
    assert before.actions[0][0].start_s == pytest.approx(3.0)
    assert before.finish_s[0] == pytest.approx(3.0 + m.run_s(6))
    # down while it drives (2.5 s in: 2.625 m at 1.5 m/s): it brakes at its limit to a
    # stop at 3.75 m (the move ending at 3 m finishes while braking) and drives the last
    # 2.25 m from rest when it is up again at 6.5 s
    mid = schedule({0: path}, [SMALL], cols=7, rows=1, downtime={0: [(2.5, 6.5)]})
    assert m.state_at(2.5, 6.0) == pytest.approx((2.625, 1.5))
    assert mid.finish_s[0] == pytest.approx(6.5 + m.distance_s(2.25))
    assert mid.actions[0][2].finish_s == pytest.approx(2.5 + 1.5 - math.sqrt(1.5))
    assert mid.actions[0][3].start_s == pytest.approx(mid.actions[0][2].finish_s)
    assert mid.actions[0][3].finish_s == pytest.approx(6.5 + m.at_s(0.25, 2.25))
    for a, b in zip(base.actions[0][:2], mid.actions[0][:2], strict=True):
        assert b.finish_s == pytest.approx(a.finish_s)
    # a turn the window interrupts is done again after it
    turn = TimedPath(0, 0, ((8, 8), (1, 1), (1, 1)))  # (1, 1) -> (0, 1): north, a quarter
    t = schedule({0: turn}, [SMALL], cols=7, rows=2, downtime={0: [(0.2, 2.0)]})
    assert t.actions[0][0].start_s == pytest.approx(2.0 + m.turn_s(1))
    # down after it is done: nothing changes
    after = schedule({0: path}, [SMALL], cols=7, rows=1, downtime={0: [(50.0, 60.0)]})
    assert after.finish_s == base.finish_s


def test_schedule_poses_pass_the_space_time_check_and_a_shifted_one_does_not():
    """A follower that waits for its leader in the schedule never meets it in continuous
    time (:mod:`warerover_phys.spacetime`); with the leader started 3 s late (the
    dependency dropped) the follower runs into its body, and the check says so."""
    from dataclasses import replace

    from warerover_phys.spacetime import from_schedule, validate_spacetime

    cols = 8
    # Leader 0 at (0, 1) drives east to (0, 5); follower 1 at (0, 0) follows one cell behind.
    lead = TimedPath(0, 0, tuple((c, c) for c in (1, 1, 2, 3, 4, 5, 5, 5)))
    follow = TimedPath(1, 0, tuple((c, c) for c in (0, 0, 0, 1, 2, 3, 4, 4)))
    paths = {0: lead, 1: follow}
    fleet = [SMALL, SMALL]
    sched = schedule(paths, fleet, cols=cols, rows=1)
    poses = sched.poses(cols, {0: 1, 1: 0})
    assert poses[1][0] == ((0, 0), 0, 0.0) and poses[0][-1][0] == (0, 5)
    for entries in poses.values():
        assert all(b[2] > a[2] for a, b in zip(entries, entries[1:], strict=False))
    body = {0: (0.7, 0.7), 1: (0.7, 0.7)}
    ok = validate_spacetime(from_schedule(poses, body_m=body), shelves=False)
    assert ok.ok, [str(c) for c in ok.conflicts]
    late = {0: tuple(replace(a, start_s=a.start_s + 3.0, finish_s=a.finish_s + 3.0)
                     for a in sched.actions[0]), 1: sched.actions[1]}
    bad = replace(sched, actions=late).poses(cols, {0: 1, 1: 0})
    found = validate_spacetime(from_schedule(bad, body_m=body), shelves=False)
    assert not found.ok and found.conflicts[0].agvs == (0, 1)
