"""Scheduler call time at fleet scale: TA and RD as array code against the Python reference.

On ``layouts/industrial.yaml`` (1,680 shelves, 2,000 SKUs, 24 stations) with N AGVs, every
AGV idle and standing on a random floor cell, and P pending orders of random SKUs and
stations, it times ``assign`` of the shipped schedulers ("new") and of the reference copy
of the pre-array ones in ``tests/schedulers/reference_schedulers.py`` ("old"), checking they
give the same assignments. Each repetition draws new AGV cells and new orders on the same
world, so the distance tables stay cached as in an episode. The first call of a fresh world
(it fills the tables of the shelves it looks at) is reported apart as ``first_ms``, and the
filling of every other shelf's table (before the timed calls of the new code) as
``fill_rest_ms``; the reference fills its own caches as it goes (new AGV cells each call).

    .venv/bin/python tools/bench_scheduler.py
    .venv/bin/python tools/bench_scheduler.py --agvs 1000 --orders 200 400 --reps 30 \\
        --json /tmp/bench_scheduler.json

Prints a table (wall and thread CPU ms per call, mean and p99: on a loaded machine the CPU
figure is the nearer to a quiet machine's wall clock) and writes JSON with the load average.
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

ROOT = Path(__file__).resolve().parent.parent
if not os.environ.get("PYTHONPATH"):  # PYTHONPATH picks the checkout to measure
    sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "schedulers"))

from reference_schedulers import ReferenceRD, ReferenceTA  # noqa: E402

from warerover_phys import load_scenario  # noqa: E402
from warerover_phys.layout import CellType  # noqa: E402
from warerover_phys.orders import Order  # noqa: E402
from warerover_phys.schedulers import RandomDispatch, TaskAssignment  # noqa: E402
from warerover_phys.schedulers.base import SchedulerView  # noqa: E402
from warerover_phys.world import World  # noqa: E402

IMPLS = {"ta": {"new": TaskAssignment, "old": ReferenceTA},
         "rd": {"new": RandomDispatch, "old": ReferenceRD}}


def build(layout: Path, agvs: int) -> World:
    return World.build(load_scenario(layout, [("fleet.agvs.0.count", agvs)]))


def new_state(w: World, orders: int, rng: np.random.Generator) -> None:
    """Every AGV idle on its own random floor cell; ``orders`` new pending orders."""
    free = np.flatnonzero(w.graphs.get(1, False).valid.ravel()
                          & (w.layout.grid.ravel() != CellType.SHELF))
    cells = rng.choice(free, size=len(w.agvs), replace=False)
    for agv, node in zip(w.agvs, cells.tolist(), strict=True):
        agv.pos = (node, node)
    w.orders.clear()
    w.status.clear()
    w._pending.clear()
    w._open = 0
    skus = np.array(sorted(w.layout.sku_shelves))
    w.add_orders([Order(i, 0, int(rng.choice(skus)), int(rng.integers(len(w.layout.stations))),
                        1) for i in range(orders)])
    w.events.clear()


def time_calls(sched, w: World, states: list[int], orders: int, seed: int) -> tuple:
    """ms per call over the states (one per seed in ``states``) and the assignments."""
    ms, cpu, outs = [], [], []
    for s in states:
        new_state(w, orders, np.random.default_rng(s))
        rng = np.random.default_rng(seed + s)
        t0, c0 = time.perf_counter(), time.thread_time()
        out = sched.assign(SchedulerView(w), rng)
        ms.append((time.perf_counter() - t0) * 1e3)
        cpu.append((time.thread_time() - c0) * 1e3)
        outs.append((out, rng.bit_generator.state))
    return ms, cpu, outs


def run_case(layout: Path, agvs: int, orders: int, name: str, reps: int, old_reps: int,
             seed: int) -> list[dict]:
    w = build(layout, agvs)
    spec = w.scenario.scheduler.model_copy(update={"name": name})
    new, old = IMPLS[name]["new"](spec), IMPLS[name]["old"](spec)
    first, _, _ = time_calls(new, w, [seed], orders, seed)
    t0 = time.perf_counter()  # the tables of the shelves the first call did not look at
    for k in sorted({a.k for a in w.agvs}):
        w.trip_costs().to_shelves(k, np.array([w.agvs[0].node]),
                                  np.arange(len(w.layout.shelves)))
    fill_ms = (time.perf_counter() - t0) * 1e3
    new_ms, new_cpu, new_out = time_calls(new, w, list(range(seed + 1, seed + 1 + reps)),
                                          orders, seed)
    rows = [_row("new", name, agvs, orders, w, new_ms, new_cpu, first[0], new_out)]
    rows[0]["fill_rest_ms"] = fill_ms
    if old_reps:
        w_old = build(layout, agvs)  # its own caches, filled as the old code fills them
        old_first, _, _ = time_calls(old, w_old, [seed], orders, seed)
        states = list(range(seed + 1, seed + 1 + old_reps))
        old_ms, old_cpu, old_out = time_calls(old, w_old, states, orders, seed)
        same = old_out == new_out[:old_reps]
        rows.append(_row("old", name, agvs, orders, w_old, old_ms, old_cpu, old_first[0],
                         old_out))
        rows[0]["same_as_old"] = rows[1]["same_as_old"] = same
    return rows


def _row(impl, name, agvs, orders, w, ms, cpu, first, outs) -> dict:
    arr = np.array(ms)
    return {"scheduler": name, "impl": impl, "agvs": agvs, "pending_orders": orders,
            "skus": len({o.sku for o in w.orders.values()}), "shelves": len(w.layout.shelves),
            "reps": len(ms), "mean_ms": float(arr.mean()), "p99_ms": float(np.percentile(arr, 99)),
            "max_ms": float(arr.max()), "cpu_mean_ms": float(np.mean(cpu)),
            "cpu_p99_ms": float(np.percentile(cpu, 99)), "first_ms": first,
            "assigned_mean": float(np.mean([len(o) for o, _ in outs])), "same_as_old": None}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", type=Path, default=ROOT / "layouts" / "industrial.yaml")
    ap.add_argument("--agvs", type=int, nargs="+", default=[100, 1000, 5000])
    ap.add_argument("--orders", type=int, nargs="+", default=[200])
    ap.add_argument("--schedulers", nargs="+", default=["ta", "rd"], choices=sorted(IMPLS))
    ap.add_argument("--reps", type=int, default=20, help="timed calls of the new code")
    ap.add_argument("--old-reps", type=int, default=2,
                    help="timed calls of the reference (about 5 s each at 1,000 AGVs)")
    ap.add_argument("--old-max-agvs", type=int, default=1000,
                    help="time the reference only up to this many AGVs")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    rows = []
    print(f"{'sched':5} {'impl':4} {'AGVs':>5} {'orders':>6} {'SKUs':>5} {'mean ms':>9} "
          f"{'p99 ms':>9} {'cpu mean':>9} {'cpu p99':>9} {'first ms':>9} {'fill ms':>8} "
          f"{'assigned':>8} same")
    for n in args.agvs:
        for p in args.orders:
            for name in args.schedulers:
                old_reps = args.old_reps if n <= args.old_max_agvs else 0
                for r in run_case(args.layout, n, p, name, args.reps, old_reps, args.seed):
                    rows.append(r)
                    print(f"{r['scheduler']:5} {r['impl']:4} {r['agvs']:5d} "
                          f"{r['pending_orders']:6d} {r['skus']:5d} {r['mean_ms']:9.2f} "
                          f"{r['p99_ms']:9.2f} {r['cpu_mean_ms']:9.2f} {r['cpu_p99_ms']:9.2f} "
                          f"{r['first_ms']:9.1f} {r.get('fill_rest_ms', 0):8.1f} "
                          f"{r['assigned_mean']:8.1f} "
                          f"{r['same_as_old']}", flush=True)
    bad = [r for r in rows if r["same_as_old"] is False]
    doc = {"rows": rows, "load_average": os.getloadavg(), "machine": platform.machine(),
           "cpus": os.cpu_count(), "python": platform.python_version(),
           "layout": str(args.layout), "reps": args.reps, "seed": args.seed}
    print(f"load average {doc['load_average'][0]:.2f} {doc['load_average'][1]:.2f} "
          f"{doc['load_average'][2]:.2f}")
    if args.json:
        args.json.write_text(json.dumps(doc, indent=1))
    if bad:
        print(f"{len(bad)} rows differ from the reference", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
