"""dt convergence of the physics executor: the same scenario and seed at several physics
steps, makespan and other figures side by side.

For each shipped scenario (``layouts/*.yaml``, or those given) and seed, runs the episode on
the physics executor at each ``dt_s`` and prints a table of makespan (ticks), success rate,
orders completed (what to compare on a run capped by ``--max-ticks``), dependency wait,
kinematic lag and contacts, with each makespan's relative difference from
the finest step's; ``--json`` writes the rows.

    python tools/dt_convergence.py [--dt 0.01 0.02 0.05] [--seeds 0] [--max-ticks N] \\
        [--set robot=diffdrive] [--json out.json] [layouts/paper_homogeneous.yaml ...]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
KEYS = ("ticks", "success_rate", "orders_completed", "delay_dependency_wait_s",
        "kinematic_lag_mean_s", "delay_turns_s", "deadlocks", "agv_contacts",
        "limit_violations", "min_clearance_m")


def run_one(path: Path, seed: int, dt: float, max_ticks: int | None,
            extra: list[tuple[str, object]] | None = None) -> dict:
    from warerover_phys import load_scenario
    from warerover_phys.sim import run_episode

    sets = [("executor.name", "physics"), ("executor.dt_s", dt), *(extra or [])]
    if max_ticks is not None:
        sets.append(("max_ticks", max_ticks))
    sc = load_scenario(path, sets)
    t0 = time.perf_counter()
    m = run_episode(sc, seed=seed).metrics
    row = {"scenario": path.stem, "seed": seed, "dt_s": dt,
           "wall_s": round(time.perf_counter() - t0, 1)}
    row.update({k: m.get(k) for k in KEYS})
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenarios", nargs="*", type=Path,
                    default=sorted((ROOT / "layouts").glob("*.yaml")))
    ap.add_argument("--dt", type=float, nargs="+", default=[0.01, 0.02, 0.05])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--max-ticks", type=int, help="cap every episode (default: the file's)")
    ap.add_argument("--json", type=Path, help="write the rows here")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="override a scenario field in every run (repeatable), e.g. "
                         "robot=diffdrive")
    args = ap.parse_args()
    from warerover_phys.config import parse_override

    extra = [parse_override(text) for text in args.set]
    rows = []
    dts = sorted(args.dt)
    print("| scenario | seed | dt_s | makespan (ticks) | vs finest | SR | orders | dependency "
          "wait (s) | kinematic lag mean (s) | deadlocks | contacts | wall (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for path in args.scenarios:
        for seed in args.seeds:
            base = None
            for dt in dts:
                row = run_one(path, seed, dt, args.max_ticks, extra)
                base = row["ticks"] if base is None else base
                row["makespan_diff"] = (row["ticks"] - base) / base if base else 0.0
                rows.append(row)
                print(f"| {row['scenario']} | {seed} | {dt:g} | {row['ticks']} | "
                      f"{row['makespan_diff']:+.1%} | {row['success_rate']:.2f} | "
                      f"{row['orders_completed']} | "
                      f"{row['delay_dependency_wait_s']:.1f} | "
                      f"{row['kinematic_lag_mean_s']:.3f} | {row['deadlocks']} | "
                      f"{row['agv_contacts']} | {row['wall_s']} |", flush=True)
    worst = max((abs(r["makespan_diff"]) for r in rows), default=0.0)
    print(f"largest makespan difference from the finest dt: {worst:.1%}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
