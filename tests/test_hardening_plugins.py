"""Plug-ins whose constructor raises, errors raised mid-run (safety corridors), sweep grids
with mapping or list values, and ``warerover report`` on malformed rows: one clean line each,
naming the scenario or results file (never ``<scenario>``, never a traceback)."""

from __future__ import annotations

import json
import textwrap
from concurrent.futures import ThreadPoolExecutor

import pytest
from hardening_helpers import LAYOUTS, assert_clean_error, run_cli

from warerover_phys import load_scenario, run_episode
from warerover_phys.errors import ScenarioError

PAPER = LAYOUTS / "paper_homogeneous.yaml"
PLUGIN = textwrap.dedent('''
    class BoomScheduler:
        def __init__(self, spec):
            raise RuntimeError("licence server down")
        def assign(self, world, rng):
            return []

    class BoomPlanner:
        replans_all = False
        def __init__(self, spec):
            raise KeyError("gpu")
        def plan(self, request):
            return None

    class SilentBoom:
        replans_all = False
        def __init__(self, spec):
            raise ValueError()
        def plan(self, request):
            return None

    class PlanRaises:
        replans_all = False
        def __init__(self, spec):
            pass
        def plan(self, request):
            raise ZeroDivisionError("oops")

    class PlanReturnsNone:
        replans_all = False
        def __init__(self, spec):
            pass
        def plan(self, request):
            return None

    class NoReplansAll:
        def __init__(self, spec):
            pass
        def plan(self, request):
            return None

    class AssignJunk:
        def __init__(self, spec):
            pass
        def assign(self, world, rng):
            return 42

    class AssignTwice:
        def __init__(self, spec):
            pass
        def assign(self, world, rng):
            from warerover_phys.schedulers import Assignment
            return [Assignment(0, 0, ()), Assignment(0, 1, ())]

    class AssignBadOrder:
        def __init__(self, spec):
            pass
        def assign(self, world, rng):
            from warerover_phys.schedulers import Assignment
            return [Assignment(0, 0, (10**6,))]
''')
WALLED = textwrap.dedent('''
    name: walled
    max_ticks: 50
    layout: {grid: ["#########", "#R.....P#", "#..S.S..#", "#R.....P#", "#########"]}
    fleet: {agvs: [{count: 2}]}
    orders: {pattern: oneshot, oneshot: {count: 3}}
    faults: {scheduled: [{agv: 0, tick: 2, repair_ticks: 5}]}
''')


def test_mid_run_corridor_error_names_the_file(tmp_path):
    path = tmp_path / "walled.yaml"
    path.write_text(WALLED)
    with pytest.raises(ScenarioError) as info:
        run_episode(load_scenario(path))
    assert str(info.value).startswith(str(path)) and "<scenario>" not in str(info.value)


def test_plugin_constructor_error_in_python(tmp_path, monkeypatch):
    (tmp_path / "boom_plugins.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    sc = load_scenario(PAPER, [("planner.name", "boom_plugins:BoomPlanner")])
    with pytest.raises(ScenarioError, match="planner.name: plugin constructor raised KeyError"):
        run_episode(sc)


@pytest.fixture(scope="module")
def procs(tmp_path_factory):
    root = tmp_path_factory.mktemp("plugins")
    (root / "boom_plugins.py").write_text(PLUGIN)
    (root / "walled.yaml").write_text(WALLED)
    sweep = root / "sweep.yaml"
    sweep.write_text(f"scenarios: {{Ho: {PAPER}}}\ngrid:\n  scheduler: [{{name: rd}}]\n"
                     "  planner.name: [[astar]]\nrepetitions: 1\n")
    sweep_ok = root / "sweep_ok.yaml"
    sweep_ok.write_text(f"scenarios: {{Ho: {PAPER}}}\ngrid:\n  scheduler: [{{name: rd}}, ta]\n"
                        "repetitions: 1\n")
    results = root / "res"
    results.mkdir()
    (results / "results.jsonl").write_text(json.dumps(
        {"key": "k1", "scenario": "Ho", "status": "ok", "pattern": "oneshot",
         "scheduler": "ta", "metrics": {"success_rate": 1.0}}) + "\n")
    results2 = root / "res2"
    results2.mkdir()
    (results2 / "results.jsonl").write_text(json.dumps(
        {"key": "k1", "scenario": "Ho", "status": "ok", "pattern": "oneshot", "planner": "a",
         "scheduler": "ta", "metrics": {"success_rate": "high"}}) + "\n")
    cases = {
        "sched": ("run", PAPER, "--scheduler", "boom_plugins:BoomScheduler", "--json"),
        "plan": ("run", PAPER, "--planner", "boom_plugins:BoomPlanner", "--json"),
        "silent": ("run", PAPER, "--planner", "boom_plugins:SilentBoom", "--json"),
        "missing": ("run", PAPER, "--planner", "boom_plugins:Nope", "--json"),
        "gap": ("gap", PAPER, "--planner", "boom_plugins:BoomPlanner", "--json"),
        "plan-raises": ("run", PAPER, "--planner", "boom_plugins:PlanRaises", "--json"),
        "plan-none": ("run", PAPER, "--planner", "boom_plugins:PlanReturnsNone", "--json"),
        "no-replans-all": ("run", PAPER, "--planner", "boom_plugins:NoReplansAll", "--json"),
        "assign-junk": ("run", PAPER, "--scheduler", "boom_plugins:AssignJunk", "--json"),
        "assign-twice": ("run", PAPER, "--scheduler", "boom_plugins:AssignTwice", "--json"),
        "assign-order": ("run", PAPER, "--scheduler", "boom_plugins:AssignBadOrder", "--json"),
        "walled": ("run", root / "walled.yaml", "--json"),
        "sweep-list": ("sweep", sweep, "--out", root / "sw", "--workers", "1", "-q"),
        "sweep-map": ("sweep", sweep_ok, "--out", root / "sw2", "--workers", "1", "-q"),
        "report": ("report", results),
        "report-type": ("report", results2),
    }
    with ThreadPoolExecutor(2) as pool:
        futs = {k: pool.submit(run_cli, *a, cwd=root) for k, a in cases.items()}
        return root, {k: f.result() for k, f in futs.items()}


@pytest.mark.slow  # one fixture runs 16 CLI commands, sweeps among them: make test-all
@pytest.mark.parametrize("case,needles", [
    ("sched", ["paper_homogeneous.yaml", "scheduler.name", "RuntimeError", "licence"]),
    ("plan", ["paper_homogeneous.yaml", "planner.name", "KeyError"]),
    ("silent", ["paper_homogeneous.yaml", "planner.name", "ValueError"]),
    ("missing", ["paper_homogeneous.yaml", "planner.name", "Nope"]),
    ("gap", ["paper_homogeneous.yaml", "planner.name", "KeyError"]),
    ("walled", ["walled.yaml", "corridor"]),
    ("plan-raises", ["paper_homogeneous.yaml", "plan() raised ZeroDivisionError", "tick 0"]),
    ("plan-none", ["paper_homogeneous.yaml", "PlanResult", "NoneType"]),
    ("no-replans-all", ["paper_homogeneous.yaml", "planner.name", "replans_all"]),
    ("assign-junk", ["scheduler.name", "assign()", "int"]),
    ("assign-twice", ["scheduler.name", "AGV 0"]),
    ("assign-order", ["scheduler.name", "order 1000000"]),
    ("sweep-list", ["sweep.yaml", "planner.name"]),
    ("report", ["results.jsonl", "planner"]),
    ("report-type", ["results.jsonl", "metrics.success_rate"]),
])
def test_clean_error(procs, case, needles):
    root, results = procs
    err = assert_clean_error(results[case], *needles)
    assert "<scenario>" not in err
    assert not (root / "runs").exists()


@pytest.mark.slow  # the CLI batch of test_clean_error: make test-all
def test_sweep_grid_with_mapping_values_runs(procs):
    root, results = procs
    proc = results["sweep-map"]
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = [json.loads(line) for line in (root / "sw2" / "results.jsonl").read_text().splitlines()]
    assert sorted(r["scheduler"] for r in rows) == ["rd", "ta"]
    assert all(r["status"] == "ok" for r in rows)


@pytest.mark.parametrize("line,needle", [
    ("repetitions: 1000000000000", "repetitions"), ("repetitions: true", "repetitions"),
    ("seeds: [1.5]", "seeds[0]"),
    ("repetitions: 600000\ngrid: {planner.name: [astar, cbs]}", "1,200,000 episodes")])
def test_sweep_sizes_are_bounded(tmp_path, line, needle):
    from warerover_phys.sweep import load_sweep
    from warerover_phys.sweep.spec import SweepError

    path = tmp_path / "s.yaml"
    path.write_text(f"scenarios: {{Ho: {PAPER}}}\n{line}\n")
    with pytest.raises(SweepError, match=needle.replace("[", r"\[")):
        load_sweep(path)
