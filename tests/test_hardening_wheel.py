"""The package stands on its own: shipped scenarios by bare name, and (slow) a wheel built
from the sdist, installed alone in a fresh venv, runs one (``tools/check_wheel.sh``)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys

import pytest
from hardening_helpers import REPO, run_cli

from warerover_phys import load_scenario
from warerover_phys.shipped import resolve_scenario, shipped_names


def test_bare_names_resolve_to_shipped_scenarios(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert set(shipped_names()) >= {"paper_homogeneous", "paper_heterogeneous", "paper_fault",
                                    "industrial"}
    sc = load_scenario("paper_fault")
    assert sc.name == "paper_fault" and sc.source.endswith("paper_fault.yaml")
    assert resolve_scenario("nope").name == "nope"
    assert str(resolve_scenario("sub/paper_fault")) == "sub/paper_fault"
    (tmp_path / "paper_fault").write_text("a: 1\n")        # a local file wins
    assert resolve_scenario("paper_fault") == tmp_path.joinpath("paper_fault").relative_to(
        tmp_path)


def test_cli_runs_a_shipped_scenario_by_name(tmp_path):
    proc = run_cli("run", "paper_homogeneous", "--json", "--out", tmp_path / "r", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("build") is None, reason="needs `build`")
@pytest.mark.skipif(os.environ.get("WAREROVER_OFFLINE") == "1", reason="needs a package index")
def test_wheel_installs_and_runs_alone():
    proc = subprocess.run(["bash", str(REPO / "tools" / "check_wheel.sh"), sys.executable],
                          capture_output=True, text=True, timeout=1500)
    assert proc.returncode == 0, (proc.stdout[-3000:], proc.stderr[-3000:])
    assert proc.stdout.strip().splitlines()[-1].startswith("wheel ok:")
