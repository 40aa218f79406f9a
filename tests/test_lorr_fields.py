"""The Robot Runners output fields of ``warerover lorr`` against the start kit's definitions
(issue 31), black-box: problems run through the command line, the output JSON read back.

The kit (``MAPF-Competition/Start-Kit``, ``BaseSystem::simulate`` / ``saveResults``) adds
one to a robot's cost for every timestep at whose start its goal list is not empty;
``sumOfCost`` is their sum, ``makespan`` their largest. With the 2023 ``roundrobin``
assignment every robot always has a goal, so ``sumOfCost`` = robots x timesteps. Tasks
finished on the last timestep's moves count. 2023 outputs keep the 2023 kit's ``events``
(per robot, ``[task, timestep, "assigned" | "finished"]``) and ``tasks`` (``[task, row,
col]``); 2024 and later, one event per errand done (``[timestep, robot, task, errands done
>= 1]``) and ``actualSchedule`` items ``t:task`` joined by commas (PlanViz reads both).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from hardening_helpers import cli_argv, cli_env

DATA = Path(__file__).parent / "data" / "lorr2023_warehouse_small"
PROBLEM = DATA / "warehouse_small_50.json"


def lorr(problem: Path, tmp_path: Path, *args: str) -> tuple[dict, dict]:
    """Run ``warerover lorr PROBLEM --out DIR --json ...``: (printed figures, output.json)."""
    out = tmp_path / "out"
    proc = subprocess.run(cli_argv("lorr", problem, "--out", out, "--json", "--quiet", *args),
                          cwd=tmp_path, env=cli_env(), capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout), json.loads((out / "output.json").read_text())


def problem_files(folder: Path, grid: list[str], starts: list[int], tasks: list[list[int]],
                  **keys) -> Path:
    """A Robot Runners problem in ``folder`` (``keys``: the problem JSON's other keys)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "m.map").write_text(f"type octile\nheight {len(grid)}\nwidth {len(grid[0])}\n"
                                  "map\n" + "\n".join(grid) + "\n")
    (folder / "a.agents").write_text(f"{len(starts)}\n" + "".join(f"{s}\n" for s in starts))
    (folder / "t.tasks").write_text(f"{len(tasks)}\n" + "".join(
        ",".join(map(str, t)) + "\n" for t in tasks))
    doc = {"mapFile": "m.map", "agentFile": "a.agents", "taskFile": "t.tasks",
           "teamSize": len(starts), "numTasksReveal": 1, **keys}
    (folder / "p.json").write_text(json.dumps(doc))
    return folder / "p.json"


@pytest.mark.parametrize("rotations", [True, False])
def test_roundrobin_sum_of_cost_is_robots_times_timesteps(tmp_path, rotations):
    """2023 roundrobin: every robot holds a task at every timestep (the kit reassigns with
    wrap-around), so sumOfCost = 50 x 40 and makespan = 40 (was 1,493 and 40: the robots'
    actions up to their last non-wait one)."""
    figures, doc = lorr(PROBLEM, tmp_path, "--ticks", "40",
                        *([] if rotations else ["--no-rotations"]))
    assert doc["teamSize"] == 50
    assert doc["sumOfCost"] == 50 * 40
    assert doc["makespan"] == 40
    assert doc["numTaskFinished"] == figures["tasks_finished"]


def test_2023_events_and_tasks_are_the_2023_kits(tmp_path):
    """Per robot ``[task, t, "assigned"]`` then ``[task, t, "finished"]``, each finish
    before the next assignment; ``tasks`` are ``[task, row, col]`` of the tasks assigned,
    each on the robot's path at its finishing timestep."""
    _, doc = lorr(PROBLEM, tmp_path, "--ticks", "60", "--no-rotations")
    events = doc["events"]
    assert len(events) == 50
    cells = {k: (r, c) for k, r, c in doc["tasks"]}
    paths = [_cells(s, doc["start"][i], doc["actionModel"]) for i, s in
             enumerate(doc["actualPaths"])]
    finished = 0
    for i, robot in enumerate(events):
        assert robot[0][2] == "assigned" and robot[0][1] == 0
        holding = None
        for task, t, what in robot:
            if what == "assigned":
                assert holding is None
                holding = task
            else:
                assert what == "finished" and task == holding
                assert paths[i][t] == cells[task]
                holding = None
                finished += 1
    assert finished == doc["numTaskFinished"] > 0


def test_a_task_finished_by_the_last_move_counts(tmp_path):
    """One robot, one task one cell ahead, one timestep: the kit checks tasks after every
    move, the last one too: 1 task finished (was 0)."""
    p = problem_files(tmp_path / "p", ["...."], [0], [[1], [2]],
                      taskAssignmentStrategy="roundrobin")
    _, doc = lorr(p, tmp_path, "--ticks", "1")
    assert doc["actualPaths"] == ["F"]
    assert doc["numTaskFinished"] == 1
    assert doc["events"] == [[[0, 0, "assigned"], [0, 1, "finished"]]]


def test_2024_events_schedule_and_idle_robots(tmp_path):
    """2024: numTasksReveal x teamSize = 1 open task for 2 robots, so exactly one robot
    holds a task at every timestep: sumOfCost = timesteps (a robot without a task costs
    nothing), makespan <= timesteps. Events are errands done (>= 1, never the assignment);
    ``actualSchedule`` items are ``t:task``, comma-joined (no trailing comma, which PlanViz
    cannot read), ``t`` one after the timestep the task was taken (as the kit records it)."""
    p = problem_files(tmp_path / "p", ["........"], [0, 7], [[3, 5], [6, 1], [2, 4]],
                      version="2024 LoRR", numTasksReveal=0.5)
    ticks = 30
    _, doc = lorr(p, tmp_path, "--ticks", str(ticks), "--no-rotations")
    assert doc["sumOfCost"] == ticks
    assert 0 < doc["makespan"] <= ticks
    assert doc["events"] and all(len(e) == 4 and e[3] >= 1 for e in doc["events"])
    tasks = {k: (rel, flat) for k, rel, flat in doc["tasks"]}
    for s in doc["actualSchedule"]:
        assert not s.endswith(",")
        for item in filter(None, s.split(",")):
            t, k = map(int, item.split(":"))
            assert t >= 1 and k in tasks
    # each task's errands were done in order, on the robot's path
    paths = [_cells(s, doc["start"][i], doc["actionModel"]) for i, s in
             enumerate(doc["actualPaths"])]
    for t, i, k, done in doc["events"]:
        flat = tasks[k][1]
        assert paths[i][t] == (flat[2 * done - 2], flat[2 * done - 1])
    assert doc["numTaskFinished"] == sum(1 for _, _, k, d in doc["events"]
                                         if d == len(tasks[k][1]) // 2)
    # the kit's per-robot cost, recounted from the schedule and the events alone: a task
    # recorded "t:k" was taken at t - 1 and is held until its last errand (or the end)
    done_at = {k: t for t, _, k, d in doc["events"] if d == len(tasks[k][1]) // 2}
    held = [sum(min(done_at.get(k, ticks), ticks) - (t - 1) for t, k in
                (map(int, item.split(":")) for item in filter(None, s.split(","))))
            for s in doc["actualSchedule"]]
    assert doc["sumOfCost"] == sum(held) and doc["makespan"] == max(held)


def _cells(actions: str, start: list, model: str) -> list[tuple[int, int]]:
    """A robot's cell at every timestep from its action string."""
    r, c, h = start[0], start[1], "ESWN".index(start[2])
    out = [(r, c)]
    steps = {"U": (-1, 0), "D": (1, 0), "L": (0, -1), "R": (0, 1)}
    for a in filter(None, actions.split(",")):
        if model == "MAPF":
            dr, dc = steps.get(a, (0, 0))
            r, c = r + dr, c + dc
        elif a == "F":
            dr, dc = ((0, 1), (1, 0), (0, -1), (-1, 0))[h]
            r, c = r + dr, c + dc
        elif a == "R":
            h = (h + 1) % 4
        elif a == "C":
            h = (h + 3) % 4
        out.append((r, c))
    return out


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__, "-q"]))
