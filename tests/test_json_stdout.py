"""Every command's ``--json`` prints one JSON document on stdout and nothing else; what it
wrote and any note goes to stderr (issue 31: ``lorr --json --out DIR`` printed ``wrote ...``
lines after the JSON, so ``| jq`` failed). Each command runs as its own process, as in a
shell pipe."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from hardening_helpers import LAYOUTS, cli_argv, cli_env

DATA = Path(__file__).parent / "data"
MAP = DATA / "random-32-32-10.map"
SCEN = DATA / "random-32-32-10-random-1.scen"
LORR = DATA / "lorr2023_warehouse_small" / "warehouse_small_50.json"
PLAN = ("Agent 0:(0,0)->(0,1)->(0,2)->(0,3)->\n"
        "Agent 1:(2,0)->(2,1)->(2,2)->(2,3)->\n")
SHORT = ["--set", "max_ticks=25"]


def _commands(tmp: Path) -> dict[str, list[list]]:
    """Per case, the commands to run in order; the last one's ``--json`` is checked."""
    plan = tmp / "plan.txt"
    homo = LAYOUTS / "paper_homogeneous.yaml"
    execute = ["execute", MAP, "--plan", plan, "--out", tmp / "exec", "--export",
               tmp / "exported.txt"]
    return {
        "run": [["run", homo, *SHORT, "--out", tmp / "run"]],
        "gap": [["gap", homo, *SHORT, "--out", tmp / "gap", "--no-pictures"]],
        "gap --seeds": [["gap", homo, *SHORT, "--seeds", "0..1", "--workers", "1", "--out",
                         tmp / "gaps", "--no-pictures"]],
        "gap --plan": [["gap", MAP, "--plan", plan, "--out", tmp / "gapp", "--no-pictures"]],
        "solve": [["solve", MAP, SCEN, "--agents", "8", "--out", tmp / "solve.txt"]],
        "solve --refine": [["solve", MAP, SCEN, "--agents", "8", "--refine", "--time-limit",
                            "2"]],
        "execute": [execute],
        "lorr": [["lorr", LORR, "--ticks", "20", "--out", tmp / "lorr"]],
        "check-trajectory": [execute, ["check-trajectory", tmp / "exec"]],
        "study": [["study", _study_spec(tmp), "--out", tmp / "study", "--workers", "1"]],
    }


def _study_spec(tmp: Path) -> Path:
    """A one-cell study (one map, one scenario, 4 agents, PIBT, one robot)."""
    spec = tmp / "study.yaml"
    if tmp.is_dir():
        spec.write_text(json.dumps({  # (JSON is YAML)
            "name": "json-case",
            "instances": [{"map": str(MAP), "scens": [str(SCEN)], "agents": [4]}],
            "planners": {"pibt": {"solver": "pibt", "time_limit_s": 5}},
            "robots": {"quick": {"max_speed_mps": 1.0, "max_accel_mps2": 1.0,
                                 "max_turn_rate_radps": 2.0}}}), encoding="utf-8")
    return spec


CASES = list(_commands(Path("/nonexistent")).keys())
# Cases whose command's --json output is also read in make test elsewhere (test_gap_cli's
# plan run), or that run several seeds, a time-limited refinement or two commands:
# make test-all.
SLOW_CASES = {"gap --seeds", "gap --plan", "solve --refine", "check-trajectory"}


@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.slow) if c in SLOW_CASES
                                  else c for c in CASES])
def test_json_is_one_document_on_stdout(tmp_path, case):
    """Every command that has ``--json`` (this list is checked against the command line's
    options below)."""
    (tmp_path / "plan.txt").write_text(PLAN)
    *before, args = _commands(tmp_path)[case]
    for prior in before:
        done = subprocess.run(cli_argv(*prior), cwd=tmp_path, env=cli_env(),
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr[-2000:]
    proc = subprocess.run(cli_argv(*args, "--json"), cwd=tmp_path, env=cli_env(),
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    try:
        doc = json.loads(proc.stdout)
    except json.JSONDecodeError as err:
        raise AssertionError(f"stdout is not one JSON document ({err}): "
                             f"{proc.stdout[-500:]!r}") from None
    assert isinstance(doc, dict) and doc
    assert "Traceback" not in proc.stderr, proc.stderr


def test_the_cases_cover_every_command_with_json():
    """A new command with ``--json`` must join the list above."""
    import typer

    from warerover_phys.cli import app

    group = typer.main.get_command(app)
    with_json = {name for name, cmd in group.commands.items()
                 if any("--json" in p.opts for p in cmd.params)}
    assert with_json == {c.split()[0] for c in CASES}


def test_without_json_lorr_still_says_what_it_wrote(tmp_path):
    """Without ``--json`` too, ``lorr --out`` says what it wrote (on stderr, as every
    progress note)."""
    proc = subprocess.run(cli_argv("lorr", LORR, "--ticks", "5", "--out", tmp_path / "o"),
                          cwd=tmp_path, env=cli_env(), capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "wrote" in proc.stderr and "output.json" in proc.stderr
    assert "wrote" not in proc.stdout
