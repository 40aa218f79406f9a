"""``python -m warerover_phys solve``: its start-up fast path imports only what solving needs,
reads its arguments as the typer command does, and gives the same output and exit codes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from warerover_phys.cli.solve import parse_solve_args

REPO = Path(__file__).resolve().parent.parent
DATA = REPO / "tests" / "data"
MAP = DATA / "warehouse-10-20-10-2-1.map"
SCEN = DATA / "warehouse-10-20-10-2-1-random-1.scen"

HEAVY = ("typer", "click", "rich", "pydantic", "pydantic_core", "yaml", "scipy",
         "pymunk", "shapely", "fcl", "trimesh", "pyarrow", "matplotlib", "PIL", "imageio",
         "warerover_phys.cli.commands", "warerover_phys.config", "warerover_phys.registry",
         "warerover_phys.sim", "warerover_phys.world", "warerover_phys.planning.search.astar",
         "warerover_phys.planning.search.cbs")
"""Modules ``solve`` must not load: the command line, the scenario models and the closed
loop, scipy (0.4 s of CPU to import; the one-shot distance tables need only numpy),
physics, geometry, media and storage."""


def _python(*args: str, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=120,
                          cwd=REPO, **kw)


def test_solve_imports_only_what_it_needs(tmp_path):
    out = tmp_path / "plan.txt"
    probe = (
        "import json, sys\n"
        "from warerover_phys.cli.solve import fast_main\n"
        "try:\n"
        f"    fast_main(['solve', {str(MAP)!r}, {str(SCEN)!r}, '--agents', '5', '--json',\n"
        f"               '--out', {str(out)!r}])\n"
        "    code = 'returned'\n"
        "except SystemExit as exit_:\n"
        "    code = exit_.code\n"
        "print(json.dumps({'code': code, 'modules': sorted(sys.modules)}), file=sys.stderr)\n")
    proc = _python("-c", probe)
    report = json.loads(proc.stderr.strip().splitlines()[-1])
    assert report["code"] == 0, proc.stderr
    assert json.loads(proc.stdout)["success"] and out.is_file()
    loaded = set(report["modules"])
    heavy = sorted(m for m in loaded if m in HEAVY or m.split(".")[0] in HEAVY)
    assert heavy == []
    assert "numpy" in loaded and "warerover_phys.planning.lacam.reference" in loaded  # it did solve


def test_the_console_script_takes_the_fast_path(tmp_path):
    """``warerover solve`` (the script pyproject.toml installs) loads what ``python -m``
    does: no typer, rich, pydantic, YAML or scipy."""
    import tomllib

    script = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["scripts"]
    module, func = script["warerover"].split(":")
    out = tmp_path / "plan.txt"
    probe = (
        "import importlib, json, sys\n"
        f"sys.argv = ['warerover', 'solve', {str(MAP)!r}, {str(SCEN)!r}, '--agents', '5',\n"
        f"            '--out', {str(out)!r}]\n"
        "try:\n"
        f"    getattr(importlib.import_module({module!r}), {func!r})()\n"
        "    code = 'returned'\n"
        "except SystemExit as exit_:\n"
        "    code = exit_.code\n"
        "print(json.dumps({'code': code, 'modules': sorted(sys.modules)}), file=sys.stderr)\n")
    proc = _python("-c", probe)
    report = json.loads(proc.stderr.strip().splitlines()[-1])
    assert report["code"] == 0, proc.stderr
    assert out.is_file()
    loaded = set(report["modules"])
    assert sorted(m for m in loaded if m in HEAVY or m.split(".")[0] in HEAVY) == []


TYPER_ONLY = ("import runpy, sys\n"
              "import warerover_phys.cli.solve as fast\n"
              "fast.fast_main = lambda argv: None  # never taken: the typer command answers\n"
              "sys.argv = ['-m', *sys.argv[1:]]\n"
              "runpy.run_module('warerover_phys', run_name='__main__', alter_sys=True)\n")
"""``python -m warerover_phys`` with the fast path turned off."""


def _both(tmp_path: Path, *args: str) -> tuple[subprocess.CompletedProcess, ...]:
    """The same command through ``python -m warerover_phys`` (fast path) and the typer app."""
    return (_python("-m", "warerover_phys", "solve", *args),
            _python("-c", TYPER_ONLY, "solve", *args))


def test_fast_path_and_typer_command_agree(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    common = [str(MAP), str(SCEN), "--agents", "12", "--seed", "2"]
    fast = _python("-m", "warerover_phys", "solve", *common, "--out", str(a))
    slow = _python("-c", TYPER_ONLY, "solve", *common, "--out", str(b))
    assert fast.returncode == slow.returncode == 0, (fast.stderr, slow.stderr)

    def strip(text: str) -> list[str]:  # wall_s differs from run to run
        return [ln for ln in text.splitlines() if "wall_s" not in ln]

    assert strip(fast.stdout) == strip(slow.stdout) and "sum_of_costs" in fast.stdout
    plan_a = [ln for ln in a.read_text().splitlines() if not ln.startswith("comp_time=")]
    plan_b = [ln for ln in b.read_text().splitlines() if not ln.startswith("comp_time=")]
    assert plan_a == plan_b and "solution=" in plan_a


@pytest.mark.parametrize("args", [["--agents", "0"], ["--agents", "zero"], ["--help"]])
def test_errors_and_help_as_the_typer_command(tmp_path, args):
    fast, slow = _both(tmp_path, str(MAP), str(SCEN), *args)
    assert fast.returncode == slow.returncode
    assert fast.stdout == slow.stdout and fast.stderr == slow.stderr
    assert "Traceback" not in fast.stderr
    assert fast.returncode == (0 if args == ["--help"] else 2)


# ----------------------------------------------------------------------------- arguments

TOKENS = ["a.map", "b.scen", "--agents", "--planner", "--time-limit", "--seed", "--out",
          "--json", "--guide", "--no-guide", "--refine", "5", "-3", "+4", "1_000", "0x10",
          "2.5", "1e3", ".5", "nan", "inf", "pibt", "", "-", "--", "--help", "-h", "--ag",
          "--agents=7", "--json=1", "--seed=", "--out=p.txt", "--time-limit=3.",
          "--no-such"]


def _typer_params(argv: list[str]) -> dict | None:
    import typer

    from warerover_phys.cli import app

    command = typer.main.get_command(app).commands["solve"]
    try:
        ctx = command.make_context("solve", list(argv), resilient_parsing=False)
    except Exception:  # any usage error: the typer command would refuse the line
        return None
    return {k: (str(v) if isinstance(v, Path) else v) for k, v in ctx.params.items()}


# 150 examples: one cheap parse per example, wide inputs
@settings(max_examples=150, deadline=None)
@given(st.lists(st.sampled_from(TOKENS), max_size=8))
def test_fast_parser_reads_what_typer_reads(argv):
    mine = parse_solve_args(argv)
    if mine is None:
        return  # left to the typer command
    theirs = _typer_params(argv)
    assert theirs is not None, argv
    defaults = {"agents": 100, "planner": "lacam", "time_limit": 60.0, "seed": 0,
                "json_out": False, "out": None, "guide": True, "refine": False}
    mine = {**defaults, **mine}
    mine = {k: (str(v) if isinstance(v, Path) else v) for k, v in mine.items()}
    assert mine == theirs, argv


def test_fast_parser_takes_plain_lines_and_leaves_the_rest():
    got = parse_solve_args(["m.map", "s.scen", "--agents", "400", "--time-limit=60",
                            "--json", "--no-guide", "--out", "p.txt", "--seed", "-1"])
    assert got == {"map_file": Path("m.map"), "scen_file": Path("s.scen"), "agents": 400,
                   "time_limit": 60.0, "json_out": True, "guide": False,
                   "out": Path("p.txt"), "seed": -1}
    for argv in (["m.map"], ["m.map", "s.scen", "--help"], ["m.map", "s.scen", "--agents"],
                 ["m.map", "s.scen", "--agents", "+5"], ["m.map", "s.scen", "x"]):
        assert parse_solve_args(argv) is None, argv


# ----------------------------------------------------------------------------- distances


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 12), st.integers(1, 12), st.floats(0.0, 0.6), st.integers(0, 2**32 - 1),
       st.integers(1, 150))
def test_goal_tables_equal_dist_to(rows, cols, density, seed, goals):
    """The bit-parallel search gives ``dist_to``'s tables on any grid: free borders (a row
    end beside the next row's start), walls that cut the grid apart, goals on obstacles,
    repeated goals and more than 64 goals (several words)."""
    import numpy as np

    from warerover_phys.planning.oneshot.core import goal_tables, grid_graph

    rng = np.random.default_rng(seed)
    obstacles = rng.random((rows, cols)) < density
    cells = [(int(r), int(c)) for r, c in zip(rng.integers(0, rows, goals),
                                              rng.integers(0, cols, goals), strict=True)]
    got = goal_tables(grid_graph(obstacles), cells)
    reference = grid_graph(obstacles)
    for cell, table in zip(cells, got, strict=True):
        want = reference.dist_to(cell)
        assert table.dtype == want.dtype and np.array_equal(table, want), cell
        assert not table.flags.writeable


def test_goal_tables_on_the_warehouse_map():
    import numpy as np

    from warerover_phys.planning.oneshot.core import goal_tables, grid_graph
    from warerover_phys.problems.movingai import read_map, read_scen

    grid = read_map(MAP)
    goals = [a.goal for a in read_scen(SCEN, 600, grid)]  # two chunks of goals
    got = goal_tables(grid_graph(grid.obstacles), goals)
    reference = grid_graph(grid.obstacles)
    for cell in sorted(set(goals))[::7]:
        assert np.array_equal(got[goals.index(cell)], reference.dist_to(cell))
