"""Benchmark the physics executor: real-time factor with 100, 300 and 1000 AGVs.

Runs ``layouts/industrial.yaml`` (generated layout, constant lifelong order stream, PIBT)
on the physics executor with the fleet size overridden, for ``--ticks`` ticks, and reports

- ``rtf_executor``: simulated seconds / wall seconds spent in the physics executor (the
  figure to compare with SMART's ~2.2x for 1,000 robots);
- ``rtf_loop``: simulated seconds / wall seconds of the whole closed loop (scheduler and
  planner included);
- physics steps per second, the share of AGVs driving or turning (``moving``), contacts,
  deadlocks, orders completed.

    .venv/bin/python tools/bench_physics.py
    .venv/bin/python tools/bench_physics.py --agvs 1000 --ticks 100 --dt 0.05

Prints a table and writes ``tools/out/bench_physics.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

from warerover_phys import load_scenario
from warerover_phys.sim import Simulation


def bench(n: int, ticks: int, dt: float, planner: str, batch: int | None = None) -> dict:
    overrides = [("fleet.agvs.0.count", n), ("executor.name", "physics"), ("executor.dt_s", dt),
                 ("planner.name", planner), ("max_ticks", ticks)]
    if batch is not None:
        overrides.append(("orders.constant.batch", batch))
    sc = load_scenario("layouts/industrial.yaml", overrides)
    sim = Simulation(sc, seed=0)
    t0 = time.perf_counter()
    while not sim.done:
        sim.step()
    wall = time.perf_counter() - t0
    ex = sim.executor
    s = ex.summary()
    sim_s = sim.world.tick * sc.tick_s
    return {
        "agvs": n, "ticks": sim.world.tick, "dt_s": ex.dt, "planner": planner,
        "sim_s": sim_s, "wall_loop_s": wall, "wall_executor_s": ex._wall,
        "rtf_executor": sim_s / ex._wall, "rtf_loop": sim_s / wall,
        "physics_steps_per_s": s["physics_steps"] / ex._wall,
        "agv_contacts": s["agv_contacts"], "static_contacts": s["static_contacts"],
        "deadlocks": s["deadlocks"], "actions_executed": s["actions_executed"],
        "moving_share": s["moving_share"],
        "orders_completed": len(sim.world.completed_tick),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agvs", type=int, nargs="+", default=[100, 300, 1000])
    ap.add_argument("--ticks", type=int, default=200)
    ap.add_argument("--dt", type=float, nargs="+", default=[0.02, 0.05])
    ap.add_argument("--planner", default="pibt")
    ap.add_argument("--batch", type=int, default=None,
                    help="orders per 10-tick batch (default: the scenario's 20); more orders "
                         "keep more of the fleet moving")
    ap.add_argument("--out", default="tools/out/bench_physics.json")
    args = ap.parse_args()
    rows = []
    print(f"{'AGVs':>5} {'dt':>5} {'ticks':>5} {'RTF exec':>9} {'RTF loop':>9} "
          f"{'steps/s':>8} {'moving':>6} {'contacts':>8} {'deadl.':>6} {'actions':>8} "
          f"{'orders':>6}",
          flush=True)
    for n in args.agvs:
        for dt in args.dt:
            r = bench(n, args.ticks, dt, args.planner, args.batch)
            rows.append(r)
            print(f"{r['agvs']:>5} {r['dt_s']:>5.2f} {r['ticks']:>5} {r['rtf_executor']:>8.1f}x "
                  f"{r['rtf_loop']:>8.1f}x {r['physics_steps_per_s']:>8.0f} {r['moving_share']:>6.0%} "
                  f"{r['agv_contacts']:>8} {r['deadlocks']:>6} {r['actions_executed']:>8} "
                  f"{r['orders_completed']:>6}", flush=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"machine": {"python": platform.python_version(),
                                           "cpus": os.cpu_count(),
                                           "processor": platform.processor()},
                               "results": rows}, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
