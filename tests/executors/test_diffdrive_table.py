"""tools/diffdrive_table.py's bookkeeping (issue 37): a run cut short keeps its rows, the
table is made of the rows asked for, and a disagreement between the independent checks and
the executor's counters shows."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _tool():
    sys.path.insert(0, str(ROOT / "tools"))
    spec = importlib.util.spec_from_file_location("diffdrive_table",
                                                  ROOT / "tools" / "diffdrive_table.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _row(scenario: str, planner: str, seed: int, delays: bool, overlaps: int = 0,
         contacts: int = 0, accel: float = 1.0) -> dict:
    peaks = {"peak_speed_ratio": 0.9, "peak_accel_ratio": accel,
             "peak_turn_rate_ratio": 1.0, "peak_wheel_speed_ratio": 0.95}
    return {"scenario": scenario, "planner": planner, "seed": seed, "delays": delays,
            "success_rate": 1.0, "agv_overlap_samples": overlaps,
            "static_overlap_samples": 0, "min_agv_clearance_m": 0.01 + seed / 100,
            "peak_lateral_speed_mps": 1e-13, **peaks,
            "exec": {"agv_contacts": contacts, "static_contacts": 0, "limit_violations": 0,
                     **peaks}}


def test_table_only_reads_the_rows_of_the_jobs_asked_for(tmp_path):
    t = _tool()
    log = tmp_path / "episodes.jsonl"
    rows = [_row("a.yaml", "pibt", s, d) for s in range(3) for d in (False, True)]
    log.write_text("".join(json.dumps(r) + "\n" for r in rows))
    jobs = [("a.yaml", "", "pibt", s, d, 100) for s in range(2) for d in (False, True)]
    got = t.run_episodes(jobs, 1, log, resume=False, run=False)
    assert sorted((r["seed"], r["delays"]) for r in got) == [
        (0, False), (0, True), (1, False), (1, True)]
    assert len(log.read_text().splitlines()) == 6  # reading it does not rewrite it
    text = t.table(got)
    assert "a.yaml" in text and " yes" in text and " NO" not in text
    assert "4 episodes ({0: 2, 1: 2} per seed), 0 with" in t.summary(got)


def test_resume_runs_nothing_when_every_job_is_there(tmp_path):
    t = _tool()
    log = tmp_path / "episodes.jsonl"
    log.write_text(json.dumps(_row("a.yaml", "astar", 0, False)) + "\n")
    got = t.run_episodes([("a.yaml", "", "astar", 0, False, 100)], 1, log, resume=True)
    assert [r["seed"] for r in got] == [0]


def test_disagreement_and_contacts_show(tmp_path):
    t = _tool()
    one_sided = _row("b.yaml", "cbs", 0, False, overlaps=0, contacts=2)
    off_peak = _row("b.yaml", "cbs", 1, False)
    off_peak["exec"]["peak_accel_ratio"] = 1.01  # the executor saw a larger peak
    assert not t.agree(one_sided) and not t.agree(off_peak)
    assert t.agree(_row("b.yaml", "cbs", 2, False, overlaps=3, contacts=1))
    assert " NO" in t.table([one_sided, off_peak])
    assert "2 with a contact" not in t.summary([one_sided, off_peak])
    assert "1 with a contact" in t.summary([one_sided, off_peak])
    assert "agree in 0 of 2" in t.summary([one_sided, off_peak])


def _two_agvs(samples: int = 41, dt: float = 0.02) -> dict:
    """AGV 0 accelerates at 1 m/s^2 along x from rest, AGV 1 stands ahead of it: their
    0.7 m bodies overlap from the moment 0 has come within 0.7 m."""
    import numpy as np

    t = np.arange(samples) * dt
    x = np.column_stack([1.0 + 0.5 * t ** 2, np.full(samples, 1.72)])
    return {"t": t, "x": x, "y": np.full((samples, 2), 1.5), "heading": np.zeros((samples, 2)),
            "body_m": np.full((2, 2), 0.7), "grid": np.zeros((3, 4), dtype=np.int8),
            "cell_m": 1.0, "limit_speed_mps": np.full(2, 1.5),
            "limit_accel_mps2": np.full(2, 1.0), "limit_turn_rate_radps": np.full(2, 2.5)}


def test_an_overlap_stride_keeps_the_peaks_and_the_sample_indices():
    import numpy as np

    sys.path.insert(0, str(ROOT / "tools"))
    from diffdrive_checks import check_npz

    d = _two_agvs()
    every = check_npz(d, np.zeros(2, dtype=bool), max_polygons=20)
    strided = check_npz(d, np.zeros(2, dtype=bool), max_polygons=20, overlap_stride=3)
    # the peaks read every sample either way: 1 m/s^2 against a limit of 1
    assert abs(every["peak_accel_ratio"] - 1.0) < 1e-6
    for k in ("peak_speed_ratio", "peak_accel_ratio", "peak_turn_rate_ratio"):
        assert strided[k] == every[k]
    # gap 0.72 - 0.5 t^2 - 0.7 < 0 from t = 0.2 s (sample 10): samples 11..40 overlap
    assert every["agv_overlap_samples"] == 30 and every["overlap_samples"] == 41
    assert strided["overlap_samples"] == 14  # samples 0, 3, ..., 39
    assert strided["agv_overlap_samples"] == len(range(12, 41, 3))
    # the smallest clearance (0: touching) first at sample 10; every 3rd: at sample 12,
    # named by its index in the whole trajectory, not in the chunk or the strided samples
    assert every["min_agv_clearance_at"][0] == 10
    assert strided["min_agv_clearance_at"][0] == 12
