"""Shared by the sweep's and the study's pool tests: start a run in a child process,
SIGKILL it once its results file has some rows, and wait for its pool workers to exit on
their own; run a function on a local Ray cluster."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any


def children(pid: int) -> set[int]:
    """The child processes of ``pid`` (from ``/proc``)."""
    out: set[int] = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            out |= {int(c) for c in (task / "children").read_text().split()}
        except OSError:
            pass
    return out


def kill_mid_run(command: list[str], results: Path, *, rows: int = 4,
                 timeout_s: float = 60) -> tuple[int, set[int]]:
    """Run ``python -m warerover_phys COMMAND ... -q``, SIGKILL it once ``results`` has
    ``rows`` lines; return the lines it had then and the worker processes it left."""
    proc = subprocess.Popen([sys.executable, "-m", "warerover_phys", *command, "-q"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env={**os.environ, "NO_COLOR": "1"})
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            if results.exists() and results.read_bytes().count(b"\n") >= rows:
                break
            assert proc.poll() is None, f"the {command[0]} ended before it could be killed"
            time.sleep(0.02)
        workers = children(proc.pid)
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    return results.read_bytes().count(b"\n"), workers


def outlived(workers: set[int], timeout_s: float = 15) -> set[int]:
    """The ``workers`` still alive (not zombies) after up to ``timeout_s``: the orphaned
    pool workers notice their parent is gone and exit."""
    deadline = time.monotonic() + timeout_s
    while workers and time.monotonic() < deadline:
        workers = {w for w in workers if Path(f"/proc/{w}").exists()
                   and "zombie" not in Path(f"/proc/{w}/status").read_text().lower()}
        time.sleep(0.1)
    return workers


def on_local_ray(fn: Callable[[], Any], results: Path) -> tuple[Any, set[int]]:
    """``fn()`` with a local two-CPU Ray cluster up (``ray_address="auto"`` finds it); its
    result and the ``pid``s of the rows in ``results`` (a ``results.jsonl``)."""
    import json

    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        out = fn()
        pids = {json.loads(x)["pid"] for x in results.read_text().splitlines() if x}
    finally:
        ray.shutdown()
    return out, pids
