"""The paper's fault-tolerant rows: ``layouts/paper_fault.yaml`` with TA + A*, CBS and PIBT
on both executors over 20 seeds.

Prints SR (%), TP (orders/tick) and CT (ms per tick, scheduler + planner) with the spread
over seeds, failures, corridor intrusions and AGV contacts, next to the paper's FT rows
(TA+A*: SR 100, TP 0.25; TA+CBS: SR 99.9, TP 0.26). Writes ``tools/out/fault_table.json``.

    .venv/bin/python tools/fault_table.py [--seeds 20] [--executors grid physics]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from warerover_phys import load_scenario
from warerover_phys.sim import run_episode

PAPER = {"astar": (100.0, 0.25), "cbs": (99.9, 0.26), "pibt": (None, None)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--planners", nargs="+", default=["astar", "cbs", "pibt"])
    ap.add_argument("--executors", nargs="+", default=["grid", "physics"])
    ap.add_argument("--out", default="tools/out/fault_table.json")
    args = ap.parse_args()
    rows = []
    print(f"{'method':<10} {'executor':<8} {'SR %':>6} {'TP':>13} {'CT ms/tick':>11} "
          f"{'failures':>9} {'intrus.':>7} {'contacts':>8} {'paper SR/TP':>12}", flush=True)
    for planner in args.planners:
        for executor in args.executors:
            sc = load_scenario("layouts/paper_fault.yaml",
                               [("planner.name", planner), ("executor.name", executor)])
            t0 = time.perf_counter()
            ms = [run_episode(sc, seed=s).metrics for s in range(args.seeds)]
            sr = np.array([m["success_rate"] for m in ms]) * 100
            tp = np.array([m["throughput"] for m in ms])
            ct = np.array([m["ct_mean_ms"] for m in ms])
            contacts = sum(m["collisions"] if executor == "grid" else m["agv_contacts"]
                           for m in ms)
            row = {"planner": planner, "executor": executor, "seeds": args.seeds,
                   "sr_pct": float(sr.mean()), "tp_mean": float(tp.mean()),
                   "tp_std": float(tp.std()), "ct_mean_ms": float(ct.mean()),
                   "failures_mean": float(np.mean([m["failures"] for m in ms])),
                   "corridor_intrusions": int(sum(m["corridor_intrusions"] for m in ms)),
                   "contacts": int(contacts),
                   "ticks_mean": float(np.mean([m["ticks"] for m in ms])),
                   "wall_s": time.perf_counter() - t0}
            rows.append(row)
            psr, ptp = PAPER.get(planner, (None, None))
            paper = "-" if psr is None else f"{psr:g} / {ptp:.2f}"
            print(f"TA+{planner:<7} {executor:<8} {row['sr_pct']:>6.1f} "
                  f"{row['tp_mean']:>6.3f}±{row['tp_std']:.3f} {row['ct_mean_ms']:>11.2f} "
                  f"{row['failures_mean']:>9.1f} {row['corridor_intrusions']:>7} "
                  f"{row['contacts']:>8} {paper:>12}", flush=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rows, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
