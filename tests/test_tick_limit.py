"""An open-loop execution that reaches its tick limit before every AGV has finished says
so on stderr (``execute`` and ``gap --plan``), and its figures say ``completed: false``;
one that finishes says nothing of it. ``--max-ticks`` sets the limit."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hardening_helpers import assert_clean_error, run_cli

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def floor_and_plan(tmp_path):
    floor = tmp_path / "strip.map"
    floor.write_text("type octile\nheight 3\nwidth 6\nmap\n......\n......\n......\n")
    plan = tmp_path / "p.txt"
    plan.write_text("agents=1\nsolution=\n0:(0,1),\n1:(1,1),\n2:(2,1),\n3:(3,1),\n")
    return floor, plan


@pytest.mark.parametrize("command", ["execute", "gap"])
def test_a_run_cut_at_its_tick_limit_says_so(floor_and_plan, tmp_path, command):
    floor, plan = floor_and_plan
    # Every tick the AGV is free a delay of 100 ticks starts (at probability 1, on the
    # tick the last one ends too): it never moves, and the run stops at either command's
    # limit (10x the plan's 3 ticks + 100 or 200).
    long = run_cli(command, floor, "--plan", plan, "--delays", "bernoulli:1:100:100",
                   "--out", tmp_path / "long", "--json", cwd=REPO, timeout=300)
    assert long.returncode == 0, long.stderr[-2000:]
    assert json.loads(long.stdout)["completed"] is False
    assert "stopped at its tick limit" in long.stderr
    short = run_cli(command, floor, "--plan", plan, "--out", tmp_path / "short", "--json",
                    cwd=REPO, timeout=300)
    assert short.returncode == 0, short.stderr[-2000:]
    assert json.loads(short.stdout)["completed"] is True
    assert "tick limit" not in short.stderr


@pytest.mark.parametrize("command", ["execute", "gap"])
def test_max_ticks_sets_the_limit(floor_and_plan, tmp_path, command):
    floor, plan = floor_and_plan
    # A free tick starts a delay of 50 ticks with probability 0.9: the 3 moves take longer
    # than the default limit, and finish within 5,000 ticks.
    delays = ("--delays", "bernoulli:0.9:50:50")
    cut = run_cli(command, floor, "--plan", plan, *delays, "--out", tmp_path / "cut0",
                  "--json", cwd=REPO, timeout=300)
    assert json.loads(cut.stdout)["completed"] is False and "tick limit" in cut.stderr
    done = run_cli(command, floor, "--plan", plan, *delays, "--max-ticks", "5000",
                   "--out", tmp_path / "done", "--json", cwd=REPO, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert json.loads(done.stdout)["completed"] is True
    assert "tick limit" not in done.stderr
    # A run stops where it is told, even without delays.
    cut = run_cli(command, floor, "--plan", plan, "--max-ticks", "2", "--out",
                  tmp_path / "cut", "--json", cwd=REPO, timeout=300)
    assert cut.returncode == 0, cut.stderr[-2000:]
    assert json.loads(cut.stdout)["completed"] is False
    assert "stopped at its tick limit (2 ticks: --max-ticks)" in cut.stderr
    bad = run_cli(command, floor, "--plan", plan, "--max-ticks", "0", "--out",
                  tmp_path / "bad", cwd=REPO)
    assert_clean_error(bad, "--max-ticks", "0")
    huge = run_cli(command, floor, "--plan", plan, "--max-ticks", "10000001", "--out",
                   tmp_path / "huge", cwd=REPO)
    assert_clean_error(huge, "--max-ticks", "10000001")
    assert not (tmp_path / "bad").exists()


def test_max_ticks_needs_a_plan_in_gap(tmp_path):
    r = run_cli("gap", REPO / "layouts" / "warerover_basic.yaml", "--max-ticks", "50",
                "--out", tmp_path / "o", cwd=REPO)
    assert_clean_error(r, "--max-ticks", "50", "--plan")
