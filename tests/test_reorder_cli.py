"""``--reorder`` on ``warerover execute`` and ``warerover gap``: checked, and the gain
reported."""

from __future__ import annotations

import json

import pytest
from hardening_helpers import REPO, assert_clean_error, run_cli

MAP = REPO / "tests" / "data" / "random-32-32-10.map"


@pytest.fixture(scope="module")
def plan40(tmp_path_factory):
    out = tmp_path_factory.mktemp("reorder") / "plan40.txt"
    r = run_cli("solve", MAP, REPO / "tests" / "data" / "random-32-32-10-random-1.scen",
                "--agents", "40", "--out", out, "--json", cwd=REPO, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return out


def test_reorder_option_is_checked_on_the_command_line(tmp_path):
    plan = tmp_path / "p.txt"
    plan.write_text("agents=1\nsolution=\n0:(1,1),\n")
    for cmd in (("execute", MAP, "--plan", plan), ("gap", MAP, "--plan", plan)):
        r = run_cli(*cmd, "--reorder", "sometimes", "--out", tmp_path / "o", cwd=REPO)
        assert_clean_error(r, "--reorder", "sometimes")


def test_reorder_without_the_dependency_graph_is_refused(tmp_path):
    """Reordering switches edges of the physics executor's dependency graph: asked for on
    the grid executor or with ``adg=false`` it is refused, not silently ignored."""
    from warerover_phys.config import ExecutorSpec

    plan = tmp_path / "p.txt"
    plan.write_text("agents=1\nsolution=\n0:(1,1),\n")
    for extra, named in ((("--executor", "grid"), "--executor grid"),
                         (("--executor", "physics", "--set", "executor.adg=false"),
                          "executor.adg=false")):
        r = run_cli("execute", MAP, "--plan", plan, "--reorder", "greedy", *extra,
                    "--out", tmp_path / "o", cwd=REPO)
        assert_clean_error(r, "--reorder greedy", named)
        assert not (tmp_path / "o").exists()
    with pytest.raises(ValueError, match="needs adg: true"):
        ExecutorSpec(name="physics", adg=False, reorder="greedy")
    # a scenario's executor section holds the physics settings whichever executor it
    # names (gap runs it on both): the grid executor ignores them
    assert ExecutorSpec(name="grid", reorder="milp").reorder == "milp"


def test_gap_with_reorder_reports_the_gain(plan40, tmp_path):
    r = run_cli("gap", MAP, "--plan", plan40,
                "--delays", "bernoulli:0.2", "--seed", "1", "--reorder", "greedy", "--json",
                "--no-pictures", "--out", tmp_path / "gap", cwd=REPO, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    rep = json.loads(r.stdout)
    assert rep["lost_reorder_gain_s_fleet_total"] < 0
    assert rep["agv_contacts"] == 0
    r = run_cli("execute", MAP, "--plan", plan40,
                "--delays", "bernoulli:0.2", "--seed", "1", "--reorder", "milp", "--json",
                "--out", tmp_path / "ex", cwd=REPO, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    m = json.loads(r.stdout)
    assert m["reorder"] == "milp" and m["reorder_switches"] >= 1 and m["agv_contacts"] == 0


@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_gap_video_outlines_the_switched_edges(plan40, tmp_path):
    import av
    import numpy as np

    from warerover_phys.render import PALETTE

    video = tmp_path / "greedy.mp4"
    r = run_cli("gap", MAP, "--plan", plan40, "--delays", "bernoulli:0.2", "--seed", "1",
                "--reorder", "greedy", "--no-pictures", "-q", "--out", tmp_path / "gap",
                "--video", video, cwd=REPO, timeout=900)
    assert r.returncode == 0, r.stderr[-2000:]
    colour = np.array(PALETTE["switch"], dtype=np.int16)
    with av.open(str(video)) as c:
        counts = [int((np.abs(f.to_ndarray(format="bgr24").astype(np.int16) - colour)
                       .max(axis=2) < 40).sum())
                  for k, f in enumerate(c.decode(video=0)) if k % 15 == 0]
    # the legend entry (~80 pixels) in every frame; for a while after each switch also
    # the outlined cells and the arrow
    assert min(counts) > 20
    assert max(counts) > min(counts) + 100


def test_gap_of_a_scenario_reorders_its_physics_run(tmp_path):
    """``gap SCENARIO --reorder``: the scenario names the grid executor for its ideal run;
    the reordering applies to the physics execution of its plan (a 2x2 fleet among 1x1s)."""
    import csv

    r = run_cli("gap", REPO / "layouts" / "paper_heterogeneous.yaml", "--seeds", "0..1",
                "--workers", "1", "--reorder", "greedy", "--delays", "bernoulli:0.2",
                "--no-pictures", "--json", "--out", tmp_path / "gap", cwd=REPO, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    rows = list(csv.DictReader((tmp_path / "gap" / "seeds.csv").open()))
    assert [row["completed"] for row in rows] == ["True", "True"]
    assert all(row["agv_contacts"] == "0" for row in rows)
    assert min(float(row["lost_reorder_gain_s_fleet_total"]) for row in rows) < 0
