"""Lifelong PIBT on any League of Robot Runners problem: ms per timestep, tasks, memory.

Runs :func:`warerover_phys.lorr.run_lifelong` (the engine of ``warerover lorr``) on the
problem JSON given, with ``--agents`` robots (default: its ``teamSize``; fewer: its first
ones; more: the extra ones drawn on free cells with ``--agents-seed``, as
``tools/make_lorr_agents.py`` does), with and/or without the rotation model, and prints and
writes (JSON) ms per timestep (mean, p99, max; of it the PIBT step and the breadth-first
searches of the distance tables), set-up seconds (of it numba's compile or cache load),
tasks finished, the distance-table
store's counters (hits, misses, evictions, prefetched) and peak memory (the process's peak
RSS so far: give one ``--rotations`` value per call to measure a run alone). Every
timestep's configuration is checked by the runner (no vertex or swap conflicts, no jumps).

    .venv/bin/python tools/bench_lifelong.py \\
        ../shared/data/robotrunners/lorr2026_warehouse_fulfill/fulfill-example_2500.json \\
        --agents 5000 --ticks 1000 --rotations off --prefetch --dist-budget-mb 2200 --stream
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from warerover_phys.lorr import read_problem, run_lifelong

ROOT = Path(__file__).resolve().parent.parent
DEFAULT = ROOT / "tests" / "data" / "lorr2023_warehouse_small" / "warehouse_small_50.json"


def with_agents(problem, n: int, seed: int = 0):
    """``problem`` with ``n`` agents: its first ``n``, or all and ``n - teamSize`` more on
    free cells no agent stands on, drawn uniformly by ``default_rng(seed)`` in one draw."""
    starts = list(problem.starts[:n])
    extra = n - len(starts)
    if extra > 0:
        free = np.setdiff1d(np.flatnonzero(~problem.grid.obstacles.ravel()),
                            np.asarray(starts))
        if extra > len(free):
            raise SystemExit(f"only {len(free)} free cells left for {extra} more agents")
        starts += np.random.default_rng(seed).choice(free, size=extra, replace=False).tolist()
    return dataclasses.replace(problem, starts=tuple(starts))


def _rss_mb() -> float:
    """Peak RSS of this process so far, MB (Linux: ru_maxrss in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", type=Path, nargs="?", default=DEFAULT)
    ap.add_argument("--agents", type=int, help="robots (default: the problem's teamSize)")
    ap.add_argument("--agents-seed", type=int, default=0)
    ap.add_argument("--ticks", type=int, default=500)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rotations", choices=["on", "off", "both"], default="both")
    ap.add_argument("--rule", choices=["actions", "turn-first"], default="actions",
                    help="how PIBT meets the rotation model (see warerover lorr)")
    ap.add_argument("--dist-budget-mb", type=float, default=1024.0)
    ap.add_argument("--prefetch", action="store_true",
                    help="tables of the errand cells before the first timestep")
    ap.add_argument("--stream", action="store_true",
                    help="stream the actions to a temporary folder (as `lorr --out`)")
    ap.add_argument("--engine", choices=["auto", "numba", "python"], default="auto",
                    help="the PIBT step: compiled (numba) or the Python reference")
    ap.add_argument("--json", type=Path, default=Path(__file__).parent / "out" /
                    "bench_lifelong.json")
    args = ap.parse_args()
    problem = read_problem(args.problem)
    if args.agents:
        problem = with_agents(problem, args.agents, args.agents_seed)
    rows = []
    for rot in {"on": [True], "off": [False], "both": [False, True]}[args.rotations]:
        load0 = os.getloadavg()[0]
        t0 = time.perf_counter()
        with tempfile.TemporaryDirectory(prefix="bench-lifelong-") as trace:
            result = run_lifelong(
                problem, args.ticks, rotations=rot, seed=args.seed, rule=args.rule,
                dist_budget_mb=args.dist_budget_mb, prefetch=args.prefetch,
                trace_dir=trace if args.stream else None, engine=args.engine,
                progress=lambda t, n, t0=t0: print(
                    f"  {t}/{n} {time.perf_counter() - t0:.0f} s RSS {_rss_mb():.0f} MB",
                    file=sys.stderr, flush=True) if t % 100 == 0 else None)
        s = result.summary()
        s["whole_run_s"] = time.perf_counter() - t0
        rss = _rss_mb()
        s.update(peak_rss_mb_so_far=rss, streamed=args.stream,
                 load_average=[load0, os.getloadavg()[0]])
        rows.append(s)
        d = s["dist_tables"]
        print(f"{args.problem.name}: {s['agents']} robots, {s['ticks']} timesteps, rotations "
              f"{'on (' + args.rule + ')' if rot else 'off'}: {s['ms_per_tick_mean']:.1f} ms/"
              f"timestep mean, {s['ms_per_tick_p99']:.1f} p99, {s['ms_per_tick_max']:.1f} max "
              f"(PIBT {s['pibt_ms_per_tick_mean']:.1f} mean, tables {d['bfs_ms_per_tick_mean']:.1f}"
              f" mean; CPU {s['cpu_ms_per_tick_mean']:.1f} mean, {s['cpu_ms_per_tick_p99']:.1f}"
              f" p99, PIBT CPU {s['pibt_cpu_ms_per_tick_mean']:.1f} mean); engine "
              f"{s['engine']}; set-up {s['setup_s']:.1f} s (of it compiling or loading the "
              f"compiled steps {s['compile_s']:.1f} s, prefetching tables "
              f"{d['prefetch_s']:.1f} s); {s['tasks_finished']} tasks; tables: "
              f"{d['misses']} computed, {d['prefetched']} prefetched, {d['hits']} hits, "
              f"{d['evictions']} evicted; peak RSS {rss:.0f} MB; load average "
              f"{load0:.1f} -> {os.getloadavg()[0]:.1f}")
    out = {"runs": rows, "python": platform.python_version(), "platform": platform.platform(),
           "argv": sys.argv[1:]}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
