"""Golden outputs of the retired Robot Runners runner (``lorr.run_lifelong``, main e9c141c),
for the parity test of the one loop (``tests/problems/test_robotrunners_parity.py``).

The only change made to the old runner for these files: its PIBT tie-break generator is the
episode's planner child stream (``world.make_rngs(seed)["planner"]``, the house rule: one
root seed, child generators) instead of ``numpy.random.default_rng(seed)``. This script
runs only where ``warerover_phys.lorr`` still exists (main up to the commit that retired it):

    git checkout e9c141c -- warerover_phys/lorr.py   # in a scratch checkout
    .venv/bin/python tools/lorr_golden.py
"""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np

from warerover_phys import lorr
from warerover_phys.world import make_rngs

DATA = Path(__file__).resolve().parent.parent / "tests" / "data"
OUT = DATA / "lorr_golden"
CASES = {
    # name: (problem, ticks, seed, rotations, rule)
    "small50_actions": ("lorr2023_warehouse_small/warehouse_small_50.json", 200, 3, True, "actions"),
    "small50_turnfirst": ("lorr2023_warehouse_small/warehouse_small_50.json", 200, 3, True,
                          "turn-first"),
    "small50_norot": ("lorr2023_warehouse_small/warehouse_small_50.json", 200, 3, False, "actions"),
    "small50_greedy": ("lorr2023_warehouse_small/warehouse_small_50_greedy.json", 200, 1, True,
                       "actions"),
    "small400_actions": ("lorr2023_warehouse_small/warehouse_small_400.json", 100, 0, True,
                         "actions"),
    "fulfill200_actions": ("lorr2026_warehouse_fulfill/fulfill_200.json", 150, 0, True, "actions"),
    "fulfill200_norot": ("lorr2026_warehouse_fulfill/fulfill_200.json", 150, 2, False, "actions"),
}


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    real = np.random.default_rng
    for name, (prob, ticks, seed, rot, rule) in CASES.items():
        def child(s=None, _seed=seed):
            return make_rngs(_seed)["planner"] if s == _seed else real(s)
        np.random.default_rng = child
        try:
            result = lorr.run_lifelong(lorr.read_problem(DATA / prob), ticks, rotations=rot,
                                       seed=seed, rule=rule)
        finally:
            np.random.default_rng = real
        doc = lorr.output_json(result)
        doc.pop("plannerTimes")
        doc["case"] = {"problem": prob, "ticks": ticks, "seed": seed, "rotations": rot,
                       "rule": rule}
        with gzip.open(OUT / f"{name}.json.gz", "wt", encoding="utf-8") as f:
            json.dump(doc, f)
        print(name, result.finished)


if __name__ == "__main__":
    main()
