"""Switching edges of the action dependency graph (executors/switch.py): a switch keeps the
graph acyclic, every AGV still drives exactly its plan's moves in order, nobody overlaps
and the execution never deadlocks, whatever the plans, delays and switches."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from test_adg import Execution, bound_for, build_or_skip, instances, planned_moves

from warerover_phys.executors.adg import build
from warerover_phys.executors.switch import SEARCH_LIMIT, Group, SwitchableGraph
from warerover_phys.planning.base import TimedPath

# A corridor (row 0) with a side cell below (1, 2) and an exit below (1, 3):
#   . . . . . .
#   # # i j # #
# AGV 0 enters the corridor at (0, 2) and drives east to (0, 5); AGV 1 drives east along
# the corridor behind it and leaves it down at (1, 3). The plan lets AGV 0 pass first.
COLS = 6
CORRIDOR = {0: TimedPath(0, 0, ((8, 8), (2, 2), (3, 3), (4, 4), (5, 5))),
            1: TimedPath(1, 0, ((0, 0), (1, 1), (1, 1), (2, 2), (3, 3), (9, 9)))}


def run_to_end(g, agv: int) -> None:
    while not g.done(agv):
        g.start(agv)
        g.finish(agv)


def test_a_waiting_agv_passes_first_over_the_cells_it_shares():
    g = build(CORRIDOR, {0: 1, 1: 1}, COLS)
    sg = SwitchableGraph(g, check=True)
    g.start(1)
    g.finish(1)  # AGV 1 stands at (0, 1); AGV 0 has not moved (it is late)
    assert not g.ready(1) and g.head(2) == 0
    grp = sg.candidate(1)
    assert (grp.first, grp.second, grp.cells) == (0, 1, (2, 3))
    g.wait_on(1)
    assert sg.switch(grp)
    assert 1 in g.woken and g.ready(1) and not g.ready(0)
    assert [v.agv for v in g.visits(2)] == [1, 0] and [v.agv for v in g.visits(3)] == [1, 0]
    run_to_end(g, 1)
    assert g.ready(0)
    run_to_end(g, 0)
    assert (sg.switches, sg.refused) == (1, 0)


def test_a_switch_that_would_close_a_cycle_is_refused_and_undone():
    # AGV 1's plan now ends on (0, 4), on AGV 0's way: it can pass first at (0, 2) and
    # (0, 3) but never leaves (0, 4), which AGV 0 must cross: no switch, nothing changed.
    paths = dict(CORRIDOR)
    paths[1] = TimedPath(1, 0, ((0, 0), (1, 1), (1, 1), (2, 2), (3, 3), (4, 4)))
    g = build(paths, {0: 1, 1: 1}, COLS)
    sg = SwitchableGraph(g, check=True)
    g.start(1)
    g.finish(1)
    before = {c: g.visits(c) for c in (2, 3, 4)}
    assert sg.candidate(1) is None  # (4) would have to switch too, and cannot
    q = g._queues
    grp = Group(0, 1, tuple((q[c][0], q[c][1]) for c in (2, 3)))
    assert not sg.switch(grp)
    assert {c: g.visits(c) for c in (2, 3, 4)} == before and sg.refused == 1
    assert not g.ready(1) and g.ready(0)


def test_a_single_cell_alone_would_close_a_cycle_but_the_run_switches():
    # Switching only (0, 2) would make AGV 1 wait for AGV 0 at (0, 3) while AGV 0 waits
    # for AGV 1 to leave (0, 2): a group is all of the shared run or nothing.
    g = build(CORRIDOR, {0: 1, 1: 1}, COLS)
    sg = SwitchableGraph(g, check=True)
    g.start(1)
    g.finish(1)
    grp = sg.candidate(1)
    half = type(grp)(grp.first, grp.second, grp.pairs[:1])
    assert not sg.switch(half)
    assert sg.switch(grp)



def test_on_a_held_cell_the_waiting_agv_passes_the_visits_behind_the_holder():
    # AGV 2 still stands on (0, 3), where AGV 0 (late) and then AGV 1 pass after it. AGV 1
    # may go first at (0, 2) only if it goes first at (0, 3) too (else it would wait
    # there for AGV 0, which waits for it at (0, 2)): it passes AGV 0 behind AGV 2.
    paths = {0: TimedPath(0, 0, ((8, 8), (2, 2), (3, 3), (4, 4), (5, 5))),
             1: TimedPath(1, 0, ((0, 0), (1, 1), (1, 1), (2, 2), (3, 3), (9, 9))),
             2: TimedPath(2, 0, ((3, 3), (3, 3), (4, 4), (10, 10)))}
    g = build(paths, {0: 1, 1: 1, 2: 1}, COLS)
    sg = SwitchableGraph(g, check=True)
    g.start(1)
    g.finish(1)
    grp = sg.candidate(1)
    assert (grp.first, grp.second, grp.cells) == (0, 1, (2, 3))
    assert sg.switch(grp)
    assert [v.agv for v in g.visits(3)] == [2, 1, 0]
    g.start(1)
    g.finish(1)  # AGV 1 on (0, 2): it waits for AGV 2 to leave (0, 3), AGV 0 for it
    assert not g.ready(1) and not g.ready(0) and g.ready(2)
    run_to_end(g, 2)
    run_to_end(g, 1)
    run_to_end(g, 0)
    assert (sg.switches, sg.refused) == (1, 0)

def test_visits_that_may_not_move_give_no_candidate():
    g = build(CORRIDOR, {0: 1, 1: 1}, COLS)
    sg = SwitchableGraph(g)
    g.start(1)
    g.finish(1)
    g.claim(0, 1)  # AGV 0 is committed to drive into (0, 2)
    assert sg.candidate(1) is None
    g.unclaim(0)
    g.start(0)  # AGV 0 enters (0, 2)
    assert sg.candidate(1) is None



def test_a_cycle_through_the_last_cell_is_refused_before_any_edge_goes_in(monkeypatch):
    # The group of the test above, without the tests' check: its cycle runs through the
    # edge of its last cell, (0, 3), so one search refuses it, and no edge of (0, 2) is
    # inserted (nor the order renumbered) first.
    paths = dict(CORRIDOR)
    paths[1] = TimedPath(1, 0, ((0, 0), (1, 1), (1, 1), (2, 2), (3, 3), (4, 4)))
    g = build(paths, {0: 1, 1: 1}, COLS)
    sg = SwitchableGraph(g)
    g.start(1)
    g.finish(1)
    sg._sync()
    order = dict(sg._ord)
    inserted = []
    insert = SwitchableGraph._insert
    monkeypatch.setattr(SwitchableGraph, "_insert",
                        lambda self, x, y, journal: inserted.append((x, y)) or insert(
                            self, x, y, journal))
    q = g._queues
    grp = Group(0, 1, tuple((q[c][0], q[c][1]) for c in (2, 3)))
    assert not sg.switch(grp)
    assert inserted == [] and sg._ord == order and sg.refused == 1
    assert [v.agv for v in g.visits(2)] == [0, 1] and [v.agv for v in g.visits(3)] == [0, 1]


def test_a_kept_candidate_follows_every_change_of_the_queues_it_read():
    g = build(CORRIDOR, {0: 1, 1: 1}, COLS)
    sg = SwitchableGraph(g)  # (no check: the kept answers themselves are tested)
    g.start(1)
    g.finish(1)
    grp = sg.candidate(1)
    assert grp is not None and sg.candidate(1) is grp  # nothing changed: kept
    g.claim(0, 1)  # AGV 0 is committed to drive into (0, 2)
    assert sg.candidate(1) is None
    g.unclaim(0)
    again = sg.candidate(1)
    assert again is not grp and (again.first, again.pairs) == (grp.first, grp.pairs)
    g.start(0)  # AGV 0 enters (0, 2)
    assert sg.candidate(1) is None
    g.finish(0)
    assert sg.candidate(1) is None  # it stands on it
    g.start(0)
    g.finish(0)  # it left (0, 2) for (0, 3): AGV 1 may enter (0, 2), nothing to switch
    assert g.ready(1) and sg.candidate(1) is None

SETTINGS = settings(max_examples=150, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.filter_too_much])


@SETTINGS
@given(instances(), st.integers(0, 2**32 - 1), st.floats(0.3, 1.0), st.integers(1, 4),
       st.floats(0.2, 1.0))
def test_random_switches_keep_the_graph_acyclic_and_every_plan_in_order(
        instance, seed, p, max_delay, p_switch):
    layout, paths, sizes, _, trajs = instance
    cols = layout.cols
    graph = build_or_skip(paths, sizes, trajs, cols)
    sg = SwitchableGraph(graph, check=True)  # check_acyclic after every switch
    rng = np.random.default_rng(seed ^ 0x5EED)
    late = {a: 0.1 for a in graph.agvs if rng.random() < 0.4}  # they start seldom
    ex = Execution(graph, sizes, cols, seed, p, max_delay, late)

    def switch_some(ex: Execution) -> None:
        for agv in graph.agvs:
            # an AGV with a running action drives: it may claim what is released to it,
            # and its candidate is for the first action it has not claimed (ahead)
            ahead = graph._agents[agv].running is not None
            if ahead and rng.random() < 0.5:
                graph.claim(agv, int(rng.integers(0, 3)))
            grp = sg.candidate(agv, ahead=ahead)
            if grp is not None and rng.random() < p_switch:
                done = sg.switch(grp)
                event(("driving " if ahead else "") + ("switched" if done else "refused"))
                if done and ahead:  # that action is released: it may drive on into it
                    assert len(graph.released(agv)) > len(graph.claimed(agv))
                elif done:
                    assert graph.ready(agv) or agv in ex.left
        graph.check_acyclic()
        assert graph.deadlock_cycles() == []

    ex.run(bound_for(graph, 0.1, max_delay), switch_some)
    for agv, path in paths.items():
        assert ex.done_moves[agv] == planned_moves(path.states)
        assert ex.where[agv] == (path.goal, path.goal)


@pytest.mark.parametrize("limit", [1, SEARCH_LIMIT])
def test_a_search_over_its_limit_refuses(limit):
    g = build(CORRIDOR, {0: 1, 1: 1}, COLS)
    sg = SwitchableGraph(g, check=True, search_limit=limit)
    g.start(1)
    g.finish(1)
    grp = sg.candidate(1)
    assert sg.switch(grp) is (limit > 1)


@SETTINGS
@given(instances())
def test_the_order_follows_the_plans_time(instance):
    # The order is built earliest planned start first, so that a switch's edge spans few
    # actions of it: every edge goes forward in it, and on a fresh plan (every edge from
    # a tick to a later or equal one) its planned ticks never go down.
    layout, paths, sizes, _, trajs = instance
    graph = build_or_skip(paths, sizes, trajs, layout.cols)
    sg = SwitchableGraph(graph)
    sg._sync()
    order = sg._ord
    assert sg._ok and sorted(order.values()) == list(range(len(order)))
    for s in order:
        for t in sg._succ(s):
            assert order[s] < order[t]
            assert s.action.tick <= t.action.tick
    ticks = [s.action.tick for s in sorted(order, key=order.__getitem__)]
    assert ticks == sorted(ticks)
