"""Studies: the full product of cells, a SIGKILL-ed study resuming each cell exactly once,
external solvers that fail or write bad plans becoming rows, AET recomputed from the kept
trajectories, solver binaries resolved (or a clear error), lifelong cells, the report."""

from __future__ import annotations

import csv
import itertools
import json
import os
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import yaml
from pool_helpers import kill_mid_run, on_local_ray, outlived
from typer.testing import CliRunner

from warerover_phys.cli import app
from warerover_phys.problems.movingai import read_map, read_scen
from warerover_phys.study import StudyError, expand, load_study, run_study
from warerover_phys.study.cells import cell_id
from warerover_phys.study.report import rank_correlation, write_study_report

REPO = Path(__file__).resolve().parents[2]
DATA = REPO / "tests" / "data"
MAP = DATA / "random-32-32-10.map"
SCEN = DATA / "random-32-32-10-random-1.scen"

ROBOTS = {"quick": {"max_speed_mps": 1.0, "max_accel_mps2": 1.0, "max_turn_rate_radps": 2.0},
          "slow": {"max_speed_mps": 0.6, "max_accel_mps2": 0.5, "max_turn_rate_radps": 0.8}}


def write_spec(tmp_path: Path, name: str = "study.yaml", **over) -> Path:
    data = {"name": "t", "instances": [{"map": str(MAP), "scens": [str(SCEN)],
                                        "agents": [6, 8]}],
            "planners": {"lacam": {"solver": "lacam", "time_limit_s": 5},
                         "pibt": {"solver": "pibt", "time_limit_s": 5}},
            "robots": ROBOTS, **over}
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def lines(out: Path) -> list[dict]:
    return [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines() if x]


def test_two_by_two_by_two_study_gives_the_full_product(tmp_path):
    spec = load_study(write_spec(tmp_path))
    out = tmp_path / "out"
    summary = run_study(spec, out, workers=2)
    assert summary.total == summary.ran == 8 and summary.failed == 0
    rows = lines(out)
    combos = Counter((r["agents"], r["planner"], r["robot"]) for r in rows)
    assert set(combos) == set(itertools.product([6, 8], ["lacam", "pibt"], ["quick", "slow"]))
    assert set(combos.values()) == {1}
    assert {r["key"] for r in rows} == {c.key for c in expand(spec)}
    table = pq.read_table(out / "results.parquet").to_pylist()
    with open(out / "results.csv", newline="") as fh:
        csv_rows = list(csv.DictReader(fh))
    assert len(table) == len(csv_rows) == 8
    for col in ("planner", "instance", "agents", "robot", "seed", "solve_s", "soc",
                "makespan", "lower_bound", "aet_s", "executed_makespan_s", "makespan_ratio",
                "soc_ratio", "lost_dependency_s_total", "lost_turning_s_total",
                "agv_contacts", "deadlocks", "real_time_factor"):
        assert col in table[0], col
    for r in table:
        assert r["status"] == "ok" and r["soc"] >= r["lower_bound"] > 0
        assert r["aet_s"] > 0 and r["executed_makespan_s"] >= r["aet_s"]
    by = {(r["agents"], r["planner"], r["robot"]): r for r in table}
    for n, p in itertools.product([6, 8], ["lacam", "pibt"]):
        quick, slow = by[n, p, "quick"], by[n, p, "slow"]
        assert quick["plan_id"] == slow["plan_id"]  # one plan, solved once, run twice
        assert quick["soc"] == slow["soc"]
        assert slow["aet_s"] > quick["aet_s"]  # slower robots, the same plan
    again = run_study(spec, out, workers=2)
    assert again.ran == 0 and again.done_before == 8


def test_mismatch_slows_the_same_plan(tmp_path):
    spec = load_study(write_spec(tmp_path, planners={"lacam": {"solver": "lacam"}},
                                 robots={"quick": ROBOTS["quick"]},
                                 mismatch={"exact": {}, "slower": {"turn_rate": 0.5,
                                                                   "speed": 0.8}}))
    run_study(spec, tmp_path / "out", workers=1)
    rows = {(r["agents"], r["mismatch"]): r for r in lines(tmp_path / "out")}
    for n in (6, 8):
        assert rows[n, "slower"]["plan_id"] == rows[n, "exact"]["plan_id"]
        assert rows[n, "slower"]["aet_s"] > rows[n, "exact"]["aet_s"]
        assert rows[n, "slower"]["planned_soc_s"] == rows[n, "exact"]["planned_soc_s"]


def test_sigkill_mid_study_then_resume_runs_each_cell_once(tmp_path):
    path = write_spec(tmp_path, seeds=[0, 1, 2, 3, 4])
    total = len(expand(load_study(path)))
    out = tmp_path / "out"
    results = out / "results.jsonl"
    before, workers = kill_mid_run(["study", str(path), "--out", str(out), "--workers", "2"],
                                   results, timeout_s=120)
    assert 4 <= before < total, "kill the study mid-way"
    assert not outlived(workers), "worker processes outlived the killed study"
    with open(results, "ab") as fh:  # a write cut short by the kill
        fh.write(b'{"key": "[\\"oneshot')
    summary = run_study(load_study(path), out, workers=2)
    assert summary.done_before == before and summary.ran == total - before
    counts = Counter(r["key"] for r in lines(out))
    assert set(counts) == {c.key for c in expand(load_study(path))}
    assert set(counts.values()) == {1}
    assert all(r["status"] == "ok" for r in lines(out))
    assert len(pq.read_table(out / "results.parquet")) == total


BAD_SOLVER = '''
import sys
mode, out, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
if mode == "fail":
    print("solver says: boom", file=sys.stderr)
    sys.exit(3)
if mode == "garbage":
    open(out, "w").write("this is not a plan\\n")
elif mode == "conflict":  # every agent on the same two cells: a vertex conflict
    lines = ["agents=%d" % n, "solution="] + ["%d:" % t + "(0,0)," * n for t in range(2)]
    open(out, "w").write("\\n".join(lines) + "\\n")
# mode "silent": exits 0 and writes nothing
'''


def test_external_solver_that_fails_or_writes_a_bad_plan_becomes_a_row(tmp_path):
    script = tmp_path / "bad_solver.py"
    script.write_text(BAD_SOLVER, encoding="utf-8")
    planners = {"lacam": {"solver": "lacam"}}
    for mode in ("fail", "garbage", "conflict", "silent"):
        planners[mode] = {"command": f"{{python}} {script} {mode} {{out}} {{n}}",
                          "time_limit_s": 5}
    path = write_spec(tmp_path, planners=planners, robots={"quick": ROBOTS["quick"]},
                      solvers={"python": {"path": sys.executable}})
    result = CliRunner().invoke(app, ["study", str(path), "--out", str(tmp_path / "out"),
                                      "--workers", "2", "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["cells"] == 10 and summary["failed"] == 8
    rows = {(r["planner"], r["agents"]): r for r in lines(tmp_path / "out")}
    for n in (6, 8):
        assert rows["lacam", n]["status"] == "ok"
        for mode in ("fail", "garbage", "conflict", "silent"):
            r = rows[mode, n]
            assert r["status"] == "failed" and r.get("aet_s") is None and not r["solved"]
        assert rows["fail", n]["error"] == "command exited with code 3: solver says: boom"
        assert rows["fail", n]["stage"] == "solve"
        assert rows["garbage", n]["stage"] == "read"
        assert rows["conflict", n]["stage"] == "validate"
        assert "starts at (0, 0)" in rows["conflict", n]["error"]
        assert "wrote no plan" in rows["silent", n]["error"]


def test_aet_is_the_mean_finish_seen_in_the_trajectories(tmp_path):
    spec = load_study(write_spec(tmp_path, robots={"slow": ROBOTS["slow"]},
                                 execution={"dt_s": 0.1, "trajectory_hz": 10,
                                            "keep_trajectories": True}))
    out = tmp_path / "out"
    run_study(spec, out, workers=2)
    grid = read_map(MAP)
    checked = 0
    for row in lines(out):
        assert row["status"] == "ok"
        scen = read_scen(SCEN, row["agents"], grid)
        with np.load(out / "cells" / cell_id(row["key"]) / "trajectories.npz") as z:
            t, x, y, cell = z["t"], z["x"], z["y"], float(z["cell_m"])
        gx = np.array([(a.goal[1] + 0.5) * cell for a in scen])
        gy = np.array([(a.goal[0] + 0.5) * cell for a in scen])
        away = np.hypot(x - gx, y - gy) > 0.02  # (T, N): not yet at rest on the goal
        assert not away[-1].any(), "every agent ends on its goal"
        last = away.shape[0] - 1 - np.argmax(away[::-1], axis=0)  # last sample away
        finish = t[last + 1]  # first sample from which it stays on its goal
        assert abs(finish.mean() - row["aet_s"]) < 0.15, (finish.mean(), row["aet_s"])
        assert abs(finish.max() - row["executed_makespan_s"]) < 0.25
        assert row["aet_s"] > row["planned_soc_s"] / row["agents"]  # slow robots lag the plan
        checked += 1
    assert checked == 4


def test_missing_solver_binary_is_one_clear_line(tmp_path, monkeypatch):
    monkeypatch.delenv("STUDY_TEST_LACAM3", raising=False)
    planners = {"lacam3": {"command": "{lacam3} -m {map} -i {scen} -N {n} -o {out} -t {time}"}}
    solvers = {"lacam3": {"path": str(tmp_path / "nowhere" / "main"), "env": "STUDY_TEST_LACAM3",
                          "build": "cmake -B build && make -C build"}}
    path = write_spec(tmp_path, planners=planners, solvers=solvers)
    result = CliRunner().invoke(app, ["study", str(path), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2
    err = " ".join(result.output.split())
    assert "solver 'lacam3' not found" in err and "solvers.lacam3.path is not an executable" \
        in err and "$STUDY_TEST_LACAM3" in err and "cmake -B build" in err
    assert "Traceback" not in result.output and not (tmp_path / "out").exists()
    fake = tmp_path / "fake_lacam3"
    fake.write_text("#!/bin/sh\nexit 7\n")
    fake.chmod(0o755)
    monkeypatch.setenv("STUDY_TEST_LACAM3", str(fake))
    spec = load_study(path)
    summary = run_study(spec, tmp_path / "out", workers=1)
    assert summary.failed == summary.total == 4
    assert all(r["error"] == "command exited with code 7" for r in lines(tmp_path / "out"))


@pytest.mark.parametrize("bad, field", [
    ({"planners": {"x": {"solver": "lacam", "command": "a"}}}, "planners.x"),
    ({"planners": {"x": {"command": "{nosuch} {out}"}}}, "planners.x"),
    ({"robots": {"big": {"footprint": 2}}}, "robots"),
    ({"exclude": [{"colour": "red"}]}, "exclude"),
    ({"seeds": []}, "seeds"),
    ({"instances": [{"map": "missing.map", "scens": ["x.scen"], "agents": [2]}]},
     "instances[0].map"),
])
def test_bad_study_files_fail_on_one_line(tmp_path, bad, field):
    path = write_spec(tmp_path, **bad)
    with pytest.raises(StudyError) as info:
        load_study(path)
    assert str(path) in str(info.value) and field in str(info.value)
    result = CliRunner().invoke(app, ["study", str(path), "--out", str(tmp_path / "o")])
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) <= 3  # one line (wrapped by the console)


def test_exclude_rules_leave_cells_out(tmp_path):
    spec = load_study(write_spec(tmp_path, exclude=[{"agents": 8, "robots": ["slow"]}]))
    cells = expand(spec)
    assert len(cells) == 6
    assert not any(c.n == 8 and c.robot == "slow" for c in cells)


def test_lifelong_cells_report_throughput(tmp_path):
    from warerover_phys.config import load_scenario
    from warerover_phys.sim import run_episode

    scenario = REPO / "layouts" / "paper_homogeneous.yaml"
    path = tmp_path / "life.yaml"
    path.write_text(yaml.safe_dump({"lifelong": {
        "scenarios": {"Ho": str(scenario)},
        "planners": {"astar": {"planner.name": "astar"}, "pibt": {"planner.name": "pibt"}},
        "grid": {"orders.oneshot.count": [4, 6]},
        "set": {"max_ticks": 80}, "seeds": [0, 1]}}))
    run_study(load_study(path), tmp_path / "out", workers=2)
    rows = lines(tmp_path / "out")
    assert len(rows) == 8 and all(r["kind"] == "lifelong" and r["status"] == "ok" for r in rows)
    r = next(r for r in rows if r["planner"] == "pibt" and r["seed"] == 1
             and r["variant"] == "orders.oneshot.count=6")
    direct = run_episode(load_scenario(scenario, [("orders.oneshot.count", 6),
                                                  ("max_ticks", 80),
                                                  ("planner.name", "pibt")]), seed=1).metrics
    assert r["throughput"] == direct["throughput"] and r["ticks"] == direct["ticks"]
    report = write_study_report(tmp_path / "out", pictures=False)
    assert len(report["tables"]["lifelong"]) == 4
    # an override the scenario schema does not know stops the study before it runs
    bad = yaml.safe_load(path.read_text())
    bad["lifelong"]["grid"] = {"planner.no_such_key": [1]}
    path.write_text(yaml.safe_dump(bad))
    result = CliRunner().invoke(app, ["study", str(path), "--out", str(tmp_path / "o2")])
    assert result.exit_code == 2 and "planner.no_such_key" in " ".join(result.output.split())
    assert "Traceback" not in result.output


def test_robot_runners_lifelong_cells_sweep_invoke_and_latency(tmp_path):
    from warerover_phys.problems.robotrunners import problem_scenario, read_problem
    from warerover_phys.sim import run_episode

    problem = DATA / "lorr2023_warehouse_small" / "warehouse_small_50.json"
    path = tmp_path / "rr.yaml"
    path.write_text(yaml.safe_dump({"lifelong": {
        "scenarios": {"small50": str(problem)}, "planners": {"pibt": {}},
        "grid": {"planner.latency": ["none", "fixed:2"]},
        "set": {"max_ticks": 40}, "seeds": [0]}}))
    run_study(load_study(path), tmp_path / "out", workers=1)
    rows = {r["variant"]: r for r in lines(tmp_path / "out")}
    assert set(rows) == {"planner.latency=none", "planner.latency=fixed:2"}
    assert all(r["status"] == "ok" and r["agents"] == 50 and r["ticks"] == 40
               for r in rows.values())
    for latency in ("none", "fixed:2"):
        sc = problem_scenario(read_problem(problem), ticks=40, seed=0,
                              overrides=[("planner.latency", latency)])
        direct = run_episode(sc, seed=0).metrics
        row = rows[f"planner.latency={latency}"]
        assert (row["throughput"], row["orders_completed"]) == \
            (direct["throughput"], direct["orders_completed"])
    # plans that arrive two ticks late cost throughput on this problem
    assert rows["planner.latency=fixed:2"]["orders_completed"] < \
        rows["planner.latency=none"]["orders_completed"]


def test_rank_correlation_and_its_interval():
    up = rank_correlation([1, 2, 3, 4, 5, 6], [10, 20, 30, 40, 50, 60])
    assert up["spearman"] == pytest.approx(1.0) and up["kendall"] == pytest.approx(1.0)
    assert up["spearman_lo"] == pytest.approx(1.0)
    down = rank_correlation([1, 2, 3, 4, 5, 6], [6, 5, 4, 3, 2, 1])
    assert down["spearman"] == pytest.approx(-1.0)
    rng = np.random.default_rng(3)
    x = rng.normal(size=40)
    mixed = rank_correlation(x, x + rng.normal(scale=2.0, size=40))
    assert mixed["spearman_lo"] < mixed["spearman"] < mixed["spearman_hi"]
    assert -1 <= mixed["kendall_lo"] < mixed["kendall_hi"] <= 1


def test_report_writes_tables_pictures_and_markdown(tmp_path):
    pytest.importorskip("matplotlib")
    spec = load_study(write_spec(tmp_path, mismatch={"exact": {}, "slow-turns":
                                                     {"turn_rate": 0.8}}))
    out = tmp_path / "out"
    run_study(spec, out, workers=2)
    result = CliRunner().invoke(app, ["study", "report", str(out)])
    assert result.exit_code == 0, result.output
    md = (out / "report.md").read_text()
    for part in ("## Planners", "## Model mismatch", "## Does SoC predict AET?",
                 "fig_aet_vs_soc.png", "Spearman"):
        assert part in md
    for name in ("fig_aet_vs_soc.png", "fig_aet_vs_agents.png", "fig_aet_vs_mismatch.png",
                 "fig_solve_vs_agents.png", "report_planners.csv", "report_correlation.csv"):
        assert (out / name).stat().st_size > 0, name
    data = json.loads(CliRunner().invoke(app, ["study", "report", str(out), "--json",
                                               "--no-pictures"]).stdout)
    corr = data["tables"]["correlation"]
    assert {(c["agents"], c["robot"], c["mismatch"]) for c in corr} == set(
        itertools.product([6, 8], ["quick", "slow"], ["exact", "slow-turns"]))
    assert all(c["points"] == 2 for c in corr)  # two planners, one scen, one seed


def test_rank_statistics_match_scipy_with_ties():
    from scipy.stats import kendalltau, spearmanr

    from warerover_phys.study.report import kendall_rows, spearman_rows

    rng = np.random.default_rng(7)
    x = rng.integers(0, 6, size=(30, 17)).astype(float)
    y = x + rng.integers(0, 5, size=(30, 17))
    for i in range(30):
        assert spearman_rows(x[i:i + 1], y[i:i + 1])[0] == pytest.approx(
            spearmanr(x[i], y[i]).statistic, abs=1e-12)
        assert kendall_rows(x[i:i + 1], y[i:i + 1])[0] == pytest.approx(
            kendalltau(x[i], y[i]).statistic, abs=1e-12)
    assert np.isnan(spearman_rows(np.ones((1, 5)), np.arange(5.0)[None]))[0]


def test_motion_timing_reads_the_same_plan_and_predicts_aet_better(tmp_path):
    planners = {"lacam": {"solver": "lacam"},
                "lacam+motion": {"solver": "lacam", "timing": "motion"},
                "pibt-rot": {"solver": "pibt", "rotations": True}}
    spec = load_study(write_spec(tmp_path, planners=planners,
                                 robots={"slow": ROBOTS["slow"]}))
    run_study(spec, tmp_path / "out", workers=2)
    rows = {(r["planner"], r["agents"]): r for r in lines(tmp_path / "out")}
    for n in (6, 8):
        unit, motion, rot = rows["lacam", n], rows["lacam+motion", n], rows["pibt-rot", n]
        assert motion["plan_id"] == unit["plan_id"] and motion["soc"] == unit["soc"]
        assert motion["aet_s"] == pytest.approx(unit["aet_s"])  # one plan, executed alike
        assert motion["planned_soc_s"] > unit["planned_soc_s"] == unit["soc"] * 1.0
        assert abs(motion["aet_over_planned"] - 1) < abs(unit["aet_over_planned"] - 1)
        assert rot["rotations"] and rot["plan_id"] != unit["plan_id"]
        assert rot["soc"] >= rot["lower_bound"]


def test_a_folder_of_plan_files_is_read_and_a_missing_one_is_a_row(tmp_path):
    from warerover_phys.planning.oneshot.core import solve, write_plan

    grid = read_map(MAP)
    scen = read_scen(SCEN, 6, grid)
    res = solve(grid.obstacles, [a.start for a in scen], [a.goal for a in scen],
                planner="pibt", time_limit_s=5)
    folder = tmp_path / "plans"
    folder.mkdir()
    write_plan(folder / f"{SCEN.stem}-6.txt", res)  # no plan for 8 agents
    spec = load_study(write_spec(tmp_path, planners={"given": {"plans": "plans"}},
                                 robots={"quick": ROBOTS["quick"]}))
    run_study(spec, tmp_path / "out", workers=1)
    rows = {r["agents"]: r for r in lines(tmp_path / "out")}
    assert rows[6]["status"] == "ok" and rows[6]["soc"] == res.sum_of_costs
    assert rows[6]["planner_kind"] == "plans" and rows[6]["aet_s"] > 0
    assert rows[8]["status"] == "failed" and rows[8]["stage"] == "read"
    assert rows[8]["error"].startswith("plan file not found:")


UNTIMED = ("host", "pid", "finished", "cell_wall_s", "cell_cpu_s", "task_wall_s", "plan_cpu_s",
           "solve_s", "execute_wall_s", "real_time_factor", "plan_kept")


@pytest.mark.slow
def test_pool_and_ray_give_the_same_rows(tmp_path):
    pytest.importorskip("ray")
    spec = load_study(write_spec(tmp_path, planners={"lacam": {"solver": "lacam"}}))
    run_study(spec, tmp_path / "pool", workers=2)
    summary, pids = on_local_ray(lambda: run_study(spec, tmp_path / "ray", ray_address="auto"),
                                 tmp_path / "ray" / "results.jsonl")
    assert summary.ran == 4 and summary.failed == 0 and os.getpid() not in pids

    def untimed(out):
        return {r["key"]: {k: v for k, v in r.items() if k not in UNTIMED} for r in lines(out)}

    assert untimed(tmp_path / "pool") == untimed(tmp_path / "ray")
