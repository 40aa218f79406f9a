"""``--delays MODEL:PROB[:MIN:MAX]`` of ``warerover execute`` and ``warerover gap --plan``
(issue 31): the command line gives text, the numbers are read and their ranges checked
(``bernoulli:0.1`` was refused with "Input should be a number (got '0.1')", and the
probability's range was never checked)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from warerover_phys.cli import app
from warerover_phys.config import DelaySpec
from warerover_phys.errors import WareroverError
from warerover_phys.execute import parse_delays

MAP = Path(__file__).parent / "data" / "random-32-32-10.map"
PLAN = ("Agent 0:(0,0)->(0,1)->(0,2)->(0,3)->(0,4)->(0,5)->\n"
        "Agent 1:(2,0)->(2,1)->(2,2)->(2,3)->(2,4)->(2,5)->\n")
runner = CliRunner()


def test_parse_delays_reads_numbers():
    assert parse_delays("bernoulli:0.1") == DelaySpec(model="bernoulli", prob=0.1)
    assert parse_delays("poisson:0.25:2:7") == DelaySpec(model="poisson", prob=0.25,
                                                         min_ticks=2, max_ticks=7)


@pytest.mark.parametrize("text, needle", [
    ("bernoulli:1.5", "prob"), ("bernoulli:-0.1", "prob"), ("bernoulli:nan", "prob"),
    ("bernoulli:inf", "prob"), ("bernoulli:x", "prob"), ("bernoulli:0.1:a:3", "min_ticks"),
    ("bernoulli:0.1:5:2", "max_ticks 2 is below"), ("bernoulli:0.1:0:2", "min_ticks"),
    ("gauss:0.1", "MODEL"), ("bernoulli", "MODEL")])
def test_parse_delays_refuses_out_of_range(text, needle):
    with pytest.raises(WareroverError) as err:
        parse_delays(text)
    assert "--delays" in str(err.value) and needle in str(err.value)


def _plan(tmp_path: Path) -> Path:
    p = tmp_path / "plan.txt"
    p.write_text(PLAN)
    return p


def test_execute_with_delays_runs_and_delays(tmp_path):
    plan = _plan(tmp_path)
    figures = {}
    for name, extra in (("none", []), ("delayed", ["--delays", "bernoulli:0.3:2:4"])):
        r = runner.invoke(app, ["execute", str(MAP), "--plan", str(plan), "--json", "--out",
                                str(tmp_path / name), *extra])
        assert r.exit_code == 0, r.output
        figures[name] = json.loads(r.stdout)
    assert figures["none"]["delay_injected_s"] == 0
    assert figures["delayed"]["delay_injected_s"] > 0
    assert figures["delayed"]["executed_makespan_ticks"] > \
        figures["none"]["executed_makespan_ticks"]


def test_gap_plan_with_delays_runs(tmp_path):
    r = runner.invoke(app, ["gap", str(MAP), "--plan", str(_plan(tmp_path)), "--delays",
                            "bernoulli:0.3:2:4", "--json", "--no-pictures", "--out",
                            str(tmp_path / "gap")])
    assert r.exit_code == 0, r.output
    report = json.loads(r.stdout)
    assert report["lost_injected_s_fleet_total"] > 0


@pytest.mark.parametrize("command", ["execute", "gap"])
def test_out_of_range_delays_are_one_line_and_write_nothing(tmp_path, command):
    args = [command, str(MAP), "--plan", str(_plan(tmp_path)), "--delays", "bernoulli:2",
            "--out", str(tmp_path / "out")]
    r = runner.invoke(app, args)
    assert r.exit_code == 2 and "--delays" in r.output and "prob" in r.output
    assert not (tmp_path / "out").exists()
