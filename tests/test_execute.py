"""``warerover execute``: plans made elsewhere, validated, repaired and executed as written.

Every plan here is made with the project's own code (the one-shot solvers and the plan
writers): no third-party plan file is copied in.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from warerover_phys.cli import app
from warerover_phys.execute import (
    PlanError,
    execute_plan,
    find_cycles,
    load_fleet,
    load_floor,
    repair_cycles,
    validate_plan,
)
from warerover_phys.planning.oneshot.core import solve
from warerover_phys.plans import FORMATS, Plan, read_plan, write_plan
from warerover_phys.problems.movingai import read_map, read_scen
from warerover_phys.validate import validate_states

DATA = Path(__file__).parent / "data"
MAP = DATA / "random-32-32-10.map"
SCEN = DATA / "random-32-32-10-random-1.scen"
runner = CliRunner()

OPEN4 = "type octile\nheight 4\nwidth 4\nmap\n....\n....\n....\n....\n"


def _solved_plan(n: int = 20) -> Plan:
    m = read_map(MAP)
    agents = read_scen(SCEN, n)
    res = solve(m.obstacles, [a.start for a in agents], [a.goal for a in agents],
                planner="lacam", time_limit_s=30)
    assert res.success
    return Plan(tuple(tuple(p) for p in res.paths), rows=m.rows, cols=m.cols)


@pytest.fixture(scope="module")
def solved() -> Plan:
    return _solved_plan()


def _invoke(*args: str):
    return runner.invoke(app, list(args))


def _open_map(tmp_path: Path) -> Path:
    p = tmp_path / "open4.map"
    p.write_text(OPEN4)
    return p


def _validate_executed(result, layout, sizes):
    """The executed per-tick states pass the independent validator."""
    blocked = np.asarray(layout.grid) == 1
    conflicts = validate_states(result.executed, blocked,
                                sizes=dict(enumerate(sizes)))
    moves = [c for c in conflicts if c.kind != "move"]  # physics ticks are not grid moves
    return moves


@pytest.mark.parametrize("executor", ["grid", "physics"])
def test_solved_plan_executes_with_no_contacts(solved, executor):
    layout, _, _ = load_floor(MAP)
    types = load_fleet(None, solved.num_agents, None, [])
    validate_plan(solved, layout, [1] * solved.num_agents)
    plan, repairs = repair_cycles(solved, layout, [1] * solved.num_agents)
    result = execute_plan(plan, layout, types, executor=executor, seed=1)
    m = result.metrics
    assert m["completed"] and m["collisions"] == 0
    assert m.get("agv_contacts", 0) == 0 and m.get("static_contacts", 0) == 0
    assert _validate_executed(result, layout, [1] * plan.num_agents) == []
    assert m["planned_sum_of_costs_ticks"] == sum(plan.costs)
    if executor == "grid":  # the ideal executor runs the plan exactly
        assert m["executed_makespan_ticks"] == m["planned_makespan_ticks"]
        assert result.executed_finish == result.planned_finish
    else:  # bodies accelerate and turn: never faster than a 1 m/s plan at 1 m/s
        assert m["executed_makespan_ticks"] >= m["planned_makespan_ticks"]
    # every agent ends on its plan's last cell
    for i, states in result.executed.items():
        assert divmod(states[-1][1], layout.cols) == plan.paths[i][-1]


def test_same_seed_same_execution(solved):
    layout, _, _ = load_floor(MAP)
    types = load_fleet(None, solved.num_agents, None, [])
    from warerover_phys.config import DelaySpec

    delays = DelaySpec(model="bernoulli", prob=0.05, min_ticks=1, max_ticks=3)
    a = execute_plan(solved, layout, types, seed=4, delays=delays)
    b = execute_plan(solved, layout, types, seed=4, delays=delays)
    assert a.executed == b.executed and a.executed_finish == b.executed_finish
    assert a.metrics["agv_contacts"] == 0 and a.metrics["delay_injected_s"] > 0


@pytest.mark.parametrize("fmt", [f for f in FORMATS if f != "robotrunners"])
def test_pipeline_every_format(tmp_path, solved, fmt):
    """solve -> write in each format -> execute reads it (format detected) -> exit 0."""
    plan_file = tmp_path / f"plan.{fmt}"
    write_plan(solved, plan_file, fmt)
    assert read_plan(plan_file).paths == solved.paths
    out = tmp_path / "out"
    r = _invoke("execute", str(MAP), "--plan", str(plan_file), "--executor", "grid",
                "--out", str(out), "--json")
    assert r.exit_code == 0, r.output
    m = json.loads(r.stdout)
    assert m["completed"] and m["executed_sum_of_costs_ticks"] == sum(solved.costs)
    assert {p.name for p in out.iterdir()} >= {"metrics.json", "events.jsonl", "paths.json",
                                               "agents.csv", "trajectories.npz"}


def test_robot_runners_plan_with_turns(tmp_path):
    """Robot Runners plans turn in place (a timestep each): turns are waits on the grid."""
    floor = _open_map(tmp_path)
    # agent 0: east along row 0, turn right (south) for a step, then down column 2
    cells = ((0, 0), (0, 1), (0, 2), (0, 2), (1, 2), (2, 2))
    heads = (0, 0, 0, 1, 1, 1)
    plan = Plan((cells, ((3, 3),)), headings=(heads, (2,)))
    f = tmp_path / "rr.json"
    write_plan(plan, f, "robotrunners")
    assert read_plan(f).paths == plan.paths
    r = _invoke("execute", str(floor), "--plan", str(f), "--executor", "grid", "--json",
                "--out", str(tmp_path / "o"))
    assert r.exit_code == 0, r.output
    m = json.loads(r.stdout)
    assert m["executed_makespan_ticks"] == m["planned_makespan_ticks"] == 5


@pytest.mark.slow  # solve, execute, export and an H.264 video through the CLI: make test-all
def test_solve_then_execute_cli_with_export_and_video(tmp_path):
    plan_file = tmp_path / "plan.txt"
    r = _invoke("solve", str(MAP), str(SCEN), "--agents", "10", "--out", str(plan_file))
    assert r.exit_code == 0, r.output
    export = tmp_path / "executed.txt"
    video = tmp_path / "plan.mp4"
    r = _invoke("execute", str(MAP), "--plan", str(plan_file), "--out", str(tmp_path / "o"),
                "--export", str(export), "--video", str(video), "--json")
    assert r.exit_code == 0, r.output
    m = json.loads(r.stdout)
    assert m["executor"] == "physics" and m["agv_contacts"] == 0 and m["completed"]
    executed = read_plan(export)
    assert executed.num_agents == 10
    assert video.stat().st_size > 10_000


def test_rotation_is_found_repaired_or_refused(tmp_path):
    floor = _open_map(tmp_path)
    layout, _, _ = load_floor(floor)
    cells = [(1, 1), (1, 2), (2, 2), (2, 1)]  # a 2x2 block, turned one step clockwise
    plan = Plan(tuple((c, cells[(i + 1) % 4], cells[(i + 2) % 4]) for i, c in enumerate(cells)))
    validate_plan(plan, layout, [1] * 4)  # a rotation is valid MAPF ...
    cycles = find_cycles(plan, layout.cols)
    assert len(cycles) == 2 and set(cycles[0].agents) == {0, 1, 2, 3}
    with pytest.raises(PlanError, match="move round a cycle"):
        repair_cycles(plan, layout, [1] * 4, strict=True)
    fixed, repairs = repair_cycles(plan, layout, [1] * 4)
    assert repairs and find_cycles(fixed, layout.cols) == []
    validate_plan(fixed, layout, [1] * 4)
    assert [p[-1] for p in fixed.paths] == [p[-1] for p in plan.paths]
    result = execute_plan(fixed, layout, load_fleet(None, 4, None, []), executor="physics")
    assert result.metrics["completed"] and result.metrics["agv_contacts"] == 0
    plan_file = tmp_path / "rot.txt"
    write_plan(plan, plan_file, "lacam")
    r = _invoke("execute", str(floor), "--plan", str(plan_file), "--strict",
                "--out", str(tmp_path / "strict"))
    assert r.exit_code == 2 and "move round a cycle" in r.output
    assert not (tmp_path / "strict").exists()
    r = _invoke("execute", str(floor), "--plan", str(plan_file), "--json",
                "--out", str(tmp_path / "ok"))
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["cycle_repairs"] >= 1


BAD = {
    "vertex": ("lns", "Agent 0:(0,0)->(0,1)->\nAgent 1:(0,2)->(0,1)->\n", "vertex conflict"),
    "swap": ("lns", "Agent 0:(0,0)->(0,1)->\nAgent 1:(0,1)->(0,0)->\n", "swap conflict"),
    "jump": ("lns", "Agent 0:(0,0)->(0,2)->\n", "more than one cell"),
    "off-map": ("lns", "Agent 0:(0,3)->(0,4)->\n", "off the 4 x 4 map"),
    "obstacle": ("lns", "Agent 0:(1,0)->(1,1)->\n", "is an obstacle"),
    "bad-header": ("lacam", "agents=two\nsolution=\n0:(0,0),\n", "agents"),
    "truncated": ("lacam", "agents=2\nsolution=\n0:(0,0),(1,", ""),
    "too-many-agents": ("lns", "".join(f"Agent {i}:({i // 4},{i % 4})->\n" for i in range(17)),
                        ""),
    "other-map-size": ("lacam", "agents=1\nwidth=9\nheight=9\nsolution=\n0:(0,0),\n", ""),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_plans_exit_2_one_line_write_nothing(tmp_path, case):
    fmt, text, expect = BAD[case]
    floor = tmp_path / "f.map"
    grid = ["....", ".@..", "....", "...."] if case == "obstacle" else ["...."] * 4
    floor.write_text("type octile\nheight 4\nwidth 4\nmap\n" + "\n".join(grid) + "\n")
    if case == "too-many-agents":
        floor.write_text("type octile\nheight 4\nwidth 4\nmap\n" + "\n".join(["...."] * 4))
    plan = tmp_path / "plan.txt"
    plan.write_text(text)
    out = tmp_path / "out"
    r = _invoke("execute", str(floor), "--plan", str(plan), "--out", str(out))
    assert r.exit_code == 2, (case, r.output)
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in r.output, r.output
    assert str(plan) in lines[0] or "plan" in lines[0]
    assert expect in lines[0], lines[0]
    assert not out.exists()


def test_validation_names_agent_and_timestep():
    layout, _, _ = load_floor(MAP)
    plan = _solved_plan(5)
    bad = list(plan.paths)
    bad[3] = bad[1]  # agent 3 copies agent 1: a vertex conflict from timestep 0
    with pytest.raises(PlanError) as info:
        validate_plan(Plan(tuple(bad)), layout, [1] * 5, source="p.txt")
    msg = str(info.value)
    assert msg.startswith("p.txt: agent 1, timestep 0: vertex conflict with agent 3")


def test_fleet_file_and_footprints(tmp_path):
    fleet = tmp_path / "fleet.yaml"
    fleet.write_text("types:\n  big: {footprint: 2, body_m: [1.4, 1.4]}\n"
                     "  small: {}\nagents: [big, small]\n")
    types = load_fleet(fleet, 2, None, [])
    assert [t.footprint for t in types] == [2, 1]
    floor = _open_map(tmp_path)
    layout, _, _ = load_floor(floor)
    # the 2x2 AGV at (0,0) covers (1,1): a 1x1 AGV there is a footprint conflict
    plan = Plan((((0, 0),), ((1, 1),)))
    with pytest.raises(PlanError, match="vertex conflict"):
        validate_plan(plan, layout, [2, 1])
    ok = Plan((((0, 0), (0, 1), (0, 2)), ((3, 0), (3, 1))))
    validate_plan(ok, layout, [2, 1])
    result = execute_plan(ok, layout, types, executor="physics")
    assert result.metrics["completed"] and result.metrics["agv_contacts"] == 0
    bad = tmp_path / "bad.yaml"
    bad.write_text("types:\n  a: {footprint: 0}\nagents: [a, a]\n")
    with pytest.raises(Exception, match="footprint"):
        load_fleet(bad, 2, None, [])


def test_layout_and_scenario_floors():
    root = Path(__file__).resolve().parent.parent / "layouts"
    layout, types, kinds = load_floor(root / "paper_homogeneous.yaml")
    assert layout.rows == 15 and len(kinds) == 9 and types
    layout2, types2, _ = load_floor(root / "maps" / "paper_20x15.yaml")
    assert types2 is None and (layout2.rows, layout2.cols) == (layout.rows, layout.cols)


def test_executor_options_reach_the_executor_and_bad_ones_exit_2(tmp_path, solved):
    """``warerover execute --set FIELD=VALUE``: the real-robot options of the executor
    section (issue 13) reach the physics executor; a bad one exits 2 naming it."""
    plan_file = tmp_path / "plan.txt"
    write_plan(solved, plan_file, "lacam")
    base = (str(MAP), "--plan", str(plan_file), "--json", "-q")
    r = _invoke("execute", *base, "--out", str(tmp_path / "a"), "--set", "no_slip=true",
                "--set", "executor.comm_latency_s=0.2")
    assert r.exit_code == 0, r.output
    m = json.loads(r.output)
    assert m["no_slip"] is True and m["comm_latency_s"] == 0.2
    assert m["delay_comm_latency_s"] > 0 and m["agv_contacts"] == 0
    for bad, field in (("bogus=1", "executor.bogus"), ("payload=maybe", "executor.payload"),
                       ("comm_latency_s=-1", "executor.comm_latency_s"),
                       ("dt_s=0.1", "executor.dt_s"), ("=3", "--set")):
        out = tmp_path / f"bad-{field}"
        r = _invoke("execute", *base, "--out", str(out), "--set", bad)
        assert r.exit_code == 2, (bad, r.output)
        assert field in r.output and "Traceback" not in r.output
        assert not out.exists()


def test_parking_changes_nothing_but_the_joints(solved):
    """``executor.park`` (default on) takes standing AGVs' drive joints out of the pymunk
    world: the execution is the same as with every joint always in it (same executed
    states; clearance within the 1 mm a parked body may sit off its hold point)."""
    layout, _, _ = load_floor(MAP)
    types = load_fleet(None, solved.num_agents, None, [])
    on = execute_plan(solved, layout, types, seed=2)
    off = execute_plan(solved, layout, types, seed=2, options={"park": False})
    assert on.executed == off.executed
    assert on.metrics["agv_contacts"] == off.metrics["agv_contacts"] == 0
    assert abs(on.metrics["min_clearance_m"] - off.metrics["min_clearance_m"]) < 1e-3
    assert on.metrics["parked_agv_s"] > 0 and off.metrics["parked_agv_s"] == 0
