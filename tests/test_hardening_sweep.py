"""One sweep per results folder (a second one exits 2 naming the holder), and SIGTERM ends
a sweep cleanly: its worker processes are gone, what finished is on disk, a rerun resumes."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest
from hardening_helpers import LAYOUTS, assert_clean_error, cli_argv, cli_env, run_cli

PAPER = LAYOUTS / "paper_homogeneous.yaml"


def children(pid: int) -> set[int]:
    """Every live descendant of ``pid`` (from /proc)."""
    parent: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            parent[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    out, frontier = set(), {pid}
    while frontier:
        frontier = {p for p, pp in parent.items() if pp in frontier} - out
        out |= frontier
    return out


def alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.slow  # two sweeps through the CLI: make test-all
def test_second_sweep_is_refused_and_sigterm_cleans_up(tmp_path):
    sweep = tmp_path / "s.yaml"
    sweep.write_text(f"scenarios: {{Ho: {PAPER}}}\ngrid: {{executor.name: [physics]}}\n"
                     "repetitions: 40\n")
    out = tmp_path / "out"
    first = subprocess.Popen(cli_argv("sweep", sweep, "--out", out, "--workers", "1", "-q"),
                             cwd=tmp_path, env=cli_env(), stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        info = out / ".sweep.lock.json"
        deadline = time.monotonic() + 60
        while not info.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        holder = json.loads(info.read_text())
        assert holder["pid"] == first.pid
        second = run_cli("sweep", sweep, "--out", out, "--workers", "1", "-q", cwd=tmp_path)
        assert_clean_error(second, str(out), f"pid {first.pid}", "another sweep")
        # Wait for a worker and a result or two, then SIGTERM the driver.
        deadline = time.monotonic() + 60
        while (not (out / "results.jsonl").exists() or
               not (out / "results.jsonl").read_text().strip()) and time.monotonic() < deadline:
            time.sleep(0.2)
        kids = children(first.pid)
        assert kids, "the sweep should have a worker process"
        first.send_signal(signal.SIGTERM)
        _, err = first.communicate(timeout=60)
        assert first.returncode == 130, err[-2000:]
        assert "Traceback" not in err, err[-2000:]
        deadline = time.monotonic() + 10
        while any(alive(k) for k in kids) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not [k for k in kids if alive(k)]
        assert not info.exists()
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
    done = len((out / "results.jsonl").read_text().splitlines())
    assert 0 < done < 40
    # the lock was released with the process: a resumed sweep runs the rest
    again = run_cli("sweep", sweep, "--out", out, "--workers", "1", "-q", "--repetitions",
                    str(done + 1), cwd=tmp_path, timeout=300)
    assert again.returncode == 0, again.stderr[-2000:]


def test_sigkill_releases_the_lock(tmp_path):
    sweep = tmp_path / "s.yaml"
    sweep.write_text(f"scenarios: {{Ho: {PAPER}}}\nrepetitions: 40\n")
    out = tmp_path / "out"
    first = subprocess.Popen(cli_argv("sweep", sweep, "--out", out, "--workers", "1", "-q"),
                             cwd=tmp_path, env=cli_env(), stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while not (out / ".sweep.lock.json").exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    kids = children(first.pid)
    first.send_signal(signal.SIGKILL)
    first.wait()
    again = run_cli("sweep", sweep, "--out", out, "--workers", "1", "-q", "--repetitions", "1",
                    cwd=tmp_path, timeout=300)
    assert again.returncode == 0, again.stderr[-2000:]
    deadline = time.monotonic() + 10
    while any(alive(k) for k in kids) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not [k for k in kids if alive(k)]
    assert os.path.exists(out / "results.jsonl")


def test_failed_sweep_leaves_no_folder(tmp_path):
    sweep = tmp_path / "s.yaml"
    sweep.write_text(f"scenarios: {{Ho: {PAPER}}}\nset: {{max_ticks: -1}}\nrepetitions: 1\n")
    proc = run_cli("sweep", sweep, "--out", tmp_path / "out", cwd=tmp_path)
    assert_clean_error(proc, "max_ticks")
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM, signal.SIGINT])
def test_killed_ray_driver_leaves_no_ray_processes(tmp_path, sig):
    pytest.importorskip("ray")
    sweep = tmp_path / "s.yaml"
    sweep.write_text(f"scenarios: {{Ho: {PAPER}}}\nrepetitions: 200\n")
    out = tmp_path / "out"
    driver = subprocess.Popen(cli_argv("sweep", sweep, "--out", out, "--ray", "local",
                                       "--workers", "1", "-q"),
                              cwd=tmp_path, env=cli_env(), stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 240
        results = out / "results.jsonl"
        while (not results.exists() or not results.read_text().strip()) \
                and time.monotonic() < deadline and driver.poll() is None:
            time.sleep(0.5)
        assert results.exists() and results.read_text().strip(), "no episode finished on Ray"
        time.sleep(2)
        kids = children(driver.pid)
        assert len(kids) > 2, "Ray should have started processes"
        driver.send_signal(sig)
        driver.wait(timeout=60)
        # (SIGTERM / SIGINT: usually exit 130 after a clean shutdown; Ray's own handlers
        # sometimes end the driver first - either way nothing may be left running.)
        deadline = time.monotonic() + 30
        while any(alive(k) for k in kids) and time.monotonic() < deadline:
            time.sleep(0.5)
        left = [k for k in kids if alive(k)]
        assert not left, [Path(f"/proc/{k}/cmdline").read_bytes()[:80] for k in left]
    finally:
        if driver.poll() is None:
            driver.kill()
            driver.wait()
