"""Benchmark the corridor intrusion checker: 1000 random AGVs against 3 open corridors.

Builds a 100 x 100 m floor (1 m cells, a few shelf blocks, access points on the border),
opens three corridors from random cells (1.0 m wide, 0.3 m margin) and times
:meth:`IntrusionChecker.check` in two cases:

- ``moving``: fresh random poses on every call (worst case for the broad phase);
- ``static``: the same poses again.

Also times the shapely reference :func:`intrusions_shapely` and checks both agree.

    .venv/bin/python tools/bench_intrusion.py
    .venv/bin/python tools/bench_intrusion.py --agvs 3000 --calls 100

Prints the figures and writes ``tools/out/bench_intrusion.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from warerover_phys.config import LayoutSpec
from warerover_phys.faults import IntrusionChecker, intrusions_shapely, plan_corridor
from warerover_phys.layout import build_layout


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agvs", type=int, default=1000)
    ap.add_argument("--corridors", type=int, default=3)
    ap.add_argument("--calls", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    side = 100
    layout = build_layout(LayoutSpec(
        size=(side, side),
        shelf_blocks=[{"origin": (r, c), "rows": 2, "cols": 10}
                      for r in range(10, 90, 8) for c in range(10, 90, 14)],
        stations=[(side - 1, 50)], access_points=[(0, 25), (0, 75), (50, 0), (50, side - 1)]))
    rng = np.random.default_rng(args.seed)
    free = np.flatnonzero(~(layout.obstacles | layout.shelf_mask).ravel())
    corridors = [plan_corridor(layout, k, agv=k, footprint_cells=[int(rng.choice(free))],
                               width_m=1.0, margin_m=0.3) for k in range(args.corridors)]
    half = np.tile([0.45, 0.35], (args.agvs, 1))

    def random_poses() -> np.ndarray:
        return np.column_stack([rng.uniform(0, side, (args.agvs, 2)),
                                rng.uniform(-np.pi, np.pi, args.agvs)])

    checker = IntrusionChecker(half)
    checker.set_corridors(corridors)
    batches = [random_poses() for _ in range(args.calls)]
    checker.check(batches[0])  # warm up
    t0 = time.perf_counter()
    found = [checker.check(p) for p in batches]
    moving = (time.perf_counter() - t0) / args.calls
    t0 = time.perf_counter()
    for _ in range(args.calls):
        checker.check(batches[-1])
    static = (time.perf_counter() - t0) / args.calls
    n_ref = min(20, args.calls)
    t0 = time.perf_counter()
    ref = [intrusions_shapely(p, half, corridors) for p in batches[:n_ref]]
    shapely_s = (time.perf_counter() - t0) / n_ref
    agree = all(
        [(i.agv, i.corridor) for i in a] == [(i.agv, i.corridor) for i in b]
        and all(abs(x.depth_m - y.depth_m) < 1e-9 for x, y in zip(a, b, strict=True))
        for a, b in zip(found[:n_ref], ref, strict=True))

    out = {
        "agvs": args.agvs, "corridors": args.corridors,
        "rects": sum(len(c.rects) for c in corridors), "calls": args.calls,
        "check_ms_moving": moving * 1e3, "check_ms_static": static * 1e3,
        "shapely_ref_ms": shapely_s * 1e3,
        "mean_intrusions": float(np.mean([len(f) for f in found])),
        "agrees_with_shapely": agree,
        "python": platform.python_version(), "cpus": os.cpu_count(),
    }
    print(f"{args.agvs} AGVs vs {args.corridors} corridors ({out['rects']} rectangles): "
          f"check {out['check_ms_moving']:.2f} ms (all moved), "
          f"{out['check_ms_static']:.2f} ms (none moved); shapely reference "
          f"{out['shapely_ref_ms']:.2f} ms; {out['mean_intrusions']:.1f} intrusions per call; "
          f"agrees: {agree}")
    path = Path(__file__).resolve().parent / "out" / "bench_intrusion.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
