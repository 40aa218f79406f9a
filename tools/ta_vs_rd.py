"""TA vs RD scheduling on the paper's homogeneous scenario, both with the A* planner.

Runs ``layouts/paper_homogeneous.yaml`` with scheduler ``ta`` and ``rd`` over seeds
0..N-1 (``run_episode(scenario, seed=s)`` on the grid executor), prints throughput (TP,
orders/tick), success rate (SR), ticks and collisions per scheduler next to the paper's
figures, and writes the per-seed metrics as JSON.

    .venv/bin/python tools/ta_vs_rd.py
    .venv/bin/python tools/ta_vs_rd.py --seeds 5 --json /tmp/ta_vs_rd.json
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

from warerover_phys import load_scenario, run_episode

SCENARIO = "layouts/paper_homogeneous.yaml"
SCHEDULERS = ("ta", "rd")
PAPER_TP = {"ta": 0.34, "rd": 0.21}
"""Throughput (orders/tick) the paper reports for TA+A* and RD+A* on its basic map."""


def run_scheduler(path: str, name: str, seeds: int) -> dict:
    scenario = load_scenario(path, overrides=[("scheduler.name", name)])
    runs = []
    for seed in range(seeds):
        m = run_episode(scenario, seed=seed).metrics
        runs.append({k: m[k] for k in ("seed", "throughput", "success_rate", "ticks",
                                       "orders_completed", "orders_generated", "collisions",
                                       "blocked_moves", "replans", "ct_mean_ms")})
    tp = np.array([r["throughput"] for r in runs])
    return {
        "scheduler": name,
        "planner": scenario.planner.name,
        "executor": scenario.executor.name,
        "seeds": seeds,
        "tp_mean": float(tp.mean()),
        "tp_std": float(tp.std(ddof=1)) if seeds > 1 else 0.0,
        "tp_min": float(tp.min()),
        "tp_max": float(tp.max()),
        "sr_mean": float(np.mean([r["success_rate"] for r in runs])),
        "ticks_mean": float(np.mean([r["ticks"] for r in runs])),
        "collisions_total": int(sum(r["collisions"] for r in runs)),
        "blocked_moves_total": int(sum(r["blocked_moves"] for r in runs)),
        "ct_mean_ms": float(np.mean([r["ct_mean_ms"] for r in runs])),
        "paper_tp": PAPER_TP[name],
        "runs": runs,
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default=SCENARIO, help="scenario (default: %(default)s)")
    parser.add_argument("--seeds", type=int, default=20,
                        help="seeds 0..N-1 (default: %(default)s)")
    parser.add_argument("--json", type=Path, default=Path("tools/out/ta_vs_rd.json"),
                        help="where to write the figures (default: %(default)s)")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error("--seeds must be at least 1")

    results = []
    for name in SCHEDULERS:
        t0 = time.perf_counter()
        print(f"{name}: {args.seeds} seeds ...", file=sys.stderr, flush=True)
        results.append(run_scheduler(args.scenario, name, args.seeds))
        print(f"{name}: done in {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)

    print(f"{args.scenario}, seeds 0..{args.seeds - 1}, planner astar, grid executor")
    head = ("scheduler", "TP mean", "TP std", "TP min", "SR mean", "ticks mean",
            "collisions", "paper TP")
    print("  ".join(f"{h:>10}" for h in head))
    for r in results:
        cells = (r["scheduler"].upper(), f"{r['tp_mean']:.3f}", f"{r['tp_std']:.3f}",
                 f"{r['tp_min']:.3f}", f"{r['sr_mean']:.3f}", f"{r['ticks_mean']:.1f}",
                 str(r["collisions_total"]), f"{r['paper_tp']:.2f}")
        print("  ".join(f"{c:>10}" for c in cells))
    ta, rd = results
    print(f"TA / RD throughput ratio: {ta['tp_mean'] / rd['tp_mean']:.2f} "
          f"(paper: {PAPER_TP['ta'] / PAPER_TP['rd']:.2f})")

    args.json.parent.mkdir(parents=True, exist_ok=True)
    out = {"scenario": args.scenario, "python": platform.python_version(),
           "paper_tp_orders_per_tick": PAPER_TP, "results": results}
    args.json.write_text(json.dumps(out, indent=2) + "\n", encoding="utf-8")
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
