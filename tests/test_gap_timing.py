"""``planner.timing`` in the open-loop gap: with ``motion`` the planned figures come from the
plan's motion-timed schedule (executed / planned within 1.10 on physics), the unit ones stay
beside them, every output says which timing it uses, and ``schedule.json`` is written."""

from __future__ import annotations

import csv
import json
import math

import pytest
from hardening_helpers import REPO, assert_clean_error, run_cli

from warerover_phys import load_scenario
from warerover_phys.errors import ScenarioError
from warerover_phys.gap.stats import SCHEDULES_FORMAT
from warerover_phys.planning.timing import SCHEDULE_FORMAT

HETERO = REPO / "layouts" / "paper_heterogeneous.yaml"


def test_timing_is_a_closed_planner_setting():
    assert load_scenario(HETERO).planner.timing == "unit"
    assert load_scenario(HETERO, [("planner.timing", "motion")]).planner.timing == "motion"
    with pytest.raises(ScenarioError, match="timing"):
        load_scenario(HETERO, [("planner.timing", "seconds")])


@pytest.fixture(scope="module")
def motion_gap(tmp_path_factory):
    out = tmp_path_factory.mktemp("gap") / "motion"
    r = run_cli("gap", HETERO, "--seed", "3", "--timing", "motion", "--out", out, "--json",
                "--no-pictures", cwd=REPO, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    return out, json.loads(r.stdout)


def test_motion_timing_plans_what_physics_does(motion_gap):
    out, rep = motion_gap
    assert rep["timing"] == "motion" and rep["mode"] == "open-loop"
    # the target of issue 15: within 1.10 (the unit plan is far off: about 1.4)
    assert 0.98 <= rep["makespan_ratio"] <= 1.10
    # the schedule itself, checked in continuous time: no two planned bodies meet
    assert rep["schedule_spacetime_conflicts"] == 0 and not rep["schedule_spacetime_truncated"]
    assert rep["makespan_ratio_unit"] > 1.2
    assert rep["planned_makespan_s"] > rep["planned_makespan_s_unit"]
    assert rep["executed_makespan_s"] == pytest.approx(
        rep["makespan_ratio"] * rep["planned_makespan_s"])
    assert 0.98 <= rep["orders_makespan_ratio"] <= 1.10
    assert rep["lost_parts_timing"] == "unit"
    gap = json.loads((out / "gap.json").read_text())
    assert gap["timing"] == "motion"


def test_schedule_json_matches_the_report(motion_gap):
    out, rep = motion_gap
    sched = json.loads((out / "schedule.json").read_text())
    assert sched["format"] == SCHEDULE_FORMAT and sched["timing"] == "motion"
    assert sched["makespan_s"] == pytest.approx(rep["planned_makespan_s"])
    assert sched["makespan_unit_s"] == pytest.approx(rep["planned_makespan_s_unit"])
    with (out / "agents.csv").open() as f:
        agents = list(csv.DictReader(f))
    for row, agv in zip(agents, sched["agvs"], strict=True):
        assert float(row["planned_finish_s"]) == pytest.approx(agv["finish_s"])
        assert float(row["planned_finish_unit_s"]) == pytest.approx(agv["finish_unit_s"])
        lost = float(row["executed_finish_s"]) - agv["finish_s"]
        assert float(row["lost_s"]) == pytest.approx(lost)
        for a in agv["actions"]:
            assert a["start_s"] >= a["ready_s"] - 1e-7 and a["finish_s"] > a["start_s"]
    # the split into causes stays the unit plan's: its parts add up to lost_unit_s
    parts = [k for k in agents[0] if k.startswith("lost_") and k not in ("lost_s", "lost_unit_s")]
    for row in agents:
        assert math.isclose(sum(float(row[k]) for k in parts), float(row["lost_unit_s"]),
                            abs_tol=1e-6)


def test_motion_timing_is_refused_with_the_closed_loop():
    r = run_cli("gap", HETERO, "--timing", "motion", "--mode", "closed", cwd=REPO)
    assert_clean_error(r, "--mode closed")
    r = run_cli("gap", HETERO, "--timing", "seconds", cwd=REPO)
    assert_clean_error(r, "--timing must be unit or motion")


@pytest.mark.slow
def test_many_seeds_write_every_schedule(tmp_path):
    out = tmp_path / "seeds"
    r = run_cli("gap", HETERO, "--seeds", "0..1", "--workers", "2", "--timing", "motion",
                "--out", out, "--json", "--no-pictures", cwd=REPO, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["timing"] == "motion"
    assert summary["statistics"]["makespan_ratio"]["max"] <= 1.10
    sched = json.loads((out / "schedule.json").read_text())
    assert sched["format"] == SCHEDULES_FORMAT and sorted(sched["seeds"]) == ["0", "1"]


@pytest.mark.slow
def test_replayed_failures_are_in_the_schedule():
    """paper_fault seed 0 (nine failures of 40 ticks replayed on physics): 1.018 measured."""
    from warerover_phys.gap.core import open_loop_gap

    g = open_loop_gap(load_scenario(REPO / "layouts" / "paper_fault.yaml",
                                    [("planner.timing", "motion")]), 0)
    assert g.report["failures"] > 0
    assert 0.98 <= g.report["makespan_ratio"] <= 1.10
