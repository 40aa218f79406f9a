"""Sweeps: spec parsing and errors, the process pool and Ray giving the same metrics, a
SIGKILL-ed sweep resuming without losing or duplicating episodes, failed episodes kept,
plugins named by import path, and the report's confidence intervals."""

from __future__ import annotations

import csv
import doctest
import importlib
import json
import math
import os
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
import yaml
from pool_helpers import kill_mid_run, on_local_ray, outlived
from typer.testing import CliRunner

from warerover_phys.cli import app
from warerover_phys.config import load_scenario
from warerover_phys.errors import ScenarioError, WareroverError
from warerover_phys.metrics import TIMING_KEYS
from warerover_phys.registry import check_plugins
from warerover_phys.sim import run_episode
from warerover_phys.sweep import (
    ResultsFile,
    SweepError,
    aggregate,
    episode_key,
    expand,
    load_sweep,
    mean_ci,
    run_sweep,
    write_report,
)
from warerover_phys.sweep.spec import narrow

REPO = Path(__file__).resolve().parents[2]
HOMOGENEOUS = REPO / "layouts" / "paper_homogeneous.yaml"
HETEROGENEOUS = REPO / "layouts" / "paper_heterogeneous.yaml"

# A short episode: 6 one-shot orders on the paper map (about 0.05 s each).
SMALL_SET = {"orders.oneshot.count": 6, "max_ticks": 80}

PLUGINS = '''
from warerover_phys.planning import AStarPlanner


class ReversedAStar:
    """Prioritized A*, planning the AGVs in reverse request order."""

    name = "reversed-astar"
    replans_all = False

    def __init__(self, spec):
        self.inner = AStarPlanner(max_expansions=spec.max_expansions)

    def plan(self, request):
        request.agents = list(reversed(request.agents))
        return self.inner.plan(request)


class Boom:
    """A planner that raises: its episodes must be recorded as failed."""

    name = "boom"
    replans_all = False

    def __init__(self, spec):
        pass

    def plan(self, request):
        raise RuntimeError("boom at tick %d" % request.tick)


class Crash:
    """A planner that kills its worker process outright."""

    name = "crash"
    replans_all = False

    def __init__(self, spec):
        pass

    def plan(self, request):
        import os

        os._exit(7)
'''


def write_sweep(folder: Path, **fields: Any) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    data = {"name": "small", "scenarios": {"Ho": str(HOMOGENEOUS)},
            "grid": {"scheduler.name": ["ta", "rd"]}, "set": dict(SMALL_SET),
            "repetitions": 2, **fields}
    path = folder / "sweep.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def plugin_module(folder: Path, name: str = "sweep_test_plugins") -> str:
    (folder / f"{name}.py").write_text(PLUGINS, encoding="utf-8")
    importlib.invalidate_caches()
    return name


def result_lines(out: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]


def untimed(metrics: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in metrics.items() if k not in TIMING_KEYS}


# ------------------------------------------------------------------------------- spec


def test_expand_seed_major_with_exclude_and_keys(tmp_path):
    path = write_sweep(tmp_path, scenarios={"Ho": str(HOMOGENEOUS), "He": str(HETEROGENEOUS)},
                       grid={"scheduler.name": ["ta", "rd"], "planner.name": ["astar", "cbs"]},
                       exclude=[{"scenario": "He", "scheduler.name": "rd"}], repetitions=3,
                       seed_start=5)
    eps = expand(load_sweep(path))
    assert len(eps) == 3 * (4 + 2)
    assert [e.seed for e in eps[:6]] == [5] * 6 and eps[-1].seed == 7
    assert not any(e.label == "He" and ("scheduler.name", "rd") in e.overrides for e in eps)
    assert len({e.key for e in eps}) == len(eps)
    # the key is (label, sorted overrides, seed) and does not depend on the order given
    e = eps[0]
    assert e.key == episode_key("Ho", dict(reversed(e.overrides)), 5)
    assert json.loads(e.key) == ["Ho", [list(kv) for kv in e.overrides], 5]
    assert dict(e.overrides)["max_ticks"] == 80


def test_narrow_keeps_keys(tmp_path):
    spec = load_sweep(write_sweep(tmp_path, repetitions=4))
    small = narrow(spec, repetitions=2, only=[("scheduler.name", "rd")])
    keys = {e.key for e in expand(small)}
    assert len(keys) == 2 and keys < {e.key for e in expand(spec)}
    with pytest.raises(SweepError, match="not one of the grid's values"):
        narrow(spec, only=[("scheduler.name", "fifo")])


def test_sweep_module_doctests(monkeypatch):
    monkeypatch.chdir(REPO)
    for name in ("warerover_phys.sweep.spec", "warerover_phys.sweep.report"):
        result = doctest.testmod(importlib.import_module(name))
        assert result.attempted > 0 and result.failed == 0, name


# Bad sweep files: (id, how to change the base file, field path in the message, other text)
BAD = [
    ("unknown-key", {"repetitons": 3}, "repetitons", "unknown key"),
    ("no-scenarios", {"scenarios": None}, "scenarios", ""),
    ("scenario-file-missing", {"scenarios": {"Ho": "nope.yaml"}}, "scenarios.Ho",
     "not found"),
    ("bad-planner-in-grid", {"grid": {"planner.name": ["astar", "dijkstra"]}},
     "grid.planner.name", "'dijkstra'"),
    ("bad-override-path", {"set": {"orders.colour": 1}}, "set.orders.colour", "unknown key"),
    ("bad-override-value", {"set": {"max_ticks": -3}}, "set.max_ticks", "(got -3)"),
    ("seeds-and-repetitions", {"seeds": [1, 2]}, "", "exactly one of repetitions"),
    ("empty-grid-values", {"grid": {"planner.name": []}}, "grid", "lists no values"),
    ("seed-as-override", {"set": {"seed": 3}}, "set", "repetitions"),
    ("exclude-unknown-path", {"exclude": [{"planner.name": "cbs"}]}, "",
     "neither 'scenario' nor a grid path"),
    ("plugin-not-importable", {"grid": {"planner.name": ["no_such_module_xyz:Planner"]}},
     "grid.planner.name", "cannot import plugin module"),
    ("plugin-missing-class", {"grid": {"planner.name": ["json:NoSuchPlanner"]}},
     "grid.planner.name", "has no attribute"),
    ("plugin-not-a-planner", {"grid": {"planner.name": ["json:JSONDecoder"]}},
     "grid.planner.name", "missing plan()"),
]


@pytest.mark.parametrize("change,field,text", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_sweep_file_one_line_exit_2(tmp_path, change, field, text):
    path = write_sweep(tmp_path)
    data = yaml.safe_load(path.read_text())
    for k, v in change.items():
        if v is None:
            data.pop(k)
        else:
            data[k] = v
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    result = CliRunner().invoke(app, ["sweep", str(path), "--out", str(tmp_path / "out")],
                                env={"COLUMNS": "60", "NO_COLOR": "1"})
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith(f"error: {path}: ")
    if field:
        assert f": {field}" in lines[0]
    assert text in lines[0]
    assert not (tmp_path / "out" / "results.jsonl").exists()


def test_bad_yaml_and_missing_file_through_console_script(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("scenarios: [unclosed\n", encoding="utf-8")
    exe = str(Path(sys.executable).parent / "warerover")
    env = {**os.environ, "COLUMNS": "60", "NO_COLOR": "1", "TERM": "dumb"}
    cases = [(["sweep", str(bad), "--out", str(tmp_path / "o")], "invalid YAML: line"),
             (["sweep", str(tmp_path / "none.yaml"), "--out", str(tmp_path / "o")], "not found"),
             (["report", str(tmp_path / "none")], "no such folder")]
    procs = [subprocess.Popen([exe, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True, env=env) for args, _ in cases]
    for proc, (_, text) in zip(procs, cases, strict=True):
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 2
        assert err.count("\n") == 1 and text in err, err


# ------------------------------------------------------------------------------- running


@pytest.mark.slow  # a sweep on a pool and on a Ray cluster: make test-all
def test_pool_and_ray_give_identical_metrics(tmp_path):
    """The same sweep (with a plugin planner from the sweep's folder) on the process pool
    and on a real local Ray cluster: the same rows, the same metrics, CT aside."""
    mod = plugin_module(tmp_path)
    path = write_sweep(tmp_path, grid={"scheduler.name": ["ta", "rd"],
                                       "planner.name": ["astar", f"{mod}:ReversedAStar"]},
                       repetitions=1)
    spec = load_sweep(path)
    pool = run_sweep(spec, tmp_path / "pool", workers=2)
    assert pool.ran == pool.total == 4 and pool.failed == 0
    try:
        import ray  # noqa: F401
    except ImportError:
        pytest.skip("ray is not installed (pip install 'warerover-phys[ray]'); the pool half "
                    "of this test ran")
    on_ray, pids = on_local_ray(lambda: run_sweep(spec, tmp_path / "ray", ray_address="auto"),
                                tmp_path / "ray" / "results.jsonl")
    assert on_ray.ran == 4 and on_ray.failed == 0
    assert os.getpid() not in pids  # ran in Ray workers, not here
    a = {r["key"]: r for r in result_lines(tmp_path / "pool")}
    b = {r["key"]: r for r in result_lines(tmp_path / "ray")}
    assert a.keys() == b.keys() == {e.key for e in expand(spec)}
    for key in a:
        assert a[key]["status"] == b[key]["status"] == "ok"
        assert untimed(a[key]["metrics"]) == untimed(b[key]["metrics"]), key
    # and both equal a plain in-process run of the same episode
    ep = expand(spec)[0]
    direct = run_episode(load_scenario(HOMOGENEOUS, list(ep.overrides)), seed=ep.seed).metrics
    assert untimed(a[ep.key]["metrics"]) == untimed(direct)


@pytest.mark.slow  # a sweep killed and resumed: make test-all
def test_sigkill_mid_sweep_then_resume_runs_each_episode_once(tmp_path):
    path = write_sweep(tmp_path, set={**SMALL_SET, "orders.oneshot.count": 10},
                       grid={"scheduler.name": ["ta", "rd"], "planner.name": ["astar", "pibt"]},
                       repetitions=6)
    total = len(expand(load_sweep(path)))
    out = tmp_path / "out"
    results = out / "results.jsonl"
    before, workers = kill_mid_run(["sweep", str(path), "--out", str(out), "--workers", "2"],
                                   results)
    assert 4 <= before < total, "kill the sweep mid-way"
    assert not outlived(workers), "worker processes outlived the killed sweep"
    # a write cut short by the kill leaves a partial last line: simulate one
    with open(results, "ab") as fh:
        fh.write(b'{"key": "[\\"Ho\\",[[\\"max_t')
    summary = run_sweep(load_sweep(path), out, workers=2)
    assert summary.done_before == before and summary.ran == total - before
    rows = result_lines(out)  # every line parses: the partial line was cut off
    counts = Counter(r["key"] for r in rows)
    assert set(counts) == {e.key for e in expand(load_sweep(path))}
    assert set(counts.values()) == {1}
    assert all(r["status"] == "ok" for r in rows)
    again = run_sweep(load_sweep(path), out, workers=2)
    assert again.ran == 0 and len(result_lines(out)) == total


@pytest.mark.slow  # sweeps on a pool and on Ray: make test-all
def test_failing_and_crashing_episodes_are_recorded(tmp_path):
    mod = plugin_module(tmp_path, "sweep_test_failing")
    path = write_sweep(tmp_path, grid={"planner.name": ["astar", f"{mod}:Boom",
                                                        f"{mod}:Crash"]}, repetitions=2)
    summary = run_sweep(load_sweep(path), tmp_path / "out", workers=2)
    assert summary.ran == summary.total == 6 and summary.failed == 4
    rows = {(r["planner"].split(":")[-1], r["seed"]): r for r in result_lines(tmp_path / "out")}
    assert len(rows) == 6
    for seed in (0, 1):
        assert rows["astar", seed]["status"] == "ok"
        boom = rows["Boom", seed]
        assert boom["status"] == "failed" and boom["metrics"] is None
        assert boom["error"] == "RuntimeError: boom at tick 0"
        assert "raise RuntimeError" in boom["traceback"]
        assert rows["Crash", seed]["status"] == "failed"
        assert "worker process died" in rows["Crash", seed]["error"]
    # failed episodes count as recorded: a rerun runs nothing ...
    assert run_sweep(load_sweep(path), tmp_path / "out", workers=2).ran == 0
    # ... unless asked, and then each key still has one row
    retry = run_sweep(load_sweep(path), tmp_path / "out", workers=1, retry_failed=True)
    assert retry.ran == 4 and retry.failed == 4
    assert Counter(r["key"] for r in result_lines(tmp_path / "out")).most_common(1)[0][1] == 1
    report = write_report(tmp_path / "out")
    boom = next(g for g in report["groups"] if g.planner.endswith(":Boom") and g.pattern == "all")
    assert (boom.n, boom.failed) == (0, 2)
    assert "RuntimeError: boom at tick 0 | 2 |" in report["markdown"]


def test_results_file_tolerates_only_a_truncated_last_line(tmp_path):
    rf = ResultsFile(tmp_path / "results.jsonl")
    rf.append({"key": "a", "v": 1})
    rf.append({"key": "b", "v": float("nan")})
    rf.close()
    with open(rf.path, "ab") as fh:
        fh.write(b'{"key": "c", "v"')
    assert list(rf.load()) == ["a", "b"] and rf.load()["b"]["v"] is None
    rf.append({"key": "c", "v": 3})
    rf.close()
    assert [json.loads(x)["key"] for x in rf.path.read_text().splitlines()] == ["a", "b", "c"]
    # a whole last row whose newline was lost is kept
    rf.path.write_bytes(rf.path.read_bytes().rstrip(b"\n"))
    assert list(rf.load()) == ["a", "b", "c"]
    rf.append({"key": "d"})
    rf.close()
    assert len(rf.path.read_text().splitlines()) == 4
    # damage anywhere but the end is an error, not silently dropped data
    lines = rf.path.read_text().splitlines()
    rf.path.write_text("\n".join([lines[0], "{oops", *lines[1:]]) + "\n")
    with pytest.raises(WareroverError, match="line 2: not a result row"):
        rf.load()


# ------------------------------------------------------------------------------- plugins


def test_plugin_names_in_scenarios(tmp_path, monkeypatch):
    mod = plugin_module(tmp_path, "sweep_test_plugin_sc")
    monkeypatch.syspath_prepend(str(tmp_path))
    sc = load_scenario(HOMOGENEOUS, [("planner.name", f"{mod}:ReversedAStar"),
                                     *SMALL_SET.items()])
    m = run_episode(sc, seed=1).metrics
    assert m["planner"] == f"{mod}:ReversedAStar" and m["orders_completed"] > 0
    with pytest.raises(ScenarioError, match=r"unknown scheduler \(choose from \['errands', 'rd', 'ta'\]"):
        check_plugins(load_scenario(HOMOGENEOUS, [("scheduler.name", "fifo")]))
    with pytest.raises(ScenarioError, match="cannot import plugin module"):
        run_episode(load_scenario(HOMOGENEOUS, [("scheduler.name", "nope_mod:Sched")]))


def test_readme_plugin_example_runs_in_a_sweep(tmp_path):
    """The plug-in guide's example (docs/plugins.md), copied as it is, runs in a sweep."""
    readme = (REPO / "docs" / "plugins.md").read_text(encoding="utf-8")
    blocks = re.findall(r"<!-- plugin-example: (\S+) -->\s*```\w*\n(.*?)```", readme, re.S)
    assert [name for name, _ in blocks] == ["my_schedulers.py", "plugin_sweep.yaml"]
    for name, text in blocks:
        (tmp_path / name).write_text(text, encoding="utf-8")
    importlib.invalidate_caches()
    spec = load_sweep(tmp_path / "plugin_sweep.yaml")
    spec = narrow(spec.model_copy(update={"scenarios": {
        label: e.model_copy(update={"file": str(REPO / e.file)})
        for label, e in spec.scenarios.items()}}), repetitions=1)
    summary = run_sweep(spec, tmp_path / "out", workers=2)
    rows = result_lines(tmp_path / "out")
    assert summary.failed == 0 and {r["scheduler"] for r in rows} >= {"my_schedulers:OldestFirst"}
    mine = [r for r in rows if r["scheduler"] == "my_schedulers:OldestFirst"]
    assert all(r["metrics"]["success_rate"] == 1.0 for r in mine)


# ------------------------------------------------------------------------------- report


def test_mean_ci_known_values():
    from scipy import stats

    m, h = mean_ci([1.0, 2.0, 3.0])
    assert m == 2.0 and h == pytest.approx(4.302652729911275 / math.sqrt(3))
    m, h = mean_ci([5.0])
    assert m == 5.0 and math.isnan(h)
    assert mean_ci([2.0, 2.0, 2.0]) == (2.0, 0.0)
    assert all(math.isnan(x) for x in mean_ci([]))
    sample = [0.31, 0.35, 0.29, 0.40, 0.33, 0.36, 0.30, 0.34]
    lo, hi = stats.t.interval(0.95, len(sample) - 1, loc=stats.tmean(sample),
                              scale=stats.sem(sample))
    m, h = mean_ci(sample)
    assert (m - h, m + h) == pytest.approx((lo, hi), rel=1e-12)
    assert mean_ci(sample, level=0.99)[1] > h


def _row(env, sched, plan, pattern, seed, sr, tp, ct_ms, status="ok"):
    metrics = {"success_rate": sr, "throughput": tp, "ct_mean_ms": ct_ms,
               "ct_total_s": ct_ms / 10} if status == "ok" else None
    return {"key": episode_key(env, {"scheduler.name": sched, "planner.name": plan,
                                     "orders.pattern": pattern}, seed),
            "scenario": env, "scheduler": sched, "planner": plan, "pattern": pattern,
            "seed": seed, "status": status, "metrics": metrics, "variant": {},
            "error": None if status == "ok" else "ValueError: x"}


def test_report_tables_on_known_inputs(tmp_path):
    rows = [_row("Ho", "ta", "astar", "oneshot", 0, 1.0, 0.30, 1.0),
            _row("Ho", "ta", "astar", "oneshot", 1, 0.5, 0.40, 2.0),
            _row("Ho", "ta", "astar", "oneshot", 2, 0.0, 0.50, 3.0),
            _row("Ho", "ta", "astar", "burst", 0, 1.0, 0.20, 4.0),
            _row("Ho", "rd", "cbs", "oneshot", 0, 1.0, 0.10, 1.0),
            _row("Ho", "rd", "cbs", "oneshot", 1, 1.0, 0.10, 1.0),
            _row("Ho", "rd", "cbs", "oneshot", 2, 0.0, 0.0, 0.0, status="failed")]
    groups = {(g.env, g.method, g.pattern): g for g in aggregate(rows)}
    os_ta = groups["Ho", "TA + A*", "oneshot"]
    assert os_ta.n == 3 and os_ta.failed == 0
    assert os_ta.stats["sr_pct"] == pytest.approx((50.0, 4.302652729911275 * 50 / math.sqrt(3)))
    assert os_ta.stats["tp"] == pytest.approx((0.4, 4.302652729911275 * 0.1 / math.sqrt(3)))
    pooled = groups["Ho", "TA + A*", "all"]
    assert pooled.n == 4 and pooled.stats["ct_ms"][0] == pytest.approx(2.5)
    rd = groups["Ho", "RD + CBS", "oneshot"]
    assert (rd.n, rd.failed) == (2, 1) and rd.stats["sr_pct"] == (100.0, 0.0)
    # the same rows through results.jsonl and `warerover report`
    out = tmp_path / "sweep"
    rf = ResultsFile(out / "results.jsonl")
    for r in rows:
        rf.append(r)
    rf.close()
    result = CliRunner().invoke(app, ["report", str(out)])
    assert result.exit_code == 0, result.output
    assert "| Ho | TA + A* | 50.0 ± 124.2 | 2.00 ± 2.48 | 0.200 ± 0.248 | 0.400 ± 0.248 | 3 | 0 |" \
        in result.stdout
    assert "| Ho | RD + CBS | 100.0 ± 0.0 |" in result.stdout and "### burst" in result.stdout
    with open(out / "report.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    row = next(r for r in table if r["method"] == "TA + A*" and r["pattern"] == "oneshot")
    assert float(row["sr_pct"]) == 50.0 and float(row["tp_ci95"]) == pytest.approx(
        4.302652729911275 * 0.1 / math.sqrt(3))
    assert (out / "report.md").read_text().startswith("# Sweep report")
    pytest.importorskip("matplotlib", reason="PNG tables need the report extra")
    for name in ("table.png", "table_oneshot.png", "table_burst.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
