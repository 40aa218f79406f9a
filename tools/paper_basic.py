"""WareRover's own floor: our TA + A* on the grid executor next to the paper code's stored
results.

Runs ``layouts/warerover_basic.yaml`` (and ``warerover_hetero.yaml`` with ``--hetero``) on
the grid executor over WareRover's seeds 42..141, in parallel (a process pool), and prints
mean throughput (orders/tick) and episode length (ticks) with 95% CIs next to the means
WareRover's ``batch_results/*.csv`` hold for TA + A* (100 runs each, the authors' last
commit b4a3934; see ``shared/data/warerover/README.md``). Our seeds draw other orders than
WareRover's (``random.Random(seed)`` there, numpy here), so only the means compare.
Per-seed metrics and the summary go to JSON.

    .venv/bin/python tools/paper_basic.py                       # 100 seeds, basic floor
    .venv/bin/python tools/paper_basic.py --hetero --workers 2
    .venv/bin/python tools/paper_basic.py --seeds 42..51 --json /tmp/paper_basic.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
PAPER = {
    "warerover_basic": {"throughput": 0.34161, "ticks": 295.87, "blocked_moves": 68.64},
    "warerover_hetero": {"throughput": 0.42170, "ticks": 240.56, "blocked_moves": 52.63},
}
"""WareRover's stored TA + A* means over seeds 42..141 (one-shot, 100 orders)."""
KEYS = ("seed", "throughput", "ticks", "success_rate", "orders_completed", "blocked_moves",
        "collisions", "order_latency_mean_ticks", "replans")


def parse_seeds(text: str) -> list[int]:
    """``"42..141"`` (inclusive) or ``"1,2,5"``."""
    if ".." in text:
        lo, hi = text.split("..", 1)
        return list(range(int(lo), int(hi) + 1))
    return [int(s) for s in text.split(",") if s.strip()]


def run_one(path: str, seed: int) -> dict:
    """One episode's figures (and how many orders WareRover's time-out re-queued)."""
    from warerover_phys import load_scenario, run_episode

    result = run_episode(load_scenario(path), seed=seed)
    row = {k: result.metrics[k] for k in KEYS}
    row["orders_requeued"] = result.world.requeued
    row["blind_trips"] = sum(1 for e in result.events if e["event"] == "blind_trip_ended")
    return row


def ci95(values: np.ndarray) -> float:
    """Half-width of the normal 95% CI of the mean."""
    return float(1.96 * values.std(ddof=1) / np.sqrt(len(values))) if len(values) > 1 else 0.0


def summarise(name: str, runs: list[dict]) -> dict:
    out: dict = {"scenario": name, "seeds": [r["seed"] for r in runs]}
    for key in ("throughput", "ticks", "success_rate", "blocked_moves", "orders_requeued",
                "blind_trips", "order_latency_mean_ticks"):
        v = np.array([r[key] for r in runs], dtype=float)
        out[key] = {"mean": float(v.mean()), "ci95": ci95(v), "min": float(v.min()),
                    "max": float(v.max())}
    paper = PAPER[name]
    out["paper"] = paper
    out["ratio_to_paper"] = {k: out[k]["mean"] / paper[k] for k in ("throughput", "ticks")}
    out["within_10pct"] = all(abs(r - 1.0) <= 0.10 for r in out["ratio_to_paper"].values())
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="42..141", help="a..b (inclusive) or a,b,c")
    ap.add_argument("--hetero", action="store_true", help="also run warerover_hetero.yaml")
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--json", type=Path, default=ROOT / "tools" / "out" / "paper_basic.json")
    args = ap.parse_args(argv)
    seeds = parse_seeds(args.seeds)
    names = ["warerover_basic"] + (["warerover_hetero"] if args.hetero else [])
    report: dict = {"python": platform.python_version(), "workers": args.workers,
                    "results": []}
    for name in names:
        path = str(ROOT / "layouts" / f"{name}.yaml")
        t0 = time.perf_counter()
        with ProcessPoolExecutor(args.workers) as pool:
            runs = list(pool.map(run_one, [path] * len(seeds), seeds))
        summary = summarise(name, runs)
        summary["wall_s"] = time.perf_counter() - t0
        summary["runs"] = runs
        report["results"].append(summary)
        tp, ln = summary["throughput"], summary["ticks"]
        paper = summary["paper"]
        print(f"{name}: TA + A*, grid executor, {len(seeds)} seeds "
              f"({seeds[0]}..{seeds[-1]}), {summary['wall_s']:.0f} s")
        print(f"  {'':22} {'ours':>20} {'WareRover':>10} {'ratio':>7}")
        print(f"  {'throughput, orders/tick':22} {tp['mean']:>11.4f} ± {tp['ci95']:.4f} "
              f"{paper['throughput']:>10.4f} {summary['ratio_to_paper']['throughput']:>7.3f}")
        print(f"  {'episode length, ticks':22} {ln['mean']:>11.1f} ± {ln['ci95']:<6.1f} "
              f"{paper['ticks']:>10.1f} {summary['ratio_to_paper']['ticks']:>7.3f}")
        print(f"  success rate {summary['success_rate']['mean']:.3f}; orders re-queued "
              f"{summary['orders_requeued']['mean']:.1f}/episode, blind trips "
              f"{summary['blind_trips']['mean']:.1f}/episode; blocked moves "
              f"{summary['blocked_moves']['mean']:.1f} (WareRover's 'collisions' "
              f"{paper['blocked_moves']:.1f}, counted differently)")
        print(f"  within 10% of WareRover on both: {summary['within_10pct']}")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(report, indent=1))
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
