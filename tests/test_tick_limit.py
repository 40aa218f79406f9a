"""An open-loop execution that reaches its tick limit before every AGV has finished says
so on stderr (``execute`` and ``gap --plan``), and its figures say ``completed: false``;
one that finishes says nothing of it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hardening_helpers import run_cli

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
    # Every tick the AGV is free a delay of 100 ticks starts: 3 moves take over 300
    # ticks, past either command's limit (10x the plan's 3 ticks + 100 or 200).
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
