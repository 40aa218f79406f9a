"""The plug-in conformance checkers (warerover_phys.testing): every built-in and every example
plug-in passes its checker, deliberately broken plug-ins fail it with a message that says what
to fix, and the examples run in full episodes, in ``warerover run`` and in a sweep."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from pydantic import BaseModel

from warerover_phys import load_scenario, run_episode, scenario_from_dict
from warerover_phys.config import ExecutorSpec, PlannerSpec, SchedulerSpec
from warerover_phys.errors import ScenarioError, WareroverError
from warerover_phys.executors import GridExecutor, StepReport
from warerover_phys.planning import AStarPlanner, PlanRequest, ReservationTable, TimedPath
from warerover_phys.schedulers import Assignment
from warerover_phys.sweep import load_sweep, run_sweep
from warerover_phys.testing import (
    ConformanceError,
    ConformanceReport,
    check_executor,
    check_planner,
    check_scheduler,
)

REPO = Path(__file__).resolve().parents[1]
HOMOGENEOUS = REPO / "layouts" / "paper_homogeneous.yaml"

NEAREST = "examples.nearest_first:NearestFirst"
LONGEST = "examples.longest_first:LongestFirstAStar"
SLOW = "examples.slow_grid:SlowGrid"


@pytest.fixture(autouse=True)
def repo_on_path(monkeypatch):
    """``examples`` is a folder of the repository, not of the installed package: it imports
    when the repository root is on sys.path (``python -m pytest`` from the root puts it
    there; plain ``pytest`` does not), and sweep workers find it through the working
    directory."""
    monkeypatch.syspath_prepend(str(REPO))
    monkeypatch.chdir(REPO)


# ------------------------------------------------------------------------------ passing


@pytest.mark.parametrize("name", ["ta", "rd", NEAREST])
def test_schedulers_pass(name):
    report = check_scheduler(name)
    assert isinstance(report, ConformanceReport) and report.kind == "scheduler"
    assert {"members", "read-only world", "assignments", "determinism"} <= set(report.passed)


@pytest.mark.parametrize("name", ["astar", "cbs", "pibt", "lacam", LONGEST])
def test_planners_pass(name):
    report = check_planner(name)
    assert {"replans_all", "motion graph", "conflict-free", "reaches goals",
            "determinism"} <= set(report.passed)


# physics: episodes on pymunk for every check (make test-all); grid and the plug-in here
@pytest.mark.parametrize("name", ["grid", pytest.param("physics", marks=pytest.mark.slow), SLOW])
def test_executors_pass(name):
    report = check_executor(name)
    assert {"report", "follows plans", "no false collisions", "summary", "trajectory",
            "stop_short", "determinism"} <= set(report.passed)


def test_targets_may_be_classes_factories_or_instances():
    from examples.longest_first import LongestFirstAStar
    from examples.nearest_first import NearestFirst
    from examples.slow_grid import SlowGrid

    assert "params" in check_scheduler(NearestFirst).passed
    assert check_planner(lambda: AStarPlanner(max_expansions=5_000)).name.endswith("<lambda>")
    assert check_planner(AStarPlanner()).passed[-1] == "determinism"
    spec = PlannerSpec(params={"longest_first": False})
    assert check_planner(LongestFirstAStar, spec).passed[-1] == "determinism"
    assert check_executor(SlowGrid, ExecutorSpec(params={"every_n_ticks": 4})).passed
    assert "determinism" in str(check_executor(GridExecutor))


def test_examples_pass_with_other_params():
    assert check_executor(SLOW, ExecutorSpec(params={"every_n_ticks": 1})).passed
    assert check_scheduler(NEAREST, SchedulerSpec(params={"max_orders_per_trip": 1})).passed


# ------------------------------------------------------------------------------ broken plug-ins
#
# Each class below breaks its Protocol in one way; its test names the check that must catch
# it and a phrase of the message.


class WrongTypePlanner:
    name = "wrong-type"
    replans_all = False

    def __init__(self, spec):
        pass

    def plan(self, request):
        return {a.agv: TimedPath(a.agv, request.tick, ((a.start, a.start),))
                for a in request.agents}


class JumpingPlanner:
    """Moves every AGV two cells to the right in one tick."""

    name = "jumper"
    replans_all = False

    def __init__(self, spec):
        pass

    def plan(self, request):
        from warerover_phys.planning import PlanResult

        return PlanResult(paths={a.agv: TimedPath(a.agv, request.tick, (
            (a.start, a.start), (a.start + 2, a.start + 2))) for a in request.agents})


class IgnoresCommittedPlanner:
    """Coordinates the AGVs it is asked about, but plans on a table that forgot every other
    AGV's committed path."""

    name = "ignores-committed"
    replans_all = False

    def __init__(self, spec):
        self.astar = AStarPlanner()

    def plan(self, request):
        blank = ReservationTable(request.reservations.cols)
        for a in request.agents:
            blank.commit(TimedPath(a.agv, request.tick, ((a.start, a.start),)), a.k)
        return self.astar.plan(PlanRequest(request.tick, request.agents, request.graphs, blank,
                                           request.rng, request.keep_clear))


class SortsInPlacePlanner:
    name = "sorts-in-place"
    replans_all = False

    def __init__(self, spec):
        self.astar = AStarPlanner()

    def plan(self, request):
        request.agents.sort(key=lambda a: -a.agv)
        return self.astar.plan(request)


class NoReplansAllPlanner:
    name = "no-replans-all"

    def __init__(self, spec):
        pass

    def plan(self, request):
        raise AssertionError("never called")


class NumpyNodesPlanner:
    """Valid paths, but the nodes are numpy integers (paths.json cannot hold them)."""

    name = "numpy-nodes"
    replans_all = False

    def __init__(self, spec):
        self.astar = AStarPlanner()

    def plan(self, request):
        import numpy as np

        result = self.astar.plan(request)
        result.paths = {i: TimedPath(i, p.start_tick, tuple((np.int64(a), np.int64(b))
                                                             for a, b in p.states))
                        for i, p in result.paths.items()}
        return result


class GraphVandalPlanner:
    """Closes a cell by editing the shared motion graph."""

    name = "graph-vandal"
    replans_all = False

    def __init__(self, spec):
        self.astar = AStarPlanner()

    def plan(self, request):
        graph = request.graphs.get(1, False)
        graph.neighbors[0] = ()
        return self.astar.plan(request)


class LazyPlanner:
    """Lets every AGV stand where it is."""

    name = "lazy"
    replans_all = False

    def __init__(self, spec):
        pass

    def plan(self, request):
        from warerover_phys.planning import PlanResult

        return PlanResult(paths={a.agv: TimedPath(a.agv, request.tick, ((a.start, a.start),))
                                 for a in request.agents})


class StatefulPlanner:
    """Plans the AGVs in an order that rotates with every call (state kept on self)."""

    name = "stateful"
    replans_all = False

    def __init__(self, spec):
        self.astar = AStarPlanner()
        self.calls = 0

    def plan(self, request):
        from dataclasses import replace

        self.calls += 1
        n = len(request.agents)
        agents = [replace(a, priority=((i + self.calls) % n,))
                  for i, a in enumerate(request.agents)]
        return self.astar.plan(replace(request, agents=agents))


BROKEN_PLANNERS = [
    (GraphVandalPlanner, "request untouched", "changed the motion graph of 1x1 unloaded AGVs"),
    (LazyPlanner, "reaches goals", "not at its goal"),
    (StatefulPlanner, "determinism", "keep no state between calls on self"),
    (WrongTypePlanner, "return type", "plan() returned dict"),
    (JumpingPlanner, "motion graph", "not an edge of its motion graph"),
    (IgnoresCommittedPlanner, "conflict-free", "runs into AGV 0's committed path"),
    (SortsInPlacePlanner, "request untouched", "reordered or changed request.agents"),
    (NoReplansAllPlanner, "replans_all", "add a class attribute replans_all"),
    (NumpyNodesPlanner, "path format", "numpy integers do not serialise"),
]


@pytest.mark.parametrize(("cls", "check", "phrase"), BROKEN_PLANNERS,
                         ids=[c[0].__name__ for c in BROKEN_PLANNERS])
def test_broken_planners_fail(cls, check, phrase):
    with pytest.raises(ConformanceError) as info:
        check_planner(cls)
    err = info.value
    assert err.check == check and phrase in str(err), str(err)
    assert "Fix: " in str(err) and isinstance(err, WareroverError)


def test_ignoring_committed_paths_names_the_case_and_the_conflict():
    with pytest.raises(ConformanceError) as info:
        check_planner(IgnoresCommittedPlanner)
    text = str(info.value)
    assert "in case 'around a committed path'" in text
    assert "conflict at tick" in text and "reservations.free(cell, t, agv)" in text


class BusyAgvScheduler:
    """Gives every AGV, idle or not, the oldest pending order it can find a shelf for."""

    name = "busy-agv"

    def __init__(self, spec):
        pass

    def assign(self, world, rng):
        out, taken, shelves = [], set(), set()
        for agv in world.agvs:
            for order in world.pending_orders():
                free = [s for s in world.free_shelves_for(order.sku, agv) if s not in shelves]
                if order.id not in taken and free:
                    out.append(Assignment(agv.id, free[0], (order.id,)))
                    taken.add(order.id)
                    shelves.add(free[0])
                    break
        return out


class MeddlingScheduler:
    """Writes the AGVs the view hands out."""

    name = "meddler"

    def __init__(self, spec):
        pass

    def assign(self, world, rng):
        for agv in world.idle_agvs():
            agv.delay = 3
        return []


class TupleScheduler:
    name = "tuple"

    def __init__(self, spec):
        pass

    def assign(self, world, rng):
        return ()


class IdleScheduler:
    """Never assigns anything: no AGV ever leaves its parking spot."""

    name = "idle"

    def __init__(self, spec):
        pass

    def assign(self, world, rng):
        return []


class NoNameScheduler:
    def __init__(self, spec):
        pass

    def assign(self, world, rng):
        return []


class WrongSignatureScheduler:
    name = "wrong-signature"

    def __init__(self, spec):
        pass

    def assign(self, world):
        return []


class StatefulScheduler:
    """Serves the pending orders newest first on every other call (state kept on self)."""

    name = "stateful"

    def __init__(self, spec):
        self.flip = False

    def assign(self, world, rng):
        self.flip = not self.flip
        pending = world.pending_orders()[::-1 if self.flip else 1]
        out, taken = [], set()
        for agv in world.idle_agvs():
            for order in pending:
                free = [s for s in world.free_shelves_for(order.sku, agv) if s not in taken]
                if free and order.id not in {o for a in out for o in a.orders}:
                    out.append(Assignment(agv.id, free[0], (order.id,)))
                    taken.add(free[0])
                    break
        return out


BROKEN_SCHEDULERS = [
    (StatefulScheduler, "determinism", "a fresh scheduler, called twice"),
    (BusyAgvScheduler, "assignments", "gives a trip to AGV 0, which is TO_SHELF, not IDLE"),
    (MeddlingScheduler, "read-only world", "assign() changed the world's AGVs"),
    (TupleScheduler, "return type", "assign() returned tuple"),
    (IdleScheduler, "progress", "it assigned nothing"),
    (NoNameScheduler, "name", "its name is None"),
    (WrongSignatureScheduler, "members", "cannot be called as assign(self, world, rng)"),
]


@pytest.mark.parametrize(("cls", "check", "phrase"), BROKEN_SCHEDULERS,
                         ids=[c[0].__name__ for c in BROKEN_SCHEDULERS])
def test_broken_schedulers_fail(cls, check, phrase):
    with pytest.raises(ConformanceError) as info:
        check_scheduler(cls)
    assert info.value.check == check and phrase in str(info.value), str(info.value)


class FakeContactsExecutor(GridExecutor):
    """Counts AGVs in neighbouring cells as contacts, which they are not."""

    name = "fake-contacts"

    def step(self, view):
        report = super().step(view)
        cells = {s[1] for s in report.states.values()}
        report.collisions = sum(1 for c in cells if c + 1 in cells)
        return report


_RUNS = [0]


class LeakyExecutor(GridExecutor):
    """Pauses the fleet on ticks that depend on how many episodes ran before in this
    process (state kept in a module global): not deterministic for a seed."""

    name = "leaky"

    def bind(self, setup):
        super().bind(setup)
        _RUNS[0] += 1
        self.offset = _RUNS[0]

    def step(self, view):
        if (view.tick + self.offset) % 3:
            return super().step(view)
        report = StepReport(states=dict(self.pos))
        for agv, path in view.plans.items():
            if path.end_tick > view.tick - view.behind[agv]:
                report.behind[agv] = view.behind[agv] + 1
        return report


class ForgetfulExecutor(GridExecutor):
    """Reports only the AGVs that moved."""

    name = "forgetful"

    def step(self, view):
        before = dict(self.pos)
        report = super().step(view)
        report.states = {i: s for i, s in report.states.items() if s != before[i]}
        return report


class StuckExecutor(GridExecutor):
    """Never moves anyone."""

    name = "stuck"

    def step(self, view):
        return StepReport(states=dict(self.pos))


class NumpySummaryExecutor(GridExecutor):
    name = "numpy-summary"

    def summary(self):
        import numpy as np

        return {"moves": np.int64(3)}


class NoTrajectoryExecutor:
    name = "no-trajectory"

    def __init__(self, spec):
        self.grid = GridExecutor(spec)

    def bind(self, setup):
        self.grid.bind(setup)

    def step(self, view):
        return self.grid.step(view)

    def remaining(self, agv):
        return []

    def stop_short(self, agv, cells, view):
        return False, False

    def summary(self):
        return {}


BROKEN_EXECUTORS = [
    (FakeContactsExecutor, "no false collisions", "while executing valid, conflict-free plans"),
    (LeakyExecutor, "determinism", "at tick 0, report.states[0] is"),
    (ForgetfulExecutor, "report", "lacks AGVs"),
    (StuckExecutor, "follows plans", "the valid plans are not done"),
    (NumpySummaryExecutor, "summary", "not JSON-serialisable"),
    (NoTrajectoryExecutor, "members", "it has no trajectory()"),
]


@pytest.mark.parametrize(("cls", "check", "phrase"), BROKEN_EXECUTORS,
                         ids=[c[0].__name__ for c in BROKEN_EXECUTORS])
def test_broken_executors_fail(cls, check, phrase):
    with pytest.raises(ConformanceError) as info:
        check_executor(cls, max_ticks=40)
    assert info.value.check == check and phrase in str(info.value), str(info.value)


class OpenParamsPlanner(AStarPlanner):
    """Its Params model ignores unknown keys: a misspelt key would be dropped silently."""

    class Params(BaseModel):
        max_expansions: int = 100

    def __init__(self, spec, params):
        super().__init__(max_expansions=params.max_expansions)


def test_open_params_model_and_bad_targets_fail():
    with pytest.raises(ConformanceError, match=r"accepts unknown keys.*extra='forbid'"):
        check_planner(OpenParamsPlanner)
    with pytest.raises(ConformanceError, match=r"fails check 'build'.*unknown parameter"):
        check_planner(LONGEST, PlannerSpec(params={"max_expansion": 10}))
    with pytest.raises(ConformanceError, match="the name does not resolve"):
        check_executor("no_such_module_xyz:Executor")
    with pytest.raises(ConformanceError, match="needs two fresh executors"):
        check_executor(GridExecutor())


# ------------------------------------------------------------------------------ in the loop


def scenario_with(**sections) -> dict:
    """The paper's homogeneous scenario as a dict, with ``sections`` replaced."""
    data = yaml.safe_load(HOMOGENEOUS.read_text(encoding="utf-8"))
    data["orders"]["oneshot"]["count"] = 10
    return {**data, **sections}


@pytest.mark.parametrize(("section", "name", "params", "figure"), [
    ("scheduler", NEAREST, {"max_orders_per_trip": 3}, None),
    ("planner", LONGEST, {"max_expansions": 30_000, "longest_first": True}, None),
    ("executor", SLOW, {"every_n_ticks": 3}, "slow_grid_paused_ticks"),
])
def test_examples_run_a_full_episode(section, name, params, figure):
    data = scenario_with(**{section: {"name": name, "params": params}})
    result = run_episode(scenario_from_dict(data, source=str(HOMOGENEOUS)), seed=1)
    m = result.metrics
    assert m["success_rate"] == 1.0 and m["collisions"] == 0
    if figure is None:
        assert m[section] == name
    else:  # the executor's summary() reaches metrics.json
        assert m[figure] > 0


def test_executor_by_import_path_runs_in_warerover_run(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "warerover_phys", "run", str(HOMOGENEOUS.relative_to(REPO)),
         "--set", f"executor.name={SLOW}", "--set", "executor.params.every_n_ticks=2",
         "--json", "--out", str(tmp_path / "run")],
        cwd=REPO, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    metrics = json.loads(out.stdout)
    assert metrics["success_rate"] == 1.0 and metrics["slow_grid_paused_ticks"] > 0
    assert (tmp_path / "run" / "metrics.json").exists()


def test_examples_run_in_a_sweep(tmp_path):
    sweep = {"name": "examples", "scenarios": {"Ho": str(HOMOGENEOUS)},
             "grid": {"scheduler.name": [NEAREST], "planner.name": ["astar", LONGEST],
                      "executor.name": [SLOW]},
             # dotted keys: a mapping as a value ("executor.params": {...}) is not hashable
             # and breaks compile_scenarios (see the report)
             "set": {"orders.oneshot.count": 6, "max_ticks": 150,
                     "scheduler.params.max_orders_per_trip": 2,
                     "executor.params.every_n_ticks": 2},
             "repetitions": 1}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump(sweep, sort_keys=False), encoding="utf-8")
    summary = run_sweep(load_sweep(path), tmp_path / "out", workers=1)
    rows = [json.loads(line) for line in (tmp_path / "out" / "results.jsonl").read_text()
            .splitlines()]
    assert summary.ran == 2 and summary.failed == 0, [r["error"] for r in rows]
    assert {r["planner"] for r in rows} == {"astar", LONGEST}
    assert all(r["metrics"]["orders_completed"] > 0 for r in rows)
    assert all(r["metrics"]["slow_grid_paused_ticks"] > 0 for r in rows)


@pytest.mark.parametrize(("section", "name", "params", "field"), [
    ("planner", LONGEST, {"max_expansion": 10}, "planner.params.max_expansion"),
    ("planner", LONGEST, {"longest_first": "sometimes"}, "planner.params.longest_first"),
    ("scheduler", NEAREST, {"max_orders_per_trip": 0}, "scheduler.params.max_orders_per_trip"),
    ("executor", SLOW, {"every_n_ticks": "often"}, "executor.params.every_n_ticks"),
    ("planner", "astar", {"anything": 1}, "planner.params.anything"),
])
def test_bad_params_name_the_field_and_the_file(tmp_path, section, name, params, field):
    data = scenario_with(**{section: {"name": name, "params": params}})
    data["layout"] = str(REPO / "layouts" / data["layout"])
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        run_episode(load_scenario(path))
    err = info.value
    assert err.file == str(path) and err.field == field, str(err)
    assert str(err).startswith(f"{path}: {field}: ")


def test_docstring_examples():
    import doctest

    import warerover_phys.testing

    result = doctest.testmod(warerover_phys.testing)
    assert result.attempted >= 4 and result.failed == 0
