"""``warerover lorr``: a League of Robot Runners problem run in the one loop, its output
JSON read back by the plan importer, the command's options and refusals. (Parity with the
retired runner and the physics output: ``tests/problems/test_robotrunners.py``.)"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from warerover_phys.cli import app
from warerover_phys.errors import ScenarioError
from warerover_phys.plans import read_plan
from warerover_phys.problems.robotrunners import output_json, problem_scenario, read_problem
from warerover_phys.sim import Simulation

DATA = Path(__file__).parent / "data" / "lorr2023_warehouse_small"
PROBLEM = DATA / "warehouse_small_50.json"
runner = CliRunner()


def _pad(seq, n):
    seq = list(seq)
    return seq + [seq[-1]] * (n - len(seq))


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
def test_output_reads_back_with_identical_paths(problem, rotations, rule):
    sim = Simulation(problem_scenario(problem, ticks=150, rotations=rotations, rule=rule,
                                      seed=3))
    result = sim.run()
    doc = json.loads(json.dumps(output_json(result, problem, rotations=rotations)))
    assert doc["teamSize"] == 50 and doc["makespan"] == 150
    assert doc["actionModel"] == ("MAPF_T" if rotations else "MAPF")
    plan = read_plan_from(doc)
    cols = problem.grid.cols
    for i in range(50):
        executed = [divmod(s[1], cols) for s in result.actual[i]]
        assert _pad(plan.paths[i], 151) == _pad(executed, 151)
        if rotations:
            assert _pad(plan.headings[i], 151) == _pad(result.headings[i], 151)
            for (a, b), h in zip(zip(executed, executed[1:], strict=False),
                                 result.headings[i][:-1], strict=True):
                if a != b:  # the rotation model: a robot moves only straight ahead
                    assert (b[0] - a[0], b[1] - a[1]) == ((0, 1), (1, 0), (0, -1), (-1, 0))[h]
    assert doc["numTaskFinished"] == len(result.world.completed_tick) > 0


def test_cli_writes_output_and_refuses_what_it_cannot_do(tmp_path):
    out = tmp_path / "run"
    r = runner.invoke(app, ["lorr", str(PROBLEM), "--ticks", "40", "--out", str(out),
                            "--json", "--dist-budget-mb", "0.1"])
    assert r.exit_code == 0, r.output
    figures = json.loads(r.stdout)  # one JSON document, nothing else on stdout
    doc = json.loads((out / "output.json").read_text())
    assert doc["numTaskFinished"] == figures["tasks_finished"]
    assert doc["sumOfCost"] == figures["sum_of_cost"] == 50 * 40
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["orders_completed"] == figures["tasks_finished"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    assert figures["ticks"] == 40 and figures["ms_per_tick_mean"] > 0
    for args, what in ((["--rotation-rule", "spin"], "--rotation-rule"),
                       (["--ticks", "0"], "--ticks"), (["--seed", "-1"], "--seed"),
                       (["--set", "executor.dt_s=-1"], "executor.dt_s")):
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
