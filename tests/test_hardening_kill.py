"""SIGKILL during ``warerover run --out`` and ``warerover render --out`` leaves either the
old complete outputs or the new complete outputs, never a mix (real subprocesses)."""

from __future__ import annotations

import hashlib
import json
import signal
import subprocess
import time
from pathlib import Path

import pytest
from hardening_helpers import LAYOUTS, cli_argv, cli_env, run_cli

from warerover_phys.util.atomic import check_set

PAPER = LAYOUTS / "paper_homogeneous.yaml"


def killed_after(args: list, delay: float, cwd: Path) -> int | None:
    """Start the CLI, SIGKILL it after ``delay`` seconds; its exit code if it ended first."""
    proc = subprocess.Popen(cli_argv(*args), cwd=cwd, env=cli_env(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        return proc.wait(timeout=delay)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        return None


def timed(args: list, cwd: Path) -> float:
    t0 = time.perf_counter()
    proc = run_cli(*args, cwd=cwd)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return time.perf_counter() - t0


@pytest.mark.slow  # seven physics runs through the CLI: make test-all
def test_sigkill_during_run_leaves_a_whole_set(tmp_path):
    out = tmp_path / "run"
    # dt 0.05 s: the same outputs (trajectories included) at a third of the physics cost.
    base = ["run", PAPER, "--executor", "physics", "--set", "executor.dt_s=0.05", "--out", out,
            "--json"]
    assert run_cli(*base, "--seed", "1", cwd=tmp_path).returncode == 0
    full = timed(base + ["--seed", "2"], tmp_path)
    assert run_cli(*base, "--seed", "1", cwd=tmp_path).returncode == 0
    seen = set()
    for k in range(1, 6):  # spread over the run; the last one just before it would end
        delay = full * k / 5 if k < 5 else full - 0.02
        killed_after(base + ["--seed", "2" if k % 2 else "3"], delay, tmp_path)
        manifest = check_set(out)                  # raises on a mixed or partial set
        assert manifest is not None
        metrics = json.loads((out / "metrics.json").read_text())
        assert metrics["seed"] == manifest["seed"]
        assert sorted(p.name for p in out.iterdir()) == [
            "events.jsonl", "manifest.json", "metrics.json", "paths.json", "trajectories.npz"]
        seen.add(manifest["seed"])
    leftovers = [p.name for p in tmp_path.iterdir() if p.name.startswith(".run.")]
    # A writer killed before its swap leaves its scratch folder; the next write removes it.
    assert run_cli(*base, "--seed", "5", cwd=tmp_path).returncode == 0
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".run.")], leftovers
    assert check_set(out)["seed"] == 5


@pytest.mark.slow  # ~18 s; the killed run (test above) keeps the atomic-set check in make test
def test_sigkill_during_render_keeps_the_old_video(tmp_path):
    run = tmp_path / "run"
    assert run_cli("run", PAPER, "--executor", "physics", "--out", run, "--json",
                   cwd=tmp_path).returncode == 0
    video = tmp_path / "v.mp4"
    short = ["render", run, "--out", video, "--fps", "2", "--size", "480p"]
    assert run_cli(*short, cwd=tmp_path).returncode == 0
    old = hashlib.sha256(video.read_bytes()).hexdigest()
    long = ["render", run, "--out", video, "--fps", "30", "--speed", "1", "--size", "720p"]
    for delay in (1.0, 2.0, 3.5):
        rc = killed_after(long, delay, tmp_path)
        if rc is None:
            assert hashlib.sha256(video.read_bytes()).hexdigest() == old
        else:
            pytest.fail("the render finished before it could be killed; make it longer")
    # The killed renders' temporary files go with the next render that completes.
    assert run_cli(*short, cwd=tmp_path).returncode == 0
    assert [p.name for p in tmp_path.iterdir() if p.suffix == ".mp4"] == ["v.mp4"]
