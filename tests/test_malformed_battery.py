"""``tools/malformed_battery.py`` runs (one class, the quickest) and reports every case
clean; the whole battery is run by hand (``docs/results/robustness.md``)."""

from __future__ import annotations

import json
import subprocess
import sys

from hardening_helpers import REPO, cli_env


def test_the_battery_runs_one_class_clean(tmp_path):
    out = tmp_path / "rows.json"
    proc = subprocess.run([sys.executable, REPO / "tools" / "malformed_battery.py", "--only",
                           "messages", "--json", out], cwd=tmp_path, env=cli_env(),
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    rows = json.loads(out.read_text())
    assert len(rows) == 3 and all(r["clean"] for r in rows)
    assert "| messages | 3 | 3 | 3 | 3 | 3 |" in proc.stdout
