"""Benchmark the corridor intrusion checkers (``faults.checker``): numpy against python-fcl.

Builds a 100 x 100 m floor (1 m cells, shelf blocks, access points on the border), opens
``--corridors`` corridors (default 50) from random free cells (1.0 m wide, 0.3 m margin) and
times :meth:`IntrusionChecker.check` of both checkers for each fleet size in ``--agvs``
(default 100, 1,000 and 5,000 AGVs, 0.9 x 0.7 m bodies) with two placements:

- ``uniform``: bodies anywhere on the floor (dense near the corridors: a worst case, many
  candidate pairs);
- ``outside``: bodies centred (+-0.3 m) on free cells no open corridor covers, as the
  planner keeps them (few candidates);

and three motions: ``moving`` (fresh random poses on every call: every fcl box moves),
``tenth`` (a tenth of the bodies get fresh poses on each call, as in a fleet where most
stand parked) and ``static`` (the same poses again: nothing to move), over ``--calls``
calls each.
Figures are medians of CPU time (``time.process_time``: fair on a loaded machine) and of
wall time. Both checkers must give identical answers on every call (``identical``); the first calls
are also checked against the shapely reference :func:`intrusions_shapely` (same pairs,
depths within 1e-9 m). Prints a table with the load average and writes
``tools/out/bench_intrusion.json``.

    .venv/bin/python tools/bench_intrusion.py
    .venv/bin/python tools/bench_intrusion.py --agvs 1000 --corridors 50 --calls 200
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import fcl
import numpy as np

from warerover_phys.config import LayoutSpec
from warerover_phys.faults import intrusions_shapely, make_checker, plan_corridor
from warerover_phys.layout import Layout, build_layout

SIDE = 100
HALF = (0.45, 0.35)
SHAPELY_CALLS = 3


def floor() -> Layout:
    return build_layout(LayoutSpec(
        size=(SIDE, SIDE),
        shelf_blocks=[{"origin": (r, c), "rows": 2, "cols": 10}
                      for r in range(10, 90, 8) for c in range(10, 90, 14)],
        stations=[(SIDE - 1, 50)],
        access_points=[(0, 25), (0, 75), (50, 0), (50, SIDE - 1)]))


def poses_for(rng: np.random.Generator, n: int, placement: str, cells: np.ndarray,
              cols: int) -> np.ndarray:
    """``n`` random poses: anywhere (``uniform``) or around the given free cells."""
    heading = rng.uniform(-np.pi, np.pi, n)
    if placement == "uniform":
        return np.column_stack([rng.uniform(0, SIDE, (n, 2)), heading])
    cell = rng.choice(cells, n)
    r, c = np.divmod(cell, cols)
    jitter = rng.uniform(-0.3, 0.3, (n, 2))
    return np.column_stack([c + 0.5 + jitter[:, 0], r + 0.5 + jitter[:, 1], heading])


def time_calls(checker, batches: list[np.ndarray]) -> tuple[list, float, float]:
    """The answers, and the median wall and CPU ms of a call."""
    out, wall, cpu = [], [], []
    for p in batches:
        t0, c0 = time.perf_counter(), time.process_time()
        out.append(checker.check(p))
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - t0)
    return out, float(np.median(wall) * 1e3), float(np.median(cpu) * 1e3)


def bench_row(n: int, placement: str, corridors: list, free_cells: np.ndarray,
              cols: int, calls: int, seed: int) -> dict:
    """Both checkers on one fleet size and placement, moving and static."""
    rng = np.random.default_rng(seed)
    half = np.tile(HALF, (n, 1))
    batches = [poses_for(rng, n, placement, free_cells, cols) for _ in range(calls)]
    tenth = [batches[-1]]
    for _ in range(calls - 1):
        p = tenth[-1].copy()
        who = rng.choice(n, max(1, n // 10), replace=False)
        p[who] = poses_for(rng, len(who), placement, free_cells, cols)
        tenth.append(p)
    row: dict = {"agvs": n, "placement": placement}
    answers = {}
    for kind in ("numpy", "fcl"):
        chk = make_checker(kind, half)
        chk.set_corridors(corridors)
        chk.check(batches[0])  # warm up
        moving, row[f"{kind}_moving_ms"], row[f"{kind}_moving_cpu_ms"] = time_calls(
            chk, batches)
        part, row[f"{kind}_tenth_ms"], row[f"{kind}_tenth_cpu_ms"] = time_calls(chk, tenth)
        static, row[f"{kind}_static_ms"], row[f"{kind}_static_cpu_ms"] = time_calls(
            chk, [batches[-1]] * calls)
        answers[kind] = moving + part + static
        if kind == "fcl":
            row["fcl_pairs_per_call"] = chk.fcl_pairs / (3 * calls + 1)
    row["identical"] = answers["numpy"] == answers["fcl"]
    row["intrusions_per_call"] = float(np.mean([len(a) for a in answers["numpy"][:calls]]))
    ref = [intrusions_shapely(p, half, corridors) for p in batches[:SHAPELY_CALLS]]
    row["agrees_with_shapely"] = all(
        [(i.agv, i.corridor) for i in a] == [(i.agv, i.corridor) for i in b]
        and all(abs(x.depth_m - y.depth_m) < 1e-9 for x, y in zip(a, b, strict=True))
        for a, b in zip(answers["fcl"][:SHAPELY_CALLS], ref, strict=True))
    row["fcl_vs_numpy_moving_cpu"] = row["fcl_moving_cpu_ms"] / row["numpy_moving_cpu_ms"]
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agvs", type=int, nargs="+", default=[100, 1000, 5000])
    ap.add_argument("--corridors", type=int, default=50)
    ap.add_argument("--placements", nargs="+", default=["uniform", "outside"],
                    choices=["uniform", "outside"])
    ap.add_argument("--calls", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "out"
                                         / "bench_intrusion.json"))
    args = ap.parse_args()

    layout = floor()
    rng = np.random.default_rng(args.seed)
    free = np.flatnonzero(~(layout.obstacles | layout.shelf_mask).ravel())
    corridors = [plan_corridor(layout, k, agv=k, footprint_cells=[int(rng.choice(free))],
                               width_m=1.0, margin_m=0.3) for k in range(args.corridors)]
    covered = set().union(*(c.cells for c in corridors)) if corridors else set()
    outside = np.array([c for c in free.tolist() if c not in covered])
    load_before = os.getloadavg()
    rows = [bench_row(n, placement, corridors, outside, layout.cols, args.calls, args.seed)
            for n in args.agvs for placement in args.placements]
    load_after = os.getloadavg()
    rects = sum(len(c.rects) for c in corridors)
    print(f"{args.corridors} corridors ({rects} rectangles), {args.calls} calls per figure, "
          f"median CPU ms per check (wall ms in brackets); load average "
          f"{load_before[0]:.2f} before, {load_after[0]:.2f} after")
    print(f"{'AGVs':>5} {'placement':<9} {'numpy moving':>15} {'fcl moving':>15} {'fcl/np':>6} "
          f"{'numpy tenth':>11} {'fcl tenth':>9} {'numpy static':>12} {'fcl static':>10} "
          f"{'pairs':>6} {'intr.':>6} {'same':>5} {'shapely':>7}")
    for r in rows:
        print(f"{r['agvs']:>5} {r['placement']:<9} "
              f"{r['numpy_moving_cpu_ms']:>6.2f} ({r['numpy_moving_ms']:>6.2f}) "
              f"{r['fcl_moving_cpu_ms']:>6.2f} ({r['fcl_moving_ms']:>6.2f}) "
              f"{r['fcl_vs_numpy_moving_cpu']:>6.2f} "
              f"{r['numpy_tenth_cpu_ms']:>11.2f} {r['fcl_tenth_cpu_ms']:>9.2f} "
              f"{r['numpy_static_cpu_ms']:>12.2f} {r['fcl_static_cpu_ms']:>10.2f} "
              f"{r['fcl_pairs_per_call']:>6.0f} {r['intrusions_per_call']:>6.1f} "
              f"{str(r['identical']):>5} {str(r['agrees_with_shapely']):>7}")
    out = {"corridors": args.corridors, "rects": rects, "calls": args.calls,
           "seed": args.seed, "rows": rows, "load_before": load_before,
           "load_after": load_after, "python": platform.python_version(),
           "numpy": np.__version__, "fcl": getattr(fcl, "__version__", None),
           "cpus": os.cpu_count()}
    path = Path(args.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
