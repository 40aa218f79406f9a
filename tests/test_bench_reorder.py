"""tools/bench_reorder.py: scenario files by label, plans it cannot execute skipped with
the reason, and the AET change pooled over scenario files."""

from __future__ import annotations

import pytest
from tool_helpers import load_tool


@pytest.fixture(scope="module")
def bench():
    return load_tool("bench_reorder")


def test_scenario_labels_name_the_scenario_files(bench, tmp_path):
    assert bench.instance("warehouse", 1) == "warehouse"
    assert bench.instance("room", 3) == "room-r3"
    mp, scen = bench.map_files("warehouse-r2", tmp_path)
    assert mp == tmp_path / "maps" / "warehouse-10-20-10-2-1.map"
    assert scen == tmp_path / "scen-random" / "warehouse-10-20-10-2-1-random-2.scen"
    assert bench.map_files("room", tmp_path)[1].name == "room-32-32-4-random-1.scen"


def test_a_plan_that_cannot_be_executed_is_skipped_with_its_reason(bench, tmp_path, capsys):
    """Four agents turning a 2x2 block on a 2x2 floor: a rotation no detour repairs."""
    floor = tmp_path / "2x2.map"
    floor.write_text("type octile\nheight 2\nwidth 2\nmap\n..\n..\n")
    turn = tmp_path / "turn.txt"
    turn.write_text("0:(0,0),(1,0),(1,1),(0,1),\n1:(1,0),(1,1),(0,1),(0,0),\n")
    step = tmp_path / "step.txt"
    step.write_text("0:(0,0),\n1:(1,0),\n")
    assert bench.executable(step, floor)
    assert capsys.readouterr().err == ""
    assert not bench.executable(turn, floor)
    err = capsys.readouterr().err
    assert "skipped, not executable" in err and "turn.txt" in err and "rotation" in err


def _row(label: str, mode: str, seed: int, aet: float) -> dict:
    return {"map": label, "planner": "lacam", "agents": 4, "delays": "bernoulli:0.1",
            "dt_s": 0.02, "seed": seed, "mode": mode, "options": {}, "aet_s": aet}


def test_pooled_change_pairs_each_run_with_none_on_its_own_scenario(bench, capsys):
    rows = [_row("warehouse", "none", 0, 100.0), _row("warehouse", "milp", 0, 90.0),
            _row("warehouse", "none", 1, 200.0), _row("warehouse", "milp", 1, 190.0),
            _row("warehouse-r2", "none", 0, 50.0), _row("warehouse-r2", "milp", 0, 44.0),
            # no `none` run on seed 1 of warehouse-r2: not paired
            _row("warehouse-r2", "milp", 1, 1.0)]
    bench.print_pooled(rows)
    line = [x for x in capsys.readouterr().out.splitlines() if "| milp |" in x]
    assert len(line) == 1
    cells = [c.strip() for c in line[0].split("|")]
    assert cells[0] == "warehouse" and cells[6:8] == ["2", "3"]
    # changes -10%, -5%, -12%: mean -9.0
    assert cells[8].startswith("-9.0 ± ")
    assert cells[9] == "warehouse: -7.5, warehouse-r2: -12.0"
    assert cells[10] == "2"
