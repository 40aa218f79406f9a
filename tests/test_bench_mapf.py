"""tools/bench_mapf.py: plan files read back, lacam3 found / built / reported missing, both
sides run as subprocesses and validated (a stand-in lacam3 in the default suite; the real
one, built from ../shared/reference/lacam3, under -m slow)."""

from __future__ import annotations

import json
import shutil
import stat

import numpy as np
import pytest
from tool_helpers import load_tool

from warerover_phys.planning.oneshot.core import OneShotResult, write_plan


def load_bench():
    return load_tool("bench_mapf")


bench = load_bench()


def test_plan_file_round_trip(tmp_path):
    paths = [[(1, 2), (1, 3), (2, 3)], [(0, 0), (0, 0), (0, 1)]]
    res = OneShotResult(True, paths, 3, 2, 3, 0.1, "lacam")
    write_plan(tmp_path / "p.txt", res)
    header, back = bench.read_plan_file(tmp_path / "p.txt")
    assert back == paths and header["solved"] == "1" and header["soc"] == "3"


def test_plan_file_without_solution(tmp_path):
    (tmp_path / "p.txt").write_text("agents=2\nsolved=0\n")
    header, back = bench.read_plan_file(tmp_path / "p.txt")
    assert back is None and header["solved"] == "0"


def test_lacam3_missing_tools_said_plainly(monkeypatch, tmp_path):
    monkeypatch.delenv("WARERO_LACAM3", raising=False)
    monkeypatch.setattr(bench, "LACAM3_BUILD", tmp_path / "none")
    monkeypatch.setattr(bench.shutil, "which", lambda tool: None)
    binary, msg = bench.find_lacam3(None, tmp_path)
    assert binary is None
    assert "cmake and g++ not found" in msg and "--lacam3" in msg


def test_lacam3_given_path_must_be_executable(tmp_path, monkeypatch):
    monkeypatch.delenv("WARERO_LACAM3", raising=False)
    binary, msg = bench.find_lacam3(str(tmp_path / "nope"), tmp_path)
    assert binary is None and "not an executable" in msg


FAKE = """#!/bin/sh
# a stand-in for lacam3: copies a prepared plan to the -o file
while [ $# -gt 0 ]; do
  if [ "$1" = "-o" ]; then cp "{plan}" "$2"; fi
  shift
done
"""


def test_bench_runs_both_sides_and_validates(tmp_path):
    """Ours (the real CLI) beside a stand-in lacam3 that returns our own first plan: the
    bench validates both, recomputes the figures and prints ratios of 1."""
    from warerover_phys.planning.oneshot.core import solve
    from warerover_phys.problems.movingai import read_map, read_scen

    grid = read_map(bench.MAP_PATH)
    scen = read_scen(bench.scen_path(1), 12, grid)
    res = solve(grid.obstacles, [a.start for a in scen], [a.goal for a in scen])
    write_plan(tmp_path / "plan.txt", res)
    fake = tmp_path / "lacam3"
    fake.write_text(FAKE.format(plan=tmp_path / "plan.txt"))
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    out = tmp_path / "bench.json"
    code = bench.main(["--agents", "12", "--modes", "first", "--lacam3", str(fake),
                       "--json", str(out)])
    data = json.loads(out.read_text())
    assert code == 0
    runs = {r["impl"]: r for r in data["runs"]}
    assert runs["ours"]["success"] and runs["lacam3"]["success"]
    assert runs["ours"]["conflicts"] == 0 == runs["lacam3"]["conflicts"]
    assert runs["ours"]["sum_of_costs"] == res.sum_of_costs == runs["lacam3"]["sum_of_costs"]
    assert data["comparison"][0]["soc_ours_over_lacam3"] == 1.0


def test_bench_reports_an_invalid_plan(tmp_path):
    """A 'solved' plan with a conflict is not a success."""
    paths = [[(1, 1), (1, 2)], [(1, 3), (1, 2)]]
    run = {"solved": True, "lower_bound": 2, "status": "solved"}
    obstacles = np.zeros((3, 5), dtype=bool)
    bench.finish_run(run, paths, [(1, 1), (1, 3)], [(1, 2), (1, 2)], obstacles)
    assert run["success"] is False and run["status"] == "invalid" and run["conflicts"] >= 1


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("cmake") is None or shutil.which("g++") is None,
                    reason="cmake and g++ are needed to build lacam3")
def test_real_lacam3_on_a_tiny_instance(tmp_path):
    if not (bench.LACAM3_SRC / "CMakeLists.txt").is_file():
        pytest.skip(f"no lacam3 sources at {bench.LACAM3_SRC}")
    out = tmp_path / "bench.json"
    code = bench.main(["--agents", "20", "--refine-time", "1", "--time-limit", "10",
                       "--json", str(out)])
    data = json.loads(out.read_text())
    assert code == 0
    assert {r["impl"] for r in data["runs"]} == {"ours", "lacam3"}
    assert all(r["success"] and r["conflicts"] == 0 for r in data["runs"])
    for row in data["comparison"]:
        assert row["soc_ours_over_lacam3"] is not None


def test_parts_breakdown(capsys):
    """``--parts``: our first solution part by part in a fresh interpreter, a valid plan."""
    assert bench.main(["--parts", "6", "--parts-engine", "python"]) == 0
    text = capsys.readouterr().out
    for part in ("interpreter", "imports", "distance tables", "guide paths", "LaCAM",
                 "validation", "plan file", "total"):
        assert part in text
    row = next(line for line in text.splitlines() if line.strip().startswith("SoC"))
    assert row.split()[-1] == "0"  # no conflicts
