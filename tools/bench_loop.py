"""Benchmark the closed loop on the grid executor: ticks/s, planner and scheduler time per tick.

For each scenario and seed, builds ``Simulation(load_scenario(path), seed)`` and steps it until
every order is done or ``--ticks`` ticks have run, timing the whole loop with a monotonic clock.
Prints one table per scenario and writes the figures, with machine info, as JSON.

    .venv/bin/python tools/bench_loop.py
    .venv/bin/python tools/bench_loop.py --scenarios layouts/industrial.yaml --ticks 100 --seeds 1
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from warerover_phys import load_scenario
from warerover_phys.sim import Simulation

DEFAULT_SCENARIOS = ["layouts/paper_homogeneous.yaml", "layouts/industrial.yaml"]
BIG_AGVS = 100
"""Scenarios with at least this many AGVs get ``--big-seeds`` seeds instead of ``--seeds``."""


def _ms(seconds: list[float]) -> tuple[float, float]:
    """Mean and p99 of per-tick seconds, in milliseconds."""
    if not seconds:
        return 0.0, 0.0
    a = np.asarray(seconds) * 1e3
    return float(a.mean()), float(np.percentile(a, 99))


def bench_one(path: str, seed: int, max_ticks: int | None) -> dict:
    """Run one episode of ``path`` with ``seed`` for at most ``max_ticks`` ticks."""
    scenario = load_scenario(path)
    t0 = time.perf_counter()
    sim = Simulation(scenario, seed)
    build_s = time.perf_counter() - t0
    cap = scenario.max_ticks if max_ticks is None else min(max_ticks, scenario.max_ticks)
    t0 = time.perf_counter()
    last = t0
    while not sim.done and sim.world.tick < cap:
        sim.step()
        now = time.perf_counter()
        if now - last > 5.0:
            print(f"  {scenario.name} seed {seed}: tick {sim.world.tick}/{cap}, "
                  f"{now - t0:.0f} s", file=sys.stderr, flush=True)
            last = now
    loop_s = time.perf_counter() - t0
    ticks = sim.world.tick
    plan_mean, plan_p99 = _ms(sim.metrics.plan_s)
    sched_mean, sched_p99 = _ms(sim.metrics.sched_s)
    return {
        "scenario": scenario.name,
        "path": path,
        "seed": seed,
        "agvs": len(sim.world.agvs),
        "ticks": ticks,
        "tick_cap": cap,
        "finished": sim.world.all_done(),
        "build_s": build_s,
        "loop_s": loop_s,
        "ticks_per_s": ticks / loop_s if loop_s > 0 else 0.0,
        "plan_mean_ms": plan_mean,
        "plan_p99_ms": plan_p99,
        "sched_mean_ms": sched_mean,
        "sched_p99_ms": sched_p99,
        "replans": sim.metrics.replans,
        "replans_per_tick": sim.metrics.replans / ticks if ticks else 0.0,
        "orders_generated": len(sim.world.orders),
        "orders_completed": len(sim.world.completed_tick),
    }


COLUMNS = [("seed", "seed", "{}"), ("AGVs", "agvs", "{}"), ("ticks", "ticks", "{}"),
           ("ticks/s", "ticks_per_s", "{:.1f}"), ("plan ms mean", "plan_mean_ms", "{:.2f}"),
           ("plan ms p99", "plan_p99_ms", "{:.2f}"), ("sched ms mean", "sched_mean_ms", "{:.2f}"),
           ("sched ms p99", "sched_p99_ms", "{:.2f}"), ("replans/tick", "replans_per_tick",
                                                         "{:.2f}"),
           ("orders done", "orders_completed", "{}")]


def _fmt_mean(value: float, fmt: str) -> str:
    return f"{value:.1f}" if fmt == "{}" and isinstance(value, float) else fmt.format(value)


def print_table(name: str, runs: list[dict], summary: dict) -> None:
    rows = [[fmt.format(r[key]) for _, key, fmt in COLUMNS] for r in runs]
    rows.append(["all"] + [_fmt_mean(summary[key], fmt) for _, key, fmt in COLUMNS[1:]])
    head = [h for h, _, _ in COLUMNS]
    widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(head)]
    print(f"\n{name}")
    print("  ".join(h.rjust(w) for h, w in zip(head, widths, strict=True)))
    for row in rows:
        print("  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True)))


def summarise(runs: list[dict]) -> dict:
    """Figures over all seeds: ticks and orders are means per seed, ticks/s and per-tick
    means pool every tick of every seed, p99 is the worst seed's."""
    ticks = sum(r["ticks"] for r in runs)
    loop_s = sum(r["loop_s"] for r in runs)
    return {
        "seeds": [r["seed"] for r in runs],
        "agvs": runs[0]["agvs"],
        "ticks": ticks / len(runs),
        "ticks_per_s": ticks / loop_s if loop_s > 0 else 0.0,
        "plan_mean_ms": sum(r["plan_mean_ms"] * r["ticks"] for r in runs) / ticks,
        "plan_p99_ms": max(r["plan_p99_ms"] for r in runs),
        "sched_mean_ms": sum(r["sched_mean_ms"] * r["ticks"] for r in runs) / ticks,
        "sched_p99_ms": max(r["sched_p99_ms"] for r in runs),
        "replans_per_tick": sum(r["replans"] for r in runs) / ticks,
        "orders_completed": sum(r["orders_completed"] for r in runs) / len(runs),
    }


def machine_info() -> dict:
    return {"platform": platform.platform(), "machine": platform.machine(),
            "processor": platform.processor(), "python": platform.python_version(),
            "cpu_count": os.cpu_count()}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenarios", nargs="+", default=DEFAULT_SCENARIOS,
                        help="scenario YAML files (default: %(default)s)")
    parser.add_argument("--ticks", type=int, default=200,
                        help=f"tick cap for scenarios with >= {BIG_AGVS} AGVs; small ones run "
                             "to the end (default: %(default)s)")
    parser.add_argument("--seeds", type=int, default=3,
                        help="seeds 0..N-1 per scenario (default: %(default)s)")
    parser.add_argument("--big-seeds", type=int, default=2,
                        help=f"seeds for scenarios with >= {BIG_AGVS} AGVs (default: "
                             "%(default)s; 0 = same as --seeds)")
    parser.add_argument("--json", type=Path, default=Path("tools/out/bench_loop.json"),
                        help="where to write the figures (default: %(default)s)")
    args = parser.parse_args(argv)

    results = []
    for path in args.scenarios:
        scenario = load_scenario(path)
        big = scenario.fleet.size >= BIG_AGVS
        n_seeds = args.big_seeds if big and args.big_seeds > 0 else args.seeds
        cap = args.ticks if big else None
        runs = []
        for seed in range(n_seeds):
            print(f"{scenario.name} seed {seed} ({scenario.fleet.size} AGVs, "
                  f"cap {cap or scenario.max_ticks} ticks) ...", file=sys.stderr, flush=True)
            runs.append(bench_one(path, seed, cap))
        summary = summarise(runs)
        print_table(f"{scenario.name} ({path})", runs, summary)
        results.append({"scenario": scenario.name, "path": path, "summary": summary,
                        "runs": runs})

    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"machine": machine_info(), "results": results},
                                    indent=2) + "\n", encoding="utf-8")
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
