"""Issue 13, fault 1: a fuzz of random delay / failure / planner combinations on the paper
scenarios, physics executor. No episode may kill its process: each runs ``warerover run``
in its own subprocess and must end with exit 0 or a clean error exit (1 or 2, one line on
stderr, no traceback). A signal (SIGABRT from a native library, SIGSEGV) fails the test
with the command that reproduces it.

Episodes are shortened (``max_ticks``, a few one-shot orders) and failures are frequent, so
corridors open and close many times per episode. The 200-episode sweep is ``slow``; a
six-episode sample runs in the default suite.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
EXE = Path(sys.executable).parent / "warerover"
SCENARIOS = ("layouts/paper_homogeneous.yaml", "layouts/paper_heterogeneous.yaml",
             "layouts/paper_fault.yaml")
PLANNERS = ("astar", "cbs", "pibt", "lacam")
CLEAN_ERROR = (1, 2)
CHECKERS = ("fcl", "numpy")
"""``faults.checker``, alternating case by case (issue 38: fcl checks corridors again)."""


def cases(n: int, seed: int, max_ticks: int, orders: int) -> list[list[str]]:
    """``n`` argument lists for ``warerover run``: every planner x scenario pair in turn,
    random delay model / probability, failure rate, repair time and episode seed; the
    corridor checker alternates."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        planner = PLANNERS[i % len(PLANNERS)]
        scenario = SCENARIOS[(i // len(PLANNERS)) % len(SCENARIOS)]
        model = str(rng.choice(["none", "bernoulli", "poisson"]))
        args = [scenario, "--executor", "physics", "--planner", planner,
                "--set", f"executor.delays.model={model}",
                "--set", f"executor.delays.prob={rng.uniform(0.0, 0.25):.3f}",
                "--set", f"executor.delays.max_ticks={int(rng.integers(1, 8))}",
                "--set", f"faults.random.prob_per_tick={rng.uniform(0.0, 0.06):.3f}",
                "--set", f"faults.random.repair_ticks={int(rng.integers(3, 40))}",
                "--set", f"max_ticks={max_ticks}",
                "--set", "orders.pattern=oneshot", "--set", f"orders.oneshot.count={orders}",
                "--set", f"faults.checker={CHECKERS[i % len(CHECKERS)]}",
                "--seed", str(int(rng.integers(0, 10_000)))]
        out.append(args)
    return out


def run_case(args: list[str]) -> tuple[list[str], int, str]:
    with tempfile.TemporaryDirectory(prefix="warerover-fuzz-") as tmp:
        r = subprocess.run([str(EXE), "run", *args, "--out", str(Path(tmp) / "run"),
                            "--quiet", "--json"], capture_output=True, text=True, cwd=ROOT,
                           timeout=600, env={**os.environ, "PYTHONFAULTHANDLER": "1"})
    return args, r.returncode, r.stderr[-1500:]


def deaths(all_args: list[list[str]], workers: int = 2) -> list[str]:
    """Run every case; describe each one that did not end with 0 or a clean error."""
    with ThreadPoolExecutor(max_workers=workers) as pool:
        results = list(pool.map(run_case, all_args))
    bad = []
    for args, rc, err in results:
        clean = rc == 0 or (rc in CLEAN_ERROR and "Traceback" not in err)
        if not clean:
            bad.append(f"exit {rc}: warerover run {' '.join(args)}\n{err}")
    return bad


@pytest.mark.slow  # a sample of fuzzed physics episodes: make test-all
def test_fuzz_small_sample_no_process_death():
    """Six short episodes (all four planners, high failure rates), < 30 s."""
    sample = cases(6, seed=13, max_ticks=50, orders=4)
    assert not deaths(sample)


@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_fuzz_200_episodes_no_process_death():
    bad = deaths(cases(200, seed=2026, max_ticks=120, orders=6))
    assert not bad, f"{len(bad)} of 200 episodes died:\n" + "\n".join(bad[:5])
