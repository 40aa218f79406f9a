"""How closely ``warerover solve --planner lacam --refine`` keeps its time limit, by the
wall clock and in CPU time: the figure behind the test that checks the limit in CPU time
(``tests/planning/test_oneshot_refine.py``; a wall-clock test flakes on a loaded machine).

    python tools/bench_deadline.py [--agents 100] [--limit 3.0] [--runs 5] [--json PATH]

Solves MovingAI warehouse-10-20-10-2-1 (scenario random-1, the first ``--agents`` agents)
``--runs`` times with ``time_limit_s = --limit`` and LNS refinement on, and prints per run
the wall seconds, the CPU seconds and both over the limit (``stopped``: ``time``, ``optimal``
or ``no plan`` where no first solution came in time), then the median and the worst,
with the load average before and after (``os.getloadavg``). Run it on a quiet machine for
the figure; under load the wall column shows the waits for a core, the CPU column not.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

if not os.environ.get("PYTHONPATH"):  # PYTHONPATH picks the checkout to measure
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from warerover_phys.planning.oneshot.core import solve  # noqa: E402
from warerover_phys.problems.movingai import read_map, read_scen  # noqa: E402

DATA = Path(__file__).resolve().parent.parent / "tests" / "data"
MAP = DATA / "warehouse-10-20-10-2-1.map"
SCEN = DATA / "warehouse-10-20-10-2-1-random-1.scen"


def measure(agents: int, limit: float, runs: int) -> dict:
    grid = read_map(MAP)
    scen = read_scen(SCEN, agents, grid)
    starts, goals = [a.start for a in scen], [a.goal for a in scen]
    rows = []
    load_before = os.getloadavg()
    for k in range(runs):
        t0, c0 = time.monotonic(), time.process_time()
        res = solve(grid.obstacles, starts, goals, planner="lacam", time_limit_s=limit,
                    refine=True, seed=k)
        wall, cpu = time.monotonic() - t0, time.process_time() - c0
        rows.append({"run": k, "success": res.success,
                     "stopped": res.stats.get("refine", {}).get("stopped", "no plan"),
                     "wall_s": wall, "cpu_s": cpu, "wall_over_limit": wall / limit,
                     "cpu_over_limit": cpu / limit})
    out = {"agents": agents, "limit_s": limit, "runs": rows,
           "load_before": load_before, "load_after": os.getloadavg()}
    for key in ("wall_over_limit", "cpu_over_limit"):
        values = [r[key] for r in rows]
        out[f"{key}_median"], out[f"{key}_max"] = statistics.median(values), max(values)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--agents", type=int, default=100)
    ap.add_argument("--limit", type=float, default=3.0, help="time_limit_s (seconds)")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--json", type=Path, help="also write the figures here")
    args = ap.parse_args(argv)
    out = measure(args.agents, args.limit, args.runs)
    print(f"lacam + LNS, {args.agents} agents, time limit {args.limit:g} s, load average "
          f"{out['load_before'][0]:.2f} before, {out['load_after'][0]:.2f} after")
    print(f"{'run':>3} {'stopped':>8} {'wall s':>7} {'cpu s':>7} {'wall/limit':>10} "
          f"{'cpu/limit':>9}")
    for r in out["runs"]:
        print(f"{r['run']:>3} {r['stopped']:>8} {r['wall_s']:7.3f} {r['cpu_s']:7.3f} "
              f"{r['wall_over_limit']:10.3f} {r['cpu_over_limit']:9.3f}")
    print(f"median {out['wall_over_limit_median']:.3f} (wall) {out['cpu_over_limit_median']:.3f}"
          f" (cpu); worst {out['wall_over_limit_max']:.3f} (wall) "
          f"{out['cpu_over_limit_max']:.3f} (cpu)")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
