"""Shared by the tests/test_hardening_*.py modules: run the CLI of THIS checkout as a
subprocess and check the one-line clean error (exit 2, no traceback)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
LAYOUTS = REPO / "layouts"
DATA = REPO / "tests" / "data"
MAP = DATA / "random-32-32-10.map"
SCEN = DATA / "random-32-32-10-random-1.scen"
LORR = DATA / "lorr2023_warehouse_small" / "warehouse_small_50.json"
HOMO = LAYOUTS / "paper_homogeneous.yaml"


def cli_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("FORCE_COLOR", "CLICOLOR_FORCE")}
    env.update(COLUMNS="200", NO_COLOR="1", TERM="dumb",
               PYTHONPATH=os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")]))
    return env


def cli_argv(*args: str | Path) -> list[str]:
    return [sys.executable, "-m", "warerover_phys", *map(str, args)]


def run_cli(*args: str | Path, cwd: Path, timeout: float = 120,
            ) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cli_argv(*args), cwd=cwd, env=cli_env(), capture_output=True,
                          text=True, timeout=timeout)


def assert_clean_error(proc: subprocess.CompletedProcess[str], *needles: str) -> str:
    """Exit 2, one line on stderr starting ``error:`` holding every needle, no traceback."""
    err = proc.stderr.strip()
    assert proc.returncode == 2, (proc.returncode, proc.stdout[-2000:], err[-3000:])
    assert "Traceback" not in err and "Traceback" not in proc.stdout, err
    assert len(err.splitlines()) == 1, err
    assert err.startswith("error: "), err
    for needle in needles:
        assert needle in err, (needle, err)
    return err


def make_box(tmp_path: Path) -> tuple[Path, Path]:
    """(inputs folder holding a one-agent ``plan.txt``, empty working folder) for a hostile
    input test: the command runs in the second, which must stay empty."""
    inputs, work = tmp_path / "in", tmp_path / "work"
    inputs.mkdir()
    work.mkdir()
    (inputs / "plan.txt").write_text("Agent 0:(0,0)->(0,1)->\n")
    return inputs, work


def refuse(work: Path, *args: str | Path, needles: tuple | list = (), timeout: float = 60.0
           ) -> str:
    """Run ``warerover ARGS`` in ``work``: a clean error (:func:`assert_clean_error`)
    naming every needle, within ``timeout`` s, and nothing written in ``work``."""
    import time

    t0 = time.monotonic()
    proc = subprocess.run(cli_argv(*args), cwd=work, env=cli_env(), capture_output=True,
                          text=True, timeout=timeout)
    assert time.monotonic() - t0 < timeout
    err = assert_clean_error(proc, *needles)
    assert sorted(p.name for p in work.iterdir()) == [], "wrote something on refusal"
    return err


TIMING = ("ct_", "wall_s", "real_time_factor")
"""Metrics that measure the machine, not the episode (left out of determinism checks)."""


def episode_digest(scenario: str, planner: str, executor: str, seed: int,
                   max_ticks: int | None = None, overrides: tuple = ()) -> str:
    """SHA-256 of everything an episode decides: metrics (timing left out), events, planned
    and executed paths, and on physics the recorded poses (bit for bit). ``overrides``:
    more ``(key, value)`` settings."""
    import hashlib
    import json

    from warerover_phys import load_scenario, run_episode

    # The planners' wall-clock safety stop (planner.time_budget_s, 10 s a call) out of the
    # way: their work budgets decide, as on a quiet machine (at load ~20 on 2 cores two slow
    # physics cases once gave different digests; suspected: that stop, hit in one process).
    over = [("planner.name", planner), ("executor.name", executor),
            ("planner.time_budget_s", 3600.0), *overrides]
    if max_ticks is not None:
        over.append(("max_ticks", max_ticks))
    result = run_episode(load_scenario(LAYOUTS / f"{scenario}.yaml", over), seed=seed)
    metrics = {k: v for k, v in result.metrics.items() if not k.startswith(TIMING)}
    blob = json.dumps([metrics, result.events, result.planned,
                       {str(k): v for k, v in result.actual.items()}],
                      sort_keys=True, default=str)
    digest = hashlib.sha256(blob.encode())
    for key in ("t", "x", "y", "heading", "state", "loaded"):
        if result.trajectory is not None and key in result.trajectory:
            digest.update(key.encode())
            digest.update(np.ascontiguousarray(result.trajectory[key]).tobytes())
    return digest.hexdigest()


def digest_in_subprocess(*args: object, hashseed: int) -> str:
    """:func:`episode_digest` in a fresh interpreter with ``PYTHONHASHSEED=hashseed`` (set
    and dict orders of strings differ between processes: determinism must not depend on
    them)."""
    code = (f"import sys; sys.path.insert(0, {str(REPO / 'tests')!r}); "
            f"import hardening_helpers as h; print(h.episode_digest(*{args!r}))")
    env = {**cli_env(), "PYTHONHASHSEED": str(hashseed)}
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, timeout=1800)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout.strip().splitlines()[-1]
