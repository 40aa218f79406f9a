"""``warerover lorr``: a League of Robot Runners problem run lifelong, its output JSON read
back by the plan importer and its finished tasks recounted from the paths alone."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from warerover_phys.cli import app
from warerover_phys.errors import ScenarioError
from warerover_phys.lorr import output_json, read_problem, run_lifelong, write_output_json
from warerover_phys.plans import read_plan

DATA = Path(__file__).parent / "data" / "lorr2023_warehouse_small"
PROBLEM = DATA / "warehouse_small_50.json"
runner = CliRunner()


def _pad(seq, n):
    seq = list(seq)
    return seq + [seq[-1]] * (n - len(seq))


def _recount(doc: dict, cols: int, problem) -> int:
    """Tasks finished, from the output's paths, tasks and schedule alone: a task recorded
    ``t:task`` in ``actualSchedule`` (the timestep after the robot took it, as the start
    kit records it) has each errand done at the first timestep from ``t`` on at which the
    robot stands on the errand's cell, in order (one errand per timestep), the last
    timestep included; the task is finished with its last errand; the robot takes its next
    task in that same timestep."""
    plan = read_plan_from(doc)
    errands = {t[0]: [tuple(t[j:j + 2]) for j in range(1, len(t), 2)]  # 2023: [k, r, c]
               for t in doc["tasks"]}
    horizon = doc["makespan"]
    finished = 0
    for i, schedule in enumerate(doc["actualSchedule"]):
        cells = _pad(plan.paths[i], horizon + 1)
        for item in filter(None, schedule.split(",")):
            t, k = map(int, item.split(":"))
            todo = list(errands[k])
            s = t
            while todo and s <= horizon:
                if cells[s] == todo[0]:
                    todo.pop(0)
                    if not todo:
                        finished += 1
                        break
                s += 1
    return finished


def read_plan_from(doc: dict):
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "out.json"
        p.write_text(json.dumps(doc))
        return read_plan(p)


@pytest.fixture(scope="module")
def problem():
    return read_problem(PROBLEM)


def test_problem_is_read_as_its_files_say(problem):
    assert problem.team_size == 50 and len(problem.tasks) == 20000
    assert (problem.grid.rows, problem.grid.cols) == (33, 57)
    assert problem.strategy == "roundrobin" and problem.reveal == 1
    assert all(len(t) == 1 for t in problem.tasks)
    assert not any(problem.grid.obstacles.ravel()[s] for s in problem.starts)


@pytest.mark.parametrize("rotations,rule", [(True, "actions"), (True, "turn-first"),
                                           (False, "actions")])
def test_output_reads_back_with_identical_paths_and_recounted_tasks(problem, rotations, rule):
    result = run_lifelong(problem, 150, rotations=rotations, seed=3, rule=rule)
    doc = json.loads(json.dumps(output_json(result)))
    assert doc["teamSize"] == 50 and doc["makespan"] == 150
    assert doc["actionModel"] == ("MAPF_T" if rotations else "MAPF")
    plan = read_plan_from(doc)
    cols = problem.grid.cols
    for i in range(50):
        executed = [divmod(c, cols) for c in result.positions[i]]
        assert _pad(plan.paths[i], 151) == _pad(executed, 151)
        if rotations:
            assert _pad(plan.headings[i], 151) == _pad(result.headings[i], 151)
            # the rotation model: a robot moves only straight ahead
            for (a, b), h in zip(zip(executed, executed[1:], strict=False), result.headings[i][:-1],
                                 strict=True):
                if a != b:
                    assert (b[0] - a[0], b[1] - a[1]) == ((0, 1), (1, 0), (0, -1), (-1, 0))[h]
    assert result.finished > 0
    assert doc["numTaskFinished"] == result.finished == _recount(doc, cols, problem)


def test_same_seed_same_run(problem):
    a = output_json(run_lifelong(problem, 60, seed=5))
    b = output_json(run_lifelong(problem, 60, seed=5))
    for key in ("actualPaths", "events", "tasks", "numTaskFinished", "sumOfCost"):
        assert a[key] == b[key]


@pytest.mark.parametrize("rotations,rule,finished,digest,kw", [
    (False, "actions", 144, "645571bee2a7d1b2", {}),
    (False, "actions", 144, "645571bee2a7d1b2", {"prefetch": True, "dist_budget_mb": 0.2}),
    (True, "actions", 114, "5550043f0c6b6209", {}),
    (True, "turn-first", 63, "74020e7033b595e6", {})])
def test_same_plans_as_before_the_table_store(problem, rotations, rule, finished, digest, kw):
    """The paths of 120 timesteps, seed 3, as the code before the distance-table store
    (commit bcbae05, ``graph.dist_to`` per robot) planned them: the store (prefetched, or
    small enough to evict) and the PIBT speed-ups change no plan. (The digest was of the
    whole output until issue 31 changed the definitions of sumOfCost, makespan, events,
    tasks and actualSchedule to the start kit's: the paths hashed here are those of that
    digest, checked against the code before; the tasks finished on the last timestep now
    count, 143 -> 144 and 112 -> 114.)"""
    result = run_lifelong(problem, 120, rotations=rotations, rule=rule, seed=3, **kw)
    doc = output_json(result)
    got = hashlib.sha256(json.dumps([doc["actualPaths"], doc["start"]]).encode()
                         ).hexdigest()[:16]
    assert (result.finished, got) == (finished, digest)
    tables = result.summary()["dist_tables"]
    assert tables["misses"] == sum(result.tick_misses) > 0 and tables["hits"] > 0


def test_streamed_output_is_byte_identical(problem, tmp_path):
    kept = run_lifelong(problem, 45, seed=2)
    streamed = run_lifelong(problem, 45, seed=2, trace_dir=tmp_path / "trace", chunk_ticks=7)
    assert streamed.actions == [] and len(streamed.chunks.files) == 7
    streamed.tick_s = kept.tick_s  # the only field that differs between two runs
    write_output_json(streamed, tmp_path / "out.json")
    assert (tmp_path / "out.json").read_text() == json.dumps(output_json(kept)) + "\n"


def test_cli_writes_output_and_refuses_what_it_cannot_do(tmp_path):
    out = tmp_path / "run"
    r = runner.invoke(app, ["lorr", str(PROBLEM), "--ticks", "40", "--out", str(out),
                            "--json", "--dist-budget-mb", "0.1"])
    assert r.exit_code == 0, r.output
    figures = json.loads(r.stdout[:r.stdout.rindex("}") + 1])
    doc = json.loads((out / "output.json").read_text())
    assert doc["numTaskFinished"] == figures["tasks_finished"]
    tables = figures["dist_tables"]  # 0.1 MiB: 27 tables of 33 x 57 cells
    assert tables["capacity_tables"] == 27 and tables["evictions"] > 0
    assert json.loads((out / "metrics.json").read_text())["output_s"] > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # the trace is gone
    assert figures["ticks"] == 40 and figures["ms_per_tick_p99"] >= figures["ms_per_tick_mean"] > 0
    for args, what in ((["--planner", "cbs"], "--planner"), (["--executor", "physics"],
                       "--executor"), (["--ticks", "0"], "--ticks")):
        r = runner.invoke(app, ["lorr", str(PROBLEM), *args])
        assert r.exit_code == 2 and what in r.output and "Traceback" not in r.output


@pytest.mark.parametrize("edit, field", [
    (lambda d: d.pop("mapFile"), "mapFile"),
    (lambda d: d.update(teamSize=0), "teamSize"),
    (lambda d: d.update(teamSize=51), "teamSize"),
    (lambda d: d.update(numTasksReveal="x"), "numTasksReveal"),
    (lambda d: d.update(taskAssignmentStrategy="fastest"), "taskAssignmentStrategy"),
    (lambda d: d.update(agentFile="agents/missing.agents"), "agentFile"),
])
def test_bad_problem_files_name_the_field(tmp_path, edit, field):
    shutil.copytree(DATA, tmp_path / "p")
    path = tmp_path / "p" / PROBLEM.name
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(ScenarioError) as info:
        read_problem(path)
    assert field in str(info.value)
    r = runner.invoke(app, ["lorr", str(path)])
    assert r.exit_code == 2 and "Traceback" not in r.output


def test_agent_on_an_obstacle_is_named(tmp_path):
    shutil.copytree(DATA, tmp_path / "p")
    agents = tmp_path / "p" / "agents" / "warehouse_small_50.agents"
    lines = agents.read_text().splitlines()
    lines[1] = "0"  # (0, 0) is a wall
    agents.write_text("\n".join(lines) + "\n")
    with pytest.raises(ScenarioError, match="agent 0"):
        read_problem(tmp_path / "p" / PROBLEM.name)


def test_the_runner_check_refuses_shared_cells_swaps_and_jumps():
    """``lorr._check`` (over arrays) on a 1 x 4 corridor, cells 0-3."""
    import numpy as np

    from warerover_phys.lorr import _check
    from warerover_phys.planning.pibt_numba import step_tables

    st = step_tables([(1,), (0, 2), (1, 3), (2,)], 4)
    pos = np.full(4, -1, dtype=np.int64)
    ar = np.arange(2)
    _check(np.array([0, 2]), np.array([1, 3]), st, pos, ar, 0)  # fine
    for cfg, nxt, what in (([0, 2], [1, 1], "vertex conflict"), ([0, 3], [2, 3], "jumps"),
                           ([0, 1], [1, 0], "swap")):
        with pytest.raises(AssertionError, match=what):
            _check(np.array(cfg), np.array(nxt), st, pos, ar, 4)
        assert (pos == -1).all()  # the scratch array is left as it was
