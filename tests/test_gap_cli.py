"""``warerover gap``: open loop by default, ``--mode closed`` labelled as such, ``--seeds``
in parallel with statistics and tidy tables, ``--plan`` for imported plans, and pictures
that are looked at."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from hardening_helpers import REPO, assert_clean_error, run_cli

from warerover_phys.gap.open_loop import PARTS
from warerover_phys.gap.plots import COLOURS, SIZES
from warerover_phys.gap.stats import STAT_KEYS, parse_seeds

HOMO = REPO / "layouts" / "paper_homogeneous.yaml"
DATA = REPO / "tests" / "data"


@pytest.fixture(scope="module")
def seeds_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("gap") / "seeds"
    r = run_cli("gap", HOMO, "--seeds", "0..1", "--workers", "2", "--out", out, "--json",
                cwd=REPO, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    return out, json.loads(r.stdout)


def test_seeds_summary_has_every_statistic(seeds_dir):
    out, printed = seeds_dir
    summary = json.loads((out / "summary.json").read_text())
    assert summary["mode"] == printed["mode"] == "open-loop"
    assert summary["seeds"] == [0, 1] and summary["failed"] == []
    stats = summary["statistics"]
    for key in ("makespan_ratio", "sum_of_costs_ratio", "lost_s_fleet_total",
                "lost_s_per_agv_mean", "lost_dependency_s_fleet_total",
                "lost_dependency_s_per_agv_mean"):
        s = stats[key]
        assert set(STAT_KEYS) <= set(s) and s["n"] == 2
        assert s["min"] <= s["median"] <= s["max"] and s["p95"] <= s["max"]
        assert s["ci95_low"] <= s["mean"] <= s["ci95_high"]
    seeds = list(csv.DictReader((out / "seeds.csv").open()))
    ratios = [float(r["makespan_ratio"]) for r in seeds]
    assert math.isclose(stats["makespan_ratio"]["mean"], sum(ratios) / 2)
    assert math.isclose(stats["makespan_ratio"]["max"], max(ratios))


def test_agents_table_one_row_per_seed_and_agv_full_precision(seeds_dir):
    import pyarrow.parquet as pq

    out, _ = seeds_dir
    rows = list(csv.DictReader((out / "agents.csv").open()))
    assert len(rows) == 2 * 9
    assert {(int(r["seed"]), int(r["agv"])) for r in rows} == {(s, a) for s in range(2)
                                                               for a in range(9)}
    table = pq.read_table(out / "agents.parquet").to_pylist()
    assert len(table) == len(rows)
    for r, t in zip(rows, table, strict=True):
        assert float(r["lost_s"]) == t["lost_s"]  # the CSV keeps every digit
        parts = sum(t[f"lost_{p}_s"] for p in PARTS)
        assert math.isclose(parts, t["lost_s"], abs_tol=1e-9)


def _near(img: np.ndarray, hex_colour: str, tol: float = 0.06) -> int:
    h = hex_colour.lstrip("#")
    rgb = np.array([int(h[j:j + 2], 16) / 255 for j in (0, 2, 4)])
    return int((np.abs(img[..., :3] - rgb).max(axis=2) < tol).sum())


@pytest.mark.parametrize("name,colours", [
    ("time_space.png", ["planned", "executed"]),
    ("lost_by_cause.png", ["dependency", "accel_decel", "turning", "faster_than_plan"]),
    ("gap_hist.png", ["hist", "mean"]),
    ("wait_heat.png", ["obstacle"]),
])
def test_pictures_are_looked_at(seeds_dir, name, colours):
    import matplotlib.image as mpimg

    out, _ = seeds_dir
    path = out / name
    assert path.stat().st_size > 5_000
    img = mpimg.imread(str(path))
    w, h = SIZES[name]
    assert img.shape[:2] == (h, w)
    assert img[..., :3].std() > 0.05  # not a blank canvas
    for c in colours:
        assert _near(img, COLOURS[c]) > 200, (name, c)
    if name == "wait_heat.png":
        # the YlOrRd heat: some pixels in the orange-red range (r high, g lower, b low)
        r, g, b = img[..., 0], img[..., 1], img[..., 2]
        assert ((r > 0.8) & (g < 0.6) & (b < 0.3)).sum() > 100


@pytest.mark.slow  # closed-loop gap runs through the CLI: make test-all
def test_closed_mode_is_labelled_everywhere(tmp_path):
    out = tmp_path / "closed.json"
    r = run_cli("gap", HOMO, "--mode", "closed", "--seed", "1", "--set", "max_ticks=40",
                "--out", out, cwd=REPO)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "closed-loop gap" in r.stdout
    assert json.loads(out.read_text())["mode"] == "closed-loop"
    r = run_cli("gap", HOMO, "--mode", "closed", "--seeds", "1,2", "--workers", "1",
                "--set", "max_ticks=40", "--out", tmp_path / "cs", "-q", cwd=REPO)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "closed-loop gap" in r.stdout
    summary = json.loads((tmp_path / "cs" / "summary.json").read_text())
    assert summary["mode"] == "closed-loop" and summary["seeds"] == [1, 2]
    assert "delay_dependency_wait_s_fleet_total" in summary["statistics"]


def test_one_seed_folder_and_table(tmp_path):
    out = tmp_path / "one"
    r = run_cli("gap", HOMO, "--seed", "1", "--out", out, "--agvs", "0,4", cwd=REPO)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "open-loop gap" in r.stdout and "lost_dependency_s" in r.stdout
    rep = json.loads((out / "gap.json").read_text())
    assert rep["mode"] == "open-loop" and rep["grid"]["success_rate"] == 1.0
    actions = list(csv.DictReader((out / "actions.csv").open()))
    assert len(actions) == rep["actions"]
    for name in ("time_space.png", "lost_by_cause.png", "wait_heat.png", "agents.csv"):
        assert (out / name).stat().st_size > 0


def test_imported_plan(tmp_path):
    plan = tmp_path / "plan.txt"
    r = run_cli("solve", DATA / "random-32-32-10.map", DATA / "random-32-32-10-random-1.scen",
                "--agents", "12", "--out", plan, cwd=REPO)
    assert r.returncode == 0, r.stderr[-2000:]
    r = run_cli("gap", DATA / "random-32-32-10.map", "--plan", plan, "--out",
                tmp_path / "g", "--json", cwd=REPO)
    assert r.returncode == 0, r.stderr[-2000:]
    rep = json.loads(r.stdout)
    assert rep["mode"] == "open-loop" and rep["agents"] == 12 and rep["completed"]
    total = sum(rep[f"lost_{p}_s_fleet_total"] for p in PARTS)
    assert math.isclose(total, rep["lost_s_fleet_total"], abs_tol=1e-6)
    assert (tmp_path / "g" / "lost_by_cause.png").exists()


@pytest.mark.parametrize("args,needles", [
    (("--seeds", "5..1"), ["--seeds", "5..1"]),
    (("--seeds", "a,b"), ["--seeds"]),
    (("--mode", "sideways"), ["--mode", "sideways"]),
    (("--agvs", "x"), ["--agvs"]),
    (("--plan", "nope.txt", "--mode", "closed"), ["--plan"]),
])
def test_bad_options_are_clean_errors(tmp_path, args, needles):
    r = run_cli("gap", HOMO, *args, "--out", tmp_path / "o", cwd=REPO)
    assert_clean_error(r, *needles)
    assert not (tmp_path / "o").exists()


def test_parse_seeds():
    assert parse_seeds("0..3") == [0, 1, 2, 3]
    assert parse_seeds("3,5,0..1,3") == [3, 5, 0, 1]
