"""Metrics of every shipped scenario x planner x executor for a few seeds, as JSON.

Run it before and after a change that must not change results, then diff the two files:

    python tools/metrics_snapshot.py --out before.json
    ... change ...
    python tools/metrics_snapshot.py --out after.json --compare before.json

Timing keys (wall-clock CT, real-time factor) are left out: they differ run to run.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from warerover_phys import load_scenario, run_episode

TIMING = ("ct_", "wall", "real_time_factor", "_ms", "_per_s")
LAYOUTS = ("paper_homogeneous", "paper_heterogeneous", "paper_fault")
PLANNERS = ("astar", "cbs", "pibt", "lacam")


def _clean(metrics: dict) -> dict:
    return {k: v for k, v in sorted(metrics.items()) if not any(t in k for t in TIMING)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--compare", type=Path)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--physics-planners", nargs="+", default=["astar", "pibt"])
    args = ap.parse_args()
    root = Path(__file__).resolve().parent.parent / "layouts"
    cases = [(lay, p, "grid") for lay in LAYOUTS for p in PLANNERS]
    cases += [(lay, p, "physics") for lay in LAYOUTS for p in args.physics_planners]
    out = {}
    for lay, planner, executor in cases:
        for seed in args.seeds:
            sc = load_scenario(root / f"{lay}.yaml", [("planner.name", planner),
                                                       ("executor.name", executor)])
            t0 = time.perf_counter()
            res = run_episode(sc, seed=seed)
            key = f"{lay}/{planner}/{executor}/{seed}"
            out[key] = _clean(res.metrics)
            print(f"{key}: SR {res.metrics['success_rate']:.3f} ticks {res.metrics['ticks']} "
                  f"({time.perf_counter() - t0:.1f} s)", file=sys.stderr, flush=True)
    args.out.write_text(json.dumps(out, indent=1, sort_keys=True))
    if args.compare is None:
        return 0
    before = json.loads(args.compare.read_text())
    bad = 0
    for key, m in out.items():
        old = before.get(key)
        if old is None:
            continue
        diff = {k: (old.get(k), m.get(k)) for k in set(old) | set(m) if old.get(k) != m.get(k)}
        if diff:
            bad += 1
            print(f"DIFF {key}: {diff}")
    print(f"{len(out) - bad} of {len(out)} cases identical")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
