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
