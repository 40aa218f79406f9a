"""Action Dependency Graph: actions from timed paths, per-cell queues, commit cut, cycles,
and randomly delayed executions of planned instances (no overlap, no deadlock)."""

from __future__ import annotations

import doctest

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from warerover_phys.config import LayoutSpec
from warerover_phys.executors import adg as adg_module
from warerover_phys.executors.adg import ActionGraph, ADGCycleError, build
from warerover_phys.layout import build_layout
from warerover_phys.planning import (
    AgentRequest,
    AStarPlanner,
    CBSPlanner,
    GraphSet,
    PlanRequest,
    ReservationTable,
    TimedPath,
)
from warerover_phys.validate import validate_states

# --------------------------------------------------------------------------- helpers


def stand(*nodes: int) -> tuple[tuple[int, int], ...]:
    """States of a 1-tick-per-cell path through ``nodes`` (repeat a node to wait)."""
    return tuple((n, n) for n in nodes)


def cells(anchor: int, k: int, cols: int) -> set[int]:
    """Footprint, computed independently of the package."""
    r, c = divmod(anchor, cols)
    return {(r + i) * cols + c + j for i in range(k) for j in range(k)}


def occupied(state: tuple[int, int], k: int, cols: int) -> set[int]:
    return cells(state[0], k, cols) | cells(state[1], k, cols)


def planned_moves(states) -> list[tuple[int, int]]:
    """The cell moves of a path, computed from its states alone."""
    anchors: list[int] = []
    for a, b in states:
        for n in (a, b):
            if not anchors or anchors[-1] != n:
                anchors.append(n)
    return list(zip(anchors, anchors[1:], strict=False))


def rotation_agvs(trajs: dict[int, list[tuple[int, int]]], sizes, cols) -> set[int] | None:
    """AGVs on a cycle of same-tick one-tick moves, each into a cell the next one leaves
    (valid for the validator, impossible to run without a common clock); None if none."""
    horizon = max(len(s) for s in trajs.values())

    def at(agv, t):
        s = trajs[agv]
        return s[min(t, len(s) - 1)]

    for t in range(horizon - 1):
        movers = {}
        for agv in trajs:
            (a, a2), (b, b2) = at(agv, t), at(agv, t + 1)
            if a == a2 and b == b2 and a != b:
                movers[agv] = (a, b)
        succ = {p: [q for q in movers if q != p and cells(movers[p][1], sizes[p], cols)
                    & cells(movers[q][0], sizes[q], cols)] for p in movers}
        for s in movers:  # DFS for a path back to s
            stack, seen = [(s, [s])], set()
            while stack:
                v, path = stack.pop()
                for w in succ[v]:
                    if w == s:
                        return set(path)
                    if w not in seen:
                        seen.add(w)
                        stack.append((w, path + [w]))
    return None


def make_layout(rows: list[str]):
    return build_layout(LayoutSpec(grid=rows))


@st.composite
def instances(draw):
    """Random small map with obstacles and 2..6 AGVs, some 2x2, some slow."""
    rows, cols = draw(st.integers(4, 8)), draw(st.integers(4, 8))
    density = draw(st.sampled_from([0.0, 0.1, 0.2]))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    obstacles = rng.random((rows, cols)) < density
    obstacles[rows - 1, cols - 2:] = False
    grid = [["#" if obstacles[r, c] else "." for c in range(cols)] for r in range(rows)]
    grid[rows - 1][cols - 1], grid[rows - 1][cols - 2] = "R", "S"
    layout = make_layout(["".join(r) for r in grid])
    free = [r * cols + c for r in range(rows) for c in range(cols) if not obstacles[r, c]]
    n = draw(st.integers(2, min(6, len(free) // 3)))
    starts, goals = rng.permutation(free), rng.permutation(free)
    graph2 = GraphSet(layout).get(2, False)
    agents: list[AgentRequest] = []
    taken: set[int] = set()
    for i in range(n):
        s, g = int(starts[i]), int(goals[i])
        k = 2 if (rng.random() < 0.5 and graph2.expandable(s) and graph2.expandable(g)) else 1
        if cells(s, k, cols) & taken or s == g:
            continue
        taken |= cells(s, k, cols)
        m = 2 if rng.random() < 0.3 else 1
        agents.append(AgentRequest(len(agents), s, g, k=k, ticks_per_move=m,
                                   priority=(int(rng.integers(3)),)))
    assume(len(agents) >= 2)
    planner = CBSPlanner(time_budget_s=0.2) if draw(st.booleans()) else AStarPlanner()
    res = ReservationTable(cols)
    for a in agents:
        res.commit(TimedPath(a.agv, 0, ((a.start, a.start),)), a.k)
    planner.plan(PlanRequest(0, agents, GraphSet(layout), res))
    paths = {a.agv: res.paths[a.agv] for a in agents}  # failed AGVs keep their resting path
    sizes = {a.agv: a.k for a in agents}
    speeds = {a.agv: a.ticks_per_move for a in agents}
    horizon = max(p.end_tick for p in paths.values()) + 2
    trajs = {aid: [p.state_at(t) for t in range(horizon)] for aid, p in paths.items()}
    conflicts = validate_states(trajs, layout.obstacles, sizes=sizes, ticks_per_move=speeds)
    assert conflicts == [], f"the planner made an invalid plan: {[str(c) for c in conflicts]}"
    return layout, paths, sizes, speeds, trajs


class Execution:
    """Discrete-event run of an ADG: each step finishes actions whose random delay is over,
    then starts each ready AGV's next action with probability ``p``."""

    def __init__(self, graph: ActionGraph, sizes, cols: int, seed: int, p: float,
                 max_delay: int, p_agv: dict[int, float] | None = None) -> None:
        self.graph, self.sizes, self.cols = graph, sizes, cols
        self.rng = np.random.default_rng(seed)
        self.p, self.max_delay = p, max_delay
        self.p_agv = p_agv or {}
        """Per AGV its own start probability instead of ``p`` (late AGVs)."""
        self.where = {a: graph.state(a) for a in graph.agvs}  # tracked by the test
        self.left: dict[int, int] = {}
        self.done_moves: dict[int, list[tuple[int, int]]] = {a: [] for a in graph.agvs}
        self.step_no = 0

    def step(self) -> None:
        g = self.graph
        for agv in sorted(self.left):
            self.left[agv] -= 1
            if self.left[agv] == 0:
                del self.left[agv]
                a = g.finish(agv)
                assert self.where[agv] == (a.src, a.dst)
                self.where[agv] = (a.dst, a.dst)
        for agv in self.rng.permutation(g.agvs).tolist():
            if agv not in self.left and g.ready(agv) and \
                    self.rng.random() < self.p_agv.get(agv, self.p):
                a = g.start(agv)
                assert self.where[agv] == (a.src, a.src)
                self.where[agv] = (a.src, a.dst)
                self.left[agv] = int(self.rng.integers(1, self.max_delay + 1))
                self.done_moves[agv].append((a.src, a.dst))
        self.step_no += 1
        self.check()

    def check(self) -> None:
        g, cols = self.graph, self.cols
        owner: dict[int, int] = {}
        for agv, state in self.where.items():
            assert g.state(agv) == state
            for c in occupied(state, self.sizes[agv], cols):
                assert c not in owner, (f"step {self.step_no}: AGVs {owner[c]} and {agv} "
                                        f"overlap on cell {divmod(c, cols)}")
                owner[c] = agv
        for agv in g.agvs:
            # Cells of released actions are free of every other AGV.
            for a in g.released(agv, 8):
                for c in a.enters:
                    assert owner.get(c, agv) == agv, (agv, a, owner.get(c))
        if not self.left and not all(g.done(a) for a in g.agvs):
            assert any(g.ready(a) for a in g.agvs), f"deadlock: {g.waiting_for()}"

    def run(self, bound: int, hook=None) -> None:
        g = self.graph
        while not all(g.done(a) for a in g.agvs):
            assert self.step_no < bound, f"not finished in {bound} steps: {g.waiting_for()}"
            self.step()
            if hook is not None:
                hook(self)


def bound_for(graph: ActionGraph, p: float, max_delay: int) -> int:
    total = sum(len(graph.upcoming(a)) for a in graph.agvs) + 1
    return int(total * (max_delay + 1 + 20 / p)) + 50


# --------------------------------------------------------------------------- actions


def test_module_examples_run():
    result = doctest.testmod(adg_module)
    assert result.attempted > 0 and result.failed == 0


def test_waits_are_dropped_and_a_slow_move_is_one_action():
    g = ActionGraph(cols=5, sizes={0: 1, 1: 1})
    g.set_plan(0, TimedPath(0, 3, stand(0, 0, 1, 1, 1, 2)))
    ups = g.upcoming(0)
    assert [(a.src, a.dst, a.tick, a.ticks) for a in ups] == [(0, 1, 4, 1), (1, 2, 7, 1)]
    assert [a.seq for a in ups] == [0, 1]
    g.set_plan(1, TimedPath(1, 0, ((5, 5), (5, 6), (5, 6), (6, 6), (6, 6), (6, 7), (7, 7))))
    assert [(a.src, a.dst, a.tick, a.ticks) for a in g.upcoming(1)] == [(5, 6, 0, 3),
                                                                      (6, 7, 4, 2)]
    assert g.upcoming(1, 1) == g.upcoming(1)[:1]


def test_enters_and_leaves_of_one_by_one_and_two_by_two_moves():
    g = ActionGraph(cols=5, sizes={0: 1, 1: 2, 2: 2})
    g.set_plan(0, TimedPath(0, 0, stand(20, 21)))
    a = g.next_action(0)
    assert (a.enters, a.leaves, a.direction) == ((21,), (20,), (0, 1))
    # 2x2 anchored at (0, 0) moves right: enters column 2, leaves column 0.
    g.set_plan(1, TimedPath(1, 0, stand(0, 1)))
    a = g.next_action(1)
    assert (set(a.enters), set(a.leaves), a.direction) == ({2, 7}, {0, 5}, (0, 1))
    # 2x2 anchored at (2, 3) moves up: enters row 1, leaves row 3.
    g.set_plan(2, TimedPath(2, 0, stand(13, 8)))
    a = g.next_action(2)
    assert (set(a.enters), set(a.leaves), a.direction) == ({8, 9}, {18, 19}, (-1, 0))


def test_malformed_paths_are_rejected():
    g = ActionGraph(cols=5, sizes={0: 1})
    with pytest.raises(ValueError, match="4-neighbour"):
        g.set_plan(0, TimedPath(0, 0, stand(0, 6)))
    with pytest.raises(ValueError, match="4-neighbour"):  # no wrap-around at a row's end
        g.set_plan(0, TimedPath(0, 0, stand(4, 5)))
    with pytest.raises(ValueError, match="does not end standing"):
        g.set_plan(0, TimedPath(0, 0, ((0, 0), (0, 1))))
    with pytest.raises(ValueError, match="start standing"):
        g.set_plan(0, TimedPath(0, 0, ((0, 1), (1, 1))))
    with pytest.raises(ValueError, match="path of AGV 1"):
        g.set_plan(0, TimedPath(1, 0, stand(0)))
    with pytest.raises(KeyError):
        g.set_plan(3, TimedPath(3, 0, stand(0)))
    assert g.agvs == ()  # nothing was registered by the failed calls


def test_registering_on_a_held_cell_is_rejected():
    g = ActionGraph(cols=5, sizes={0: 2, 1: 1})
    g.set_plan(0, TimedPath(0, 0, stand(0)))
    with pytest.raises(ValueError, match="held by AGV 0"):
        g.set_plan(1, TimedPath(1, 0, stand(6)))


# --------------------------------------------------------------------------- queues


def test_follower_is_ready_only_after_the_leader_left_the_cell():
    # One corridor row: the leader at 1 goes to 4, the follower at 0 goes to 3, in lockstep.
    g = build({0: TimedPath(0, 0, stand(1, 2, 3, 4)), 1: TimedPath(1, 0, stand(0, 1, 2, 3))},
              {0: 1, 1: 1}, cols=6)
    assert g.ready(0) and not g.ready(1)
    assert g.released(1) == [] and len(g.released(0)) == 3
    assert g.waiting_for() == {1: {0}}
    assert [v.agv for v in g.visits(1)] == [0, 1]
    g.start(0)
    assert not g.ready(1)  # the leader is moving out but still covers cell 1
    with pytest.raises(RuntimeError, match="not ready"):
        g.start(1)
    assert g.state(0) == (1, 2) and g.current(0).dst == 2
    g.finish(0)
    assert g.ready(1) and [v.agv for v in g.visits(1)] == [1]
    assert g.waiting_for() == {}
    a = g.start(1)
    assert (a.src, a.dst) == (0, 1)
    assert not g.ready(1)  # its own action runs
    # The follower's next cell (2) is still the leader's until the leader leaves it.
    assert g.released(1) == []
    g.start(0)
    g.finish(0)
    assert [a.dst for a in g.released(1)] == [2]  # the leader now stands on cell 3
    g.finish(1)
    assert g.ready(1)


def test_later_plan_takes_its_place_by_planned_tick():
    # AGV 1 will cross cell 2 at tick 8; AGV 0 registered later plans it at tick 3: first.
    g = ActionGraph(cols=5, sizes={0: 1, 1: 1})
    g.set_plan(1, TimedPath(1, 0, stand(7, 7, 7, 7, 7, 7, 7, 7, 2, 7)))
    g.set_plan(0, TimedPath(0, 0, stand(0, 1, 1, 2, 3)))
    assert [(v.agv, v.tick) for v in g.visits(2)] == [(0, 3), (1, 8)]
    g.check_acyclic()


def test_a_held_cell_stays_at_the_head_whatever_the_ticks():
    # AGV 0 plans cell 1 at tick 5; AGV 1 plans it at tick 1: AGV 1 goes first.
    g = ActionGraph(cols=5, sizes={0: 1, 1: 1, 2: 1})
    g.set_plan(0, TimedPath(0, 0, stand(0, 0, 0, 0, 0, 1, 0)))
    g.set_plan(1, TimedPath(1, 0, stand(2, 1, 6)))
    assert [(v.agv, v.tick) for v in g.visits(1)] == [(1, 1), (0, 5)]
    # Once AGV 0 has entered cell 1 (early), a visit planned for tick 1 queues behind it.
    g2 = ActionGraph(cols=5, sizes={0: 1, 1: 1})
    g2.set_plan(0, TimedPath(0, 0, stand(0, 0, 0, 0, 0, 1, 0)))
    g2.start(0)
    g2.finish(0)
    g2.set_plan(1, TimedPath(1, 0, stand(2, 1, 6)))
    assert [(v.agv, v.tick, v.entered) for v in g2.visits(1)] == [(0, 5, True), (1, 1, False)]
    assert not g2.ready(1) and g2.ready(0)


def test_claimed_cells_keep_their_place_and_survive_a_new_plan():
    """A driving AGV claims the released cells it will pass without stopping: a visit
    planned earlier by a later plan queues behind them (not ahead, as it would on an
    unclaimed cell), and the AGV's own new plan must start after them."""
    g = ActionGraph(cols=6, sizes={0: 1, 1: 1, 2: 1})
    g.set_plan(0, TimedPath(0, 0, stand(0, 0, 0, 1, 2, 3, 4)))  # cells 1..4 at ticks 3..6
    g.start(0)
    assert [a.dst for a in g.claim(0, 2)] == [2, 3]
    assert g.cut_node(0) == 3
    g.set_plan(1, TimedPath(1, 0, stand(9, 3, 9)))  # cell 3 (claimed) at tick 1
    g.set_plan(2, TimedPath(2, 0, stand(10, 4, 10)))  # cell 4 (not claimed) at tick 1
    assert [v.agv for v in g.visits(3)] == [0, 1]
    assert [v.agv for v in g.visits(4)] == [2, 0]
    with pytest.raises(ValueError, match="after the cut"):
        g.set_plan(0, TimedPath(0, 5, stand(1, 7)))
    g.set_plan(0, TimedPath(0, 5, stand(3, 4, 5)))
    assert [a.dst for a in g.upcoming(0)] == [2, 3, 4, 5]
    assert [v.agv for v in g.visits(4)] == [2, 0]
    g.check_acyclic()


def test_forced_start_ignores_dependencies():
    g = ActionGraph(cols=5, sizes={0: 1, 1: 1})
    g.set_plan(0, TimedPath(0, 0, stand(0, 1, 2)))
    g.set_plan(1, TimedPath(1, 0, stand(1, 6)))
    assert not g.ready(0)
    with pytest.raises(RuntimeError):
        g.start(0)
    assert g.start(0, force=True).dst == 1
    assert g.state(0) == (0, 1)


def test_commit_cut_keeps_the_running_action_and_reorders_later_visits():
    # Row 0: AGV 0 drives 0 -> 3. Below: AGV 1 pops up into cell 2 at tick 5 and back.
    g = build({0: TimedPath(0, 0, stand(0, 1, 2, 3)),
               1: TimedPath(1, 0, stand(7, 7, 7, 7, 7, 2, 7))}, {0: 1, 1: 1}, cols=5)
    assert [v.agv for v in g.visits(2)] == [0, 1]
    g.start(0)  # 0 -> 1 runs
    with pytest.raises(ValueError, match="after the cut"):
        g.set_plan(0, TimedPath(0, 0, stand(0, 1, 2)))
    # AGV 0 now waits on cell 1 until tick 10 before going on.
    g.set_plan(0, TimedPath(0, 1, stand(1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 2, 3)))
    run = g.current(0)
    assert (run.src, run.dst, run.seq) == (0, 1, 0)
    ups = g.upcoming(0)
    assert [(a.src, a.dst, a.tick, a.seq) for a in ups] == [(1, 2, 10, 3), (2, 3, 11, 4)]
    # The dropped actions' visits are gone, AGV 1 now crosses cell 2 first.
    assert [(v.agv, v.enter) for v in g.visits(3)] == [(0, 4)]
    assert [(v.agv, v.enter) for v in g.visits(2)] == [(1, 0), (0, 3)]
    # Cell 1 was entered by the running action: its visit stays at the head, left by seq 3.
    assert [(v.agv, v.enter, v.leave, v.entered) for v in g.visits(1)] == [(0, 0, 3, True)]
    # Cell 0 is still left by the running action.
    assert [(v.agv, v.enter, v.leave) for v in g.visits(0)] == [(0, None, 0)]
    g.check_acyclic()
    g.finish(0)
    assert not g.ready(0) and g.waiting_for() == {0: {1}}
    g.start(1)
    g.finish(1)
    g.start(1)
    g.finish(1)
    assert g.done(1) and g.ready(0)
    assert g.visits(0) == ()
    # A cut while standing: the path must start at the anchor.
    with pytest.raises(ValueError, match="after the cut"):
        g.set_plan(0, TimedPath(0, 20, stand(2, 3)))
    g.set_plan(0, TimedPath(0, 20, stand(1, 6)))
    assert [(a.src, a.dst, a.seq) for a in g.upcoming(0)] == [(1, 6, 5)]
    assert [v.leave for v in g.visits(1)] == [5] and g.visits(2) == ()


def test_set_plan_with_an_empty_remainder_parks_the_agv():
    g = build({0: TimedPath(0, 0, stand(0, 1, 2))}, {0: 1}, cols=4)
    g.start(0)
    g.set_plan(0, TimedPath(0, 1, stand(1)))
    assert g.upcoming(0) == [] and not g.done(0)
    g.finish(0)
    assert g.done(0) and g.next_action(0) is None and g.state(0) == (1, 1)
    assert [(v.enter, v.leave) for v in g.visits(1)] == [(0, None)]
    with pytest.raises(RuntimeError, match="no running action"):
        g.finish(0)


def test_collinear_run_stops_at_a_turn():
    g = ActionGraph(cols=5, sizes={0: 1})
    g.set_plan(0, TimedPath(0, 0, stand(0, 1, 2, 7, 12, 13)))
    assert [a.dst for a in g.collinear_run(0)] == [1, 2]
    assert [a.dst for a in g.collinear_run(0, 1)] == [1]
    g.start(0)
    g.finish(0)
    g.start(0)
    g.finish(0)
    assert [a.direction for a in g.collinear_run(0)] == [(1, 0), (1, 0)]


# --------------------------------------------------------------------------- cycles


def test_swap_conflict_is_a_cycle_naming_both_agvs():
    with pytest.raises(ADGCycleError, match=r"AGV 0.*AGV 1|AGV 1.*AGV 0") as info:
        build({0: TimedPath(0, 0, stand(0, 1)), 1: TimedPath(1, 0, stand(1, 0))},
              {0: 1, 1: 1}, cols=3)
    assert set(info.value.agvs) == {0, 1} and set(info.value.cells) == {(0, 0), (0, 1)}


def test_rotation_of_four_is_valid_but_cannot_run_without_a_clock():
    # Four AGVs rotate around a 2x2 block in one tick: the validator accepts it.
    paths = {0: TimedPath(0, 0, stand(0, 1)), 1: TimedPath(1, 0, stand(1, 5)),
             2: TimedPath(2, 0, stand(5, 4)), 3: TimedPath(3, 0, stand(4, 0))}
    trajs = {a: list(p.states) for a, p in paths.items()}
    assert validate_states(trajs, np.zeros((2, 4), bool)) == []
    assert rotation_agvs(trajs, dict.fromkeys(paths, 1), 4) == {0, 1, 2, 3}
    with pytest.raises(ADGCycleError) as info:
        build(paths, dict.fromkeys(paths, 1), cols=4)
    assert set(info.value.agvs) == {0, 1, 2, 3}


def test_visit_behind_an_agv_parked_for_good_is_reported():
    g = ActionGraph(cols=4, sizes={0: 1, 1: 1})
    g.set_plan(0, TimedPath(0, 0, stand(0, 1)))
    g.set_plan(1, TimedPath(1, 0, stand(3, 2, 1)))
    with pytest.raises(ADGCycleError, match="whose plan ends on it"):
        g.check_acyclic()


def test_deadlock_cycles_are_found_once_each():
    # Three AGVs each planned into the next one's cell (set one at a time): 0->1->2->0,
    # plus AGV 3 waiting on AGV 0 outside the cycle.
    g = ActionGraph(cols=4, sizes=dict.fromkeys(range(4), 1))
    g.set_plan(0, TimedPath(0, 0, stand(0)))
    g.set_plan(1, TimedPath(1, 0, stand(1)))
    g.set_plan(2, TimedPath(2, 0, stand(5)))
    g.set_plan(3, TimedPath(3, 0, stand(4)))
    g.set_plan(0, TimedPath(0, 0, stand(0, 1)))
    g.set_plan(1, TimedPath(1, 0, stand(1, 5)))
    g.set_plan(2, TimedPath(2, 0, stand(5, 4)))
    g.set_plan(3, TimedPath(3, 0, stand(4, 0)))
    assert g.waiting_for() == {0: {1}, 1: {2}, 2: {3}, 3: {0}}
    assert g.deadlock_cycles() == [[0, 1, 2, 3]]
    with pytest.raises(ADGCycleError):
        g.check_acyclic()
    # Two AGVs facing each other: a second, separate cycle.
    g2 = ActionGraph(cols=4, sizes=dict.fromkeys(range(4), 1))
    for agv, n in enumerate((0, 1, 2, 3)):
        g2.set_plan(agv, TimedPath(agv, 0, stand(n)))
    g2.set_plan(1, TimedPath(1, 0, stand(1, 0)))
    g2.set_plan(0, TimedPath(0, 0, stand(0, 1)))
    g2.set_plan(3, TimedPath(3, 0, stand(3, 2)))
    g2.set_plan(2, TimedPath(2, 0, stand(2, 3)))
    assert g2.deadlock_cycles() == [[0, 1], [2, 3]]


def test_a_checked_graph_skips_the_search_until_a_plan_changes():
    """Once check_acyclic has passed (run by deadlock_cycles when the searches since the
    last change cost as much), no search runs until a plan changes; a later plan that
    closes a cycle of waits is found at once."""
    g = ActionGraph(cols=4, sizes=dict.fromkeys(range(2), 1))
    g.set_plan(0, TimedPath(0, 0, stand(0)))
    g.set_plan(1, TimedPath(1, 0, stand(1, 2)))
    calls = []
    search = g._cycles
    g._cycles = lambda m: calls.append(m) or search(m)
    for _ in range(10):
        assert g.deadlock_cycles() == []
    assert g._acyclic and len(calls) < 10  # checked, then no more searches
    # Two AGVs facing each other, re-planned one at a time: each waits on the other.
    g.set_plan(1, TimedPath(1, 0, stand(1, 0)))
    g.set_plan(0, TimedPath(0, 0, stand(0, 1)))
    assert not g._acyclic
    assert g.deadlock_cycles() == [[0, 1]]


def test_all_paths_must_start_together():
    with pytest.raises(ValueError, match="same tick"):
        build({0: TimedPath(0, 0, stand(0)), 1: TimedPath(1, 1, stand(2))}, {0: 1, 1: 1}, 4)


# --------------------------------------------------------------------------- properties

SETTINGS = settings(max_examples=100, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


def build_or_skip(paths, sizes, trajs, cols) -> ActionGraph:
    """Build; a cycle is only allowed where the plan has a same-tick rotation."""
    rot = rotation_agvs(trajs, sizes, cols)
    if rot is not None:
        with pytest.raises(ADGCycleError):
            build(paths, sizes, cols)
        assume(False)
    return build(paths, sizes, cols)


@SETTINGS
@given(instances(), st.integers(0, 2**32 - 1), st.floats(0.3, 1.0), st.integers(1, 4))
def test_delayed_execution_never_overlaps_and_always_finishes(instance, seed, p, max_delay):
    layout, paths, sizes, _, trajs = instance
    cols = layout.cols
    graph = build_or_skip(paths, sizes, trajs, cols)
    ex = Execution(graph, sizes, cols, seed, p, max_delay)
    ex.check()
    ex.run(bound_for(graph, p, max_delay))
    for agv, path in paths.items():
        assert ex.done_moves[agv] == planned_moves(path.states)
        assert ex.where[agv] == (path.goal, path.goal)


def virtual_states(graph: ActionGraph, agv: int, moves=None) -> list[tuple[int, int]]:
    """The AGV's remaining plan on the plan's clock: it stands where it is (or keeps running
    its action) from tick 0 until its next action's planned tick, then follows the plan.
    ``moves`` (src, dst, tick, ticks) replace its upcoming actions."""
    run = graph.current(agv)
    if moves is None:
        moves = [(a.src, a.dst, a.tick, a.ticks) for a in graph.upcoming(agv)]
    if run is not None:
        states = [(run.src, run.dst)] * (run.tick + run.ticks)
        cur = run.dst
    else:
        states = []
        cur = graph.state(agv)[0]
    states.append((cur, cur))
    for src, dst, tick, ticks in moves:
        assert src == cur and tick >= len(states) - 1
        states += [(cur, cur)] * (tick + 1 - len(states))
        states += [(src, dst)] * (ticks - 1) + [(dst, dst)]
        cur = dst
    return states


def retimed(graph: ActionGraph, agv: int, rng) -> list[tuple[int, int, int, int]]:
    """The same remaining cells, each move delayed by a random non-decreasing amount."""
    shift, out = 0, []
    for a in graph.upcoming(agv):
        shift += int(rng.integers(0, 3))
        out.append((a.src, a.dst, a.tick + shift, a.ticks))
    return out


def as_path(agv: int, moves) -> TimedPath:
    t0 = moves[0][2]
    states = [(moves[0][0], moves[0][0])]
    for src, dst, tick, ticks in moves:
        states += [(src, src)] * (tick - t0 + 1 - len(states))
        states += [(src, dst)] * (ticks - 1) + [(dst, dst)]
    return TimedPath(agv, t0, tuple(states))


@SETTINGS
@given(instances(), st.integers(0, 2**32 - 1), st.floats(0.3, 1.0), st.integers(1, 3),
       st.lists(st.integers(1, 12), min_size=1, max_size=3, unique=True))
def test_replanning_mid_execution_keeps_the_invariants(instance, seed, p, max_delay,
                                                       replan_steps):
    layout, paths, sizes, speeds, trajs = instance
    cols = layout.cols
    graph = build_or_skip(paths, sizes, trajs, cols)
    ex = Execution(graph, sizes, cols, seed, p, max_delay)
    rng = np.random.default_rng(seed + 1)

    def valid(virtual) -> bool:
        conflicts = validate_states(virtual, layout.obstacles, sizes=sizes,
                                    ticks_per_move=speeds)
        return not conflicts and rotation_agvs(virtual, sizes, cols) is None

    def hook(ex: Execution) -> None:
        if ex.step_no not in replan_steps:
            return
        virtual = {a: virtual_states(graph, a) for a in graph.agvs}
        # The queues keep the remaining plan consistent on the plan's clock.
        assert valid(virtual), validate_states(virtual, layout.obstacles, sizes=sizes)
        for agv in graph.agvs:
            if not graph.upcoming(agv) or rng.random() < 0.4:
                continue
            moves = retimed(graph, agv, rng)
            candidate = dict(virtual) | {agv: virtual_states(graph, agv, moves)}
            same = [(a.src, a.dst, a.tick, a.ticks) for a in graph.upcoming(agv)]
            if not valid(candidate):
                moves, candidate = same, virtual  # same timing: still a cut and rebuild
            event("re-timed later" if moves != same else "same timing")
            event("cut while running" if graph.current(agv) else "cut while standing")
            before = [(a.src, a.dst) for a in graph.upcoming(agv)]
            graph.set_plan(agv, as_path(agv, moves))
            assert [(a.src, a.dst, a.tick, a.ticks) for a in graph.upcoming(agv)] == moves
            assert [(a.src, a.dst) for a in graph.upcoming(agv)] == before
            graph.check_acyclic()
            virtual = candidate
        ex.check()

    def every_step(ex: Execution) -> None:
        hook(ex)
        assert graph.deadlock_cycles() == graph._cycles(64) == []

    ex.run(bound_for(graph, p, max_delay) * 2, every_step)
    for agv, path in paths.items():
        assert ex.done_moves[agv] == planned_moves(path.states)
        assert ex.where[agv] == (path.goal, path.goal)


@SETTINGS
@given(instances(), st.integers(0, 2**32 - 1), st.floats(0.3, 1.0), st.integers(1, 3))
def test_valid_plans_are_acyclic_and_never_deadlock(instance, seed, p, max_delay):
    layout, paths, sizes, _, trajs = instance
    cols = layout.cols
    rot = rotation_agvs(trajs, sizes, cols)
    if rot is not None:
        with pytest.raises(ADGCycleError) as info:
            build(paths, sizes, cols)
        assert len(info.value.agvs) >= 3  # a swap would be invalid: a real rotation
        return
    graph = build(paths, sizes, cols)
    ex = Execution(graph, sizes, cols, seed, p, max_delay)

    def hook(ex: Execution) -> None:
        assert graph.deadlock_cycles() == []
        graph.check_acyclic()
        for agv, ahead in graph.waiting_for().items():
            assert not graph.ready(agv) and agv not in ahead and ahead

    hook(ex)
    ex.run(bound_for(graph, p, max_delay), hook)


def test_progress_and_head_match_the_per_agv_queries():
    """``progress`` (the executor's write-back in one pass) says what ``state``,
    ``next_action`` and ``current`` say, AGV by AGV; ``head`` names a queue's first AGV."""
    g = build({0: TimedPath(0, 0, ((1, 1), (2, 2), (3, 3))),
               1: TimedPath(1, 0, ((0, 0), (1, 1), (2, 2)))}, {0: 1, 1: 1}, cols=4)

    def expected(tick):
        out = ([], [], [], [])
        for i in (0, 1):
            nxt, cur = g.next_action(i), g.current(i)
            out[0].append(g.state(i))
            out[1].append((cur is None and nxt is not None and nxt.tick < tick)
                          or (cur is not None and cur.tick + cur.ticks < tick))
            out[2].append(nxt is not None)
            out[3].append(cur is not None)
        return out

    for tick in (0, 1, 3):
        assert g.progress(2, tick) == expected(tick)
    assert g.head(1) == 0 and g.head(0) == 1 and g.head(3) == 0
    g.start(0)
    assert g.progress(2, 2) == expected(2) and g.progress(2, 2)[0] == [(1, 2), (0, 0)]
    g.finish(0)
    assert g.head(1) == 1 and g.progress(2, 1) == expected(1)
    with pytest.raises(KeyError):
        g.progress(3, 0)


def test_prune_keeps_every_node_that_reaches_a_cycle():
    """Before the cycle search, waiting AGVs that reach no cycle are dropped; those that
    wait on a cycle (and the cycle) stay with their edges in order."""
    graph = {0: [1], 1: [2], 2: [0], 3: [0, 4], 4: [5], 5: [9], 6: [3]}
    assert adg_module._prune_acyclic(graph) == {0: [1], 1: [2], 2: [0], 3: [0], 6: [3]}
    assert adg_module._prune_acyclic({0: [1], 1: [0]}) == {0: [1], 1: [0]}
    assert adg_module._prune_acyclic({0: [1], 1: [2]}) == {}


def _progress_from_scratch(g: ActionGraph, n: int, tick: int):
    states, late, pending, running = [], [], [], []
    for i in range(n):
        cur, nxt = g.current(i), g.next_action(i)
        states.append(g.state(i))
        late.append(cur.tick + cur.ticks < tick if cur is not None
                    else nxt is not None and nxt.tick < tick)
        pending.append(nxt is not None)
        running.append(cur is not None)
    return states, late, pending, running


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_progress_answers_as_a_fresh_pass_whatever_happened_since(data):
    """``progress`` looks again only at AGVs with something left or a changed record; its
    answers equal a pass over every AGV after any sequence of starts, finishes and new
    plans."""
    g = ActionGraph(cols=8, sizes=dict.fromkeys(range(3), 1))
    lanes = {0: [0, 1, 2, 3, 4], 1: [8, 9, 10, 11], 2: [16, 17, 18, 19, 20, 21]}
    for i, cells in lanes.items():
        g.set_plan(i, TimedPath(i, 0, stand(*cells)))
    for tick in range(12):
        for i in data.draw(st.lists(st.sampled_from([0, 1, 2]), max_size=3), label="who"):
            if g.current(i) is not None:
                g.finish(i)
            elif g.ready(i):
                g.start(i)
            elif g.done(i) and data.draw(st.booleans(), label="new plan"):
                here = g.state(i)[0]  # one cell along its own row (rows never meet)
                g.set_plan(i, TimedPath(i, tick, stand(here, here + 1 if here % 8 < 7
                                                       else here - 1)))
        assert g.progress(3, tick) == _progress_from_scratch(g, 3, tick)


@SETTINGS
@given(instances(), st.integers(0, 2**32 - 1), st.floats(0.3, 1.0), st.integers(1, 3))
def test_released_answers_hold_until_woken_and_blockers_match_heads(instance, seed, p,
                                                                     max_delay):
    """What the follower relies on to skip a look ahead (``wait_release``, ``ext_woken``):
    an AGV that claimed its released actions gets the same :meth:`released` answer, with
    the same running and next action, until it is named in ``ext_woken``; and
    :meth:`blockers` says what ``next_action`` and ``head`` say, AGV by AGV."""
    layout, paths, sizes, _, trajs = instance
    graph = build_or_skip(paths, sizes, trajs, layout.cols)
    ex = Execution(graph, sizes, layout.cols, seed, p, max_delay)
    kept: dict[int, tuple] = {}

    def hook(ex: Execution) -> None:
        agvs = list(graph.agvs)
        heads = []
        for agv in agvs:
            nxt = graph.next_action(agv)
            h = next((graph.head(c) for c in (nxt.enters if nxt else ())
                      if graph.head(c) not in (None, agv)), None)
            heads.append(-1 if h is None else h)
        assert graph.blockers(agvs) == heads
        for agv in agvs:
            cur, nxt = graph.current(agv), graph.next_action(agv)
            old = kept.pop(agv, None)
            if old is not None and old[0] is cur and old[1] is nxt \
                    and agv not in graph.ext_woken:
                event("released answer kept")
                assert graph.released(agv, 8) == old[2]
            graph.ext_woken.discard(agv)
            ans = graph.released(agv, 8)
            stop = graph.released_stop
            graph.claim(agv, len(ans), released=ans)
            if stop is not False:
                if stop is not None:
                    graph.wait_release(agv, stop)
                kept[agv] = (cur, nxt, ans)

    hook(ex)
    ex.run(bound_for(graph, p, max_delay), hook)


@SETTINGS
@given(instances())
def test_bulk_registration_gives_the_queues_of_one_by_one(instance):
    """``begin_bulk`` / ``end_bulk`` (the fleet's first plans in one batch, as ``build``
    does) leave every queue in the order that registering the AGVs one by one gives."""
    layout, paths, sizes, _, _ = instance
    one = ActionGraph(layout.cols, sizes)
    bulk = ActionGraph(layout.cols, sizes)
    assert bulk.begin_bulk() and not bulk.begin_bulk()
    for agv in sorted(paths):
        one.set_plan(agv, paths[agv])
        bulk.set_plan(agv, paths[agv])
    bulk.end_bulk()
    assert not bulk.begin_bulk()  # only on an empty graph
    for cell in range(layout.rows * layout.cols):
        assert bulk.visits(cell) == one.visits(cell)
    assert [bulk.upcoming(a) for a in sorted(paths)] == [one.upcoming(a) for a in sorted(paths)]
