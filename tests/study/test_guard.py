"""The study's wall-clock guards: a busy loop is interrupted, a cell whose execution or
plan outruns its guard is a row with status ``timeout`` (and stays done on a resume), and
the guards are not part of a cell's identity."""

from __future__ import annotations

import json
import signal
import sys
import time

import pytest
from test_study import ROBOTS, write_spec

from warerover_phys.study import expand, load_study, run_study
from warerover_phys.study.guard import CellTimeout, wall_guard


def test_the_guard_interrupts_a_busy_loop_and_restores_the_timer():
    before = signal.getsignal(signal.SIGALRM)
    t0 = time.perf_counter()
    with pytest.raises(CellTimeout, match="spin still running after 0.2 s"):
        with wall_guard(0.2, "spin"):
            while True:
                pass
    assert 0.2 <= time.perf_counter() - t0 < 2.0
    assert signal.getsignal(signal.SIGALRM) == before
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
    with wall_guard(None, "no limit") as g:  # no guard: check never raises
        g.check()


def _rows(out):
    return [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines() if x]


def test_an_execution_past_its_guard_is_a_timeout_row_and_stays_done(tmp_path):
    path = write_spec(tmp_path, execution={"cell_timeout_s": 0.05})
    spec = load_study(path)
    summary = run_study(spec, tmp_path / "out", workers=1)
    rows = _rows(tmp_path / "out")
    assert len(rows) == len(expand(spec)) == summary.ran
    assert {r["status"] for r in rows} == {"timeout"}
    assert {r["stage"] for r in rows} == {"execute"}
    assert all("the execution still running after 0.05 s" in r["error"] for r in rows)
    assert all(r["solved"] for r in rows)  # the plans were made: only execution stopped
    again = run_study(load_study(path), tmp_path / "out", workers=1)
    assert again.ran == 0 and again.failed_total == len(rows)


def test_a_solver_past_the_plan_guard_is_killed_and_its_cells_time_out(tmp_path):
    # a solver that ignores its 1 s limit: the guard (2 x 1 + 3 s) stops it long before
    # the command's own timeout (2 x 1 + 30 s)
    sleeper = tmp_path / "sleeper.py"
    sleeper.write_text("import time\ntime.sleep(60)\n", encoding="utf-8")
    path = write_spec(tmp_path, planners={"slow": {"command": f"{{python}} {sleeper}",
                                                   "time_limit_s": 1.0}},
                      solvers={"python": {"path": sys.executable}},
                      robots={"quick": ROBOTS["quick"]}, execution={"plan_grace_s": 3.0})
    t0 = time.perf_counter()
    run_study(load_study(path), tmp_path / "out", workers=1)
    assert time.perf_counter() - t0 < 40
    rows = _rows(tmp_path / "out")
    assert len(rows) == 2 and {r["status"] for r in rows} == {"timeout"}
    assert {r["stage"] for r in rows} == {"solve"}
    assert all("plan still running after 5 s" in r["error"] for r in rows)


def test_the_guards_do_not_change_the_cells_keys(tmp_path):
    a = expand(load_study(write_spec(tmp_path, "a.yaml")))
    b = expand(load_study(write_spec(tmp_path, "b.yaml", execution={
        "cell_timeout_s": 7.0, "plan_grace_s": 3.0})))
    assert [c.key for c in a] == [c.key for c in b]
    c = expand(load_study(write_spec(tmp_path, "c.yaml", execution={"dt_s": 0.05})))
    assert [x.key for x in a] != [x.key for x in c]


def test_max_minutes_stops_the_run_and_a_second_run_finishes_it(tmp_path):
    from collections import Counter

    from typer.testing import CliRunner

    from warerover_phys.cli import app

    path = write_spec(tmp_path, seeds=[0, 1])
    total = len(expand(load_study(path)))
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["study", str(path), "--out", str(out), "--workers", "1",
                                      "--max-minutes", "0.00001", "--json"])
    assert result.exit_code == 0, result.output
    first = json.loads(result.stdout)
    assert first["ran"] == 0 and first["left"] == total == first["cells"]
    assert not (out / "results.jsonl").read_text().strip()
    bad = CliRunner().invoke(app, ["study", str(path), "--out", str(out), "--max-minutes", "0"])
    assert bad.exit_code == 2 and "--max-minutes: must be above 0" in bad.output
    summary = run_study(load_study(path), out, workers=1, max_wall_s=600)
    assert summary.ran == total and summary.left == 0
    counts = Counter(r["key"] for r in _rows(out))
    assert set(counts.values()) == {1} and len(counts) == total
