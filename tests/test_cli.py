"""The ``warerover`` command line, run as a real subprocess on the shipped scenarios.

The paper scenarios run in well under a second each; the module fixture starts every
command up front (a few at a time) and the tests check their results.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections import Counter
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parent.parent
LAYOUTS = REPO / "layouts"
PAPER = LAYOUTS / "paper_homogeneous.yaml"
SHIPPED = sorted(LAYOUTS.glob("*.yaml"))
WAREROVER = Path(sys.executable).parent / "warerover"


def run_cli(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("FORCE_COLOR", "CLICOLOR_FORCE")}
    env.update(COLUMNS="100", NO_COLOR="1", TERM="dumb")
    return subprocess.run([str(WAREROVER), *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=120)


# name -> (arguments after ``run``; output folder given with --out)
RUNS: dict[str, tuple[str, ...]] = {
    "base": ("--seed", "1", "--json"),
    "again": ("--seed", "1", "--json"),
    "rd-seed3": ("--scheduler", "rd", "--seed", "3", "--planner", "astar", "--executor", "grid",
                 "--json", "--quiet"),
    "set-orders": ("--set", "orders.pattern=constant", "--set", "orders.duration_ticks=60",
                   "--json"),
    "set-misc": ("--set", "scheduler=rd", "--orders", "constant", "--set",
                 "orders.duration_ticks=40", "--set", "fleet.agvs.0.count=4", "--json", "-q"),
}


class Cli:
    """The started commands of this module."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.pool = ThreadPoolExecutor(max_workers=max(2, min(4, os.cpu_count() or 2)))
        self.runs: dict[str, Future[subprocess.CompletedProcess[str]]] = {}
        for name, args in RUNS.items():
            self.runs[name] = self.pool.submit(run_cli, "run", PAPER, "--out", root / name,
                                               *args, cwd=root)
        table_cwd = root / "table-cwd"
        table_cwd.mkdir()
        self.runs["table"] = self.pool.submit(run_cli, "run", PAPER, "--seed", "2",
                                              cwd=table_cwd)
        self.checks = {p.name: self.pool.submit(run_cli, "check", p, cwd=REPO) for p in SHIPPED}
        self.check_set = self.pool.submit(run_cli, "check", PAPER, "--set",
                                          "fleet.agvs.0.count=5", cwd=root)
        self.help = self.pool.submit(run_cli, "--help", cwd=root)

    def ok(self, name: str) -> subprocess.CompletedProcess[str]:
        proc = self.runs[name].result()
        assert "Traceback" not in proc.stderr, proc.stderr
        assert proc.returncode == 0, proc.stderr
        return proc

    def metrics(self, name: str) -> dict[str, Any]:
        self.ok(name)
        return json.loads((self.root / name / "metrics.json").read_text())


@pytest.fixture(scope="module")
def cli(tmp_path_factory: pytest.TempPathFactory) -> Any:
    c = Cli(tmp_path_factory.mktemp("cli"))
    yield c
    c.pool.shutdown(wait=True, cancel_futures=True)


def read_events(path: Path) -> list[dict[str, Any]]:
    lines = path.read_text().splitlines()
    assert lines, "no events"
    return [json.loads(line) for line in lines]


# ------------------------------------------------------------------------------ run --json


def test_run_json_prints_metrics(cli: Cli) -> None:
    proc = cli.ok("base")
    printed = json.loads(proc.stdout)  # the whole of stdout is one JSON document
    assert printed["success_rate"] == 1.0
    assert printed["collisions"] == 0
    assert printed["seed"] == 1
    assert printed["scenario"] == "paper_homogeneous"
    assert (printed["scheduler"], printed["planner"], printed["executor"]) == \
        ("ta", "astar", "grid")
    assert printed["order_pattern"] == "oneshot"
    assert printed["agvs"] == 9
    assert printed["orders_generated"] == printed["orders_completed"] == 20
    assert 0 < printed["ticks"] <= 1000


def test_run_writes_the_three_files(cli: Cli) -> None:
    proc = cli.ok("base")
    out = cli.root / "base"
    assert sorted(p.name for p in out.iterdir()) == ["events.jsonl", "manifest.json",
                                                      "metrics.json", "paths.json"]
    assert json.loads((out / "metrics.json").read_text()) == json.loads(proc.stdout)


def test_events_jsonl(cli: Cli) -> None:
    m = cli.metrics("base")
    events = read_events(cli.root / "base" / "events.jsonl")
    for e in events:
        assert isinstance(e, dict) and "tick" in e and "event" in e, e
        assert isinstance(e["tick"], int) and 0 <= e["tick"] <= m["ticks"]
    ticks = [e["tick"] for e in events]
    assert ticks == sorted(ticks), "events out of tick order"
    kinds = Counter(e["event"] for e in events)
    assert kinds["order_created"] == m["orders_generated"]
    assert kinds["order_completed"] == m["orders_completed"]
    created = [e["order"] for e in events if e["event"] == "order_created"]
    completed = [e["order"] for e in events if e["event"] == "order_completed"]
    assert len(set(created)) == len(created)
    assert len(set(completed)) == len(completed)
    assert set(completed) <= set(created)


def test_paths_json(cli: Cli) -> None:
    m = cli.metrics("base")
    paths = json.loads((cli.root / "base" / "paths.json").read_text())
    assert set(paths) == {"agvs", "planned", "actual"}
    assert len(paths["agvs"]) == m["agvs"] == 9
    assert set(paths["actual"]) == set(paths["agvs"])
    for aid, states in paths["actual"].items():
        assert len(states) == m["ticks"] + 1, aid
        for (r0, c0), (r1, c1) in states:
            assert 0 <= r0 < 15 and 0 <= r1 < 15 and 0 <= c0 < 20 and 0 <= c1 < 20
        assert states[0][0] == states[0][1], "an AGV starts standing"
    assert paths["planned"], "no planned paths"
    for p in paths["planned"]:
        assert str(p["agv"]) in paths["agvs"]
        assert 0 <= p["tick"] <= m["ticks"]
        assert p["states"] and all(len(s) == 2 for s in p["states"])


def test_same_seed_same_events(cli: Cli) -> None:
    cli.ok("base")
    cli.ok("again")
    assert (cli.root / "base" / "events.jsonl").read_text() == \
        (cli.root / "again" / "events.jsonl").read_text()


# ------------------------------------------------------------------------ flags and --set


def test_named_flags_take_effect(cli: Cli) -> None:
    m = cli.metrics("rd-seed3")
    assert m["scheduler"] == "rd"
    assert m["seed"] == 3
    assert (m["planner"], m["executor"]) == ("astar", "grid")
    assert m["collisions"] == 0


def test_set_orders_takes_effect(cli: Cli) -> None:
    m = cli.metrics("set-orders")
    assert m["order_pattern"] == "constant"
    assert m["seed"] == 0  # the file's
    assert m["orders_generated"] > 0
    created = [e for e in read_events(cli.root / "set-orders" / "events.jsonl")
               if e["event"] == "order_created"]
    assert len(created) == m["orders_generated"]
    assert all(e["tick"] < 60 for e in created), "orders after duration_ticks"


def test_set_shorthands_and_fleet_size(cli: Cli) -> None:
    m = cli.metrics("set-misc")
    assert m["scheduler"] == "rd"
    assert m["order_pattern"] == "constant"
    assert m["agvs"] == 4
    paths = json.loads((cli.root / "set-misc" / "paths.json").read_text())
    assert len(paths["actual"]) == 4
    created = [e for e in read_events(cli.root / "set-misc" / "events.jsonl")
               if e["event"] == "order_created"]
    assert created and all(e["tick"] < 40 for e in created)


# ------------------------------------------------------------------------------ table output


def test_table_output_and_default_out_dir(cli: Cli) -> None:
    proc = cli.ok("table")
    assert "success rate" in proc.stdout
    assert "collisions" in proc.stdout
    assert "wrote" in proc.stdout
    with pytest.raises(json.JSONDecodeError):
        json.loads(proc.stdout)
    default = cli.root / "table-cwd" / "runs" / "paper_homogeneous-seed2"
    m = json.loads((default / "metrics.json").read_text())
    assert m["seed"] == 2
    assert (default / "events.jsonl").is_file() and (default / "paths.json").is_file()


# ------------------------------------------------------------------------------ check


def test_shipped_scenarios_found() -> None:
    names = {p.name for p in SHIPPED}
    assert {"paper_homogeneous.yaml", "paper_heterogeneous.yaml", "paper_fault.yaml",
            "industrial.yaml"} <= names


@pytest.mark.parametrize("name", [p.name for p in SHIPPED])
def test_check_shipped_scenario(cli: Cli, name: str) -> None:
    proc = cli.checks[name].result()
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert "ok" in proc.stdout and "AGVs" in proc.stdout


def test_check_with_set(cli: Cli) -> None:
    proc = cli.check_set.result()
    assert proc.returncode == 0, proc.stderr
    assert "9 parking cells, 5 AGVs" in proc.stdout


def test_help_lists_commands(cli: Cli) -> None:
    proc = cli.help.result()
    assert proc.returncode == 0, proc.stderr
    assert "run" in proc.stdout and "check" in proc.stdout
