"""paper_fault with LaCAM: wall seconds per run and whether the same seed gives the same
episode twice (metrics without timing, events, planned paths), on both executors.

    .venv/bin/python tools/paper_fault_lacam.py [--seeds 5] [--json tools/out/paper_fault_lacam.json]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import time
from pathlib import Path

from warerover_phys import load_scenario, run_episode

TIMING = ("ct_", "wall_s", "real_time_factor")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--json", type=Path, default=Path("tools/out/paper_fault_lacam.json"))
    args = ap.parse_args()
    rows = []
    for ex in ("grid", "physics"):
        for seed in range(args.seeds):
            runs = []
            for _ in range(2):
                sc = load_scenario("paper_fault", [("planner.name", "lacam"),
                                                   ("executor.name", ex)])
                t0 = time.perf_counter()
                r = run_episode(sc, seed=seed)
                wall = time.perf_counter() - t0
                m = {k: v for k, v in r.metrics.items() if not k.startswith(TIMING)}
                digest = hashlib.sha256(json.dumps([m, r.events, r.planned], sort_keys=True,
                                                   default=str).encode()).hexdigest()
                runs.append((wall, digest, r.metrics))
            same = runs[0][1] == runs[1][1]
            m = runs[0][2]
            row = {"executor": ex, "seed": seed, "identical": same,
                   "wall_s": [round(w, 2) for w, _, _ in runs],
                   "planner_ct_s": round(m["ct_total_s"], 3),
                   "budget_hits": m["planner_budget_hits"], "ticks": m["ticks"],
                   "success_rate": m["success_rate"]}
            rows.append(row)
            print(f"{ex:8s} seed {seed}: {'identical' if same else 'DIFFERENT'}, "
                  f"wall {row['wall_s'][0]:.2f} / {row['wall_s'][1]:.2f} s, planner CT "
                  f"{row['planner_ct_s']:.2f} s, budget hits {row['budget_hits']}, "
                  f"{row['ticks']} ticks, SR {row['success_rate']:.2f}", flush=True)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(rows, indent=2) + "\n", encoding="utf-8")
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
