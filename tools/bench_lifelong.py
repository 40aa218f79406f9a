"""Lifelong PIBT on any League of Robot Runners problem: ms per timestep, tasks, memory.

Runs :func:`warerover_phys.lorr.run_lifelong` (the engine of ``warerover lorr``) on the
problem JSON given, with its first ``--agents`` robots (default: its ``teamSize``), with and
without the rotation model, and prints and writes (JSON) ms per timestep (mean, p99, max),
set-up seconds (distance tables of the first goals), tasks finished and peak memory. Every
timestep's configuration is checked by the runner (no vertex or swap conflicts, no jumps).

    .venv/bin/python tools/bench_lifelong.py \\
        ../shared/data/robotrunners/lorr2023_warehouse_small/warehouse_small_400.json \\
        --ticks 500
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import resource
import sys
from pathlib import Path

from warerover_phys.lorr import read_problem, run_lifelong

ROOT = Path(__file__).resolve().parent.parent
DEFAULT = ROOT / "tests" / "data" / "lorr2023_warehouse_small" / "warehouse_small_50.json"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", type=Path, nargs="?", default=DEFAULT)
    ap.add_argument("--agents", type=int, help="use the first N robots")
    ap.add_argument("--ticks", type=int, default=500)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rotations", choices=["on", "off", "both"], default="both")
    ap.add_argument("--rule", choices=["actions", "turn-first"], default="actions",
                    help="how PIBT meets the rotation model (see warerover lorr)")
    ap.add_argument("--json", type=Path, default=Path(__file__).parent / "out" /
                    "bench_lifelong.json")
    args = ap.parse_args()
    problem = read_problem(args.problem)
    if args.agents:
        problem = dataclasses.replace(problem, starts=problem.starts[:args.agents])
    rows = []
    for rot in {"on": [True], "off": [False], "both": [False, True]}[args.rotations]:
        result = run_lifelong(problem, args.ticks, rotations=rot, seed=args.seed, rule=args.rule,
                              progress=lambda t, n: print(f"  {t}/{n}", file=sys.stderr)
                              if t % 100 == 0 else None)
        s = result.summary()
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        s["peak_rss_mb_so_far"] = rss
        rows.append(s)
        print(f"{args.problem.name}: {s['agents']} robots, {s['ticks']} timesteps, rotations "
              f"{'on (' + args.rule + ')' if rot else 'off'}: {s['ms_per_tick_mean']:.2f} ms/timestep mean, "
              f"{s['ms_per_tick_p99']:.2f} p99, {s['ms_per_tick_max']:.2f} max; set-up "
              f"{s['setup_s']:.2f} s; {s['tasks_finished']} tasks; peak RSS {rss:.0f} MB")
    out = {"runs": rows, "python": platform.python_version(), "platform": platform.platform()}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
