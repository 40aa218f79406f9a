"""`warerover report`: execution columns (gap, contacts, minimum clearance, intrusions,
deadlocks) and heat maps that mark cells whose CI overlaps the best one."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from warerover_phys.cli import app
from warerover_phys.sweep.report import aggregate, ci_marks, heatmap, markdown_table
from warerover_phys.sweep.results import ResultsFile
from warerover_phys.sweep.spec import episode_key


def _row(planner, executor, seed, ticks, tp, extra=None):
    metrics = {"success_rate": 1.0, "throughput": tp, "ct_mean_ms": 1.0, "ct_total_s": 0.1,
               "ticks": ticks, "corridor_intrusions": 0, **(extra or {})}
    variant = {"executor.name": executor}
    return {"key": episode_key("Ho", {"planner.name": planner, **variant}, seed),
            "scenario": "Ho", "scheduler": "ta", "planner": planner, "pattern": "oneshot",
            "executor": executor, "seed": seed, "status": "ok", "metrics": metrics,
            "variant": variant, "error": None}


PHYS = {"agv_contacts": 2, "static_contacts": 1, "min_separation_m": 0.25, "deadlocks": 1}


def _rows():
    rows = []
    for seed, (g, p) in enumerate([(100, 120), (100, 130), (200, 220)]):
        rows.append(_row("astar", "grid", seed, g, 20 / g))
        rows.append(_row("astar", "physics", seed, p, 20 / p, PHYS))
    return rows


def test_gap_pairs_physics_with_its_grid_twin():
    groups = {(g.variant, g.pattern): g for g in aggregate(_rows())}
    phys = groups['executor.name="physics"', "all"]
    ratios = [1.2, 1.3, 1.1]
    assert phys.stats["gap"][0] == pytest.approx(np.mean(ratios))
    assert phys.stats["gap"][1] > 0
    assert phys.stats["contacts"][0] == 3.0 and phys.stats["deadlocks"][0] == 1.0
    assert phys.stats["min_clear_m"] == (0.25, 0.0)
    grid = groups['executor.name="grid"', "all"]
    assert all(math.isnan(grid.stats[m][0]) for m in ("gap", "contacts", "min_clear_m",
                                                     "deadlocks"))
    assert grid.stats["intrusions"] == (0.0, 0.0)


def test_gap_needs_a_twin_with_the_same_seed():
    rows = [r for r in _rows() if not (r["executor"] == "grid" and r["seed"] == 2)]
    phys = next(g for g in aggregate(rows) if "physics" in g.variant and g.pattern == "all")
    assert phys.stats["gap"][0] == pytest.approx(1.25)   # seeds 0 and 1 only


def test_markdown_shows_execution_columns_blank_where_missing():
    groups = [g for g in aggregate(_rows()) if g.pattern == "all"]
    md = markdown_table(groups)
    head = md.splitlines()[0]
    for title in ("gap (ticks, phys/grid)", "contacts", "min clearance (m)", "intrusions",
                  "deadlocks"):
        assert title in head
    grid_line = next(line for line in md.splitlines() if '"grid"' in line)
    cells = [c.strip() for c in grid_line.strip("|").split("|")]
    # gap, contacts, min clearance blank; intrusions 0; deadlocks blank
    assert cells[-7:-2] == ["", "", "", "0.0 ± 0.0", ""]


def test_no_execution_columns_when_no_episode_has_them():
    rows = [_row("astar", "grid", s, 100, 0.2) for s in range(2)]
    for r in rows:
        del r["metrics"]["corridor_intrusions"]
    md = markdown_table([g for g in aggregate(rows) if g.pattern == "all"])
    assert "contacts" not in md and "gap" not in md


def test_ci_marks_overlap_and_difference():
    rows = []
    for seed in range(4):
        rows.append(_row("astar", "grid", seed, 100, 0.30 + 0.01 * seed))   # 0.315 ± .02
        rows.append(_row("pibt", "grid", seed, 100, 0.31 + 0.01 * seed))    # 0.325 ± .02
        rows.append(_row("cbs", "grid", seed, 100, 0.10 + 0.001 * seed))    # far below
    groups = [g for g in aggregate(rows) if g.pattern == "all"]
    marks = dict(zip([g.planner for g in groups], ci_marks(groups, "tp"), strict=True))
    assert marks == {"pibt": "best", "astar": "overlap", "cbs": ""}
    # lower is better for CT; all equal -> all best
    assert set(ci_marks(groups, "ct_ms")) == {"best"}
    assert set(ci_marks(groups, "gap")) == {"none"}


def test_heatmap_hatches_overlapping_cells(tmp_path):
    pytest.importorskip("matplotlib")
    import cv2

    def hatched_pixels(tp_second: float) -> int:
        rows = []
        for seed in range(4):
            rows.append(_row("astar", "grid", seed, 100, 0.30 + 0.01 * seed))
            rows.append(_row("pibt", "grid", seed, 100, tp_second + 0.01 * seed))
        groups = [g for g in aggregate(rows) if g.pattern == "all"]
        path = heatmap(groups, tmp_path / f"t{tp_second}.png", "t")
        img = cv2.imread(str(path))
        assert img is not None and img.shape[0] > 100 and img.shape[1] > 600
        # the TP column of the two data rows (between the header and legend)
        h, w = img.shape[:2]
        dark = (img.max(axis=2) < 170)
        return int(dark[:, int(w * 0.72):].sum()), img

    overlap_dark, img = hatched_pixels(0.31)       # CIs overlap: the lower cell is hatched
    apart_dark, img2 = hatched_pixels(0.90)        # far apart: no hatching in the column
    assert overlap_dark > apart_dark + 200
    # green (best) and red (worst) fills present where they differ
    b, g, r = [img2[..., i].astype(int) for i in range(3)]
    assert ((g - r > 40) & (g > 200)).any() and ((r - g > 40) & (r > 200)).any()


def test_report_cli_csv_has_execution_columns(tmp_path):
    out = tmp_path / "sweep"
    rf = ResultsFile(out / "results.jsonl")
    for r in _rows():
        rf.append(r)
    rf.close()
    result = CliRunner().invoke(app, ["report", str(out)])
    assert result.exit_code == 0, result.output
    assert "gap (ticks, phys/grid)" in result.stdout
    with open(out / "report.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    phys = next(r for r in table if "physics" in r["variant"] and r["pattern"] == "all")
    grid = next(r for r in table if "grid" in r["variant"] and r["pattern"] == "all")
    assert float(phys["gap"]) == pytest.approx(1.2) and float(phys["contacts"]) == 3.0
    assert grid["gap"] == "" and grid["deadlocks"] == "" and float(grid["intrusions"]) == 0
