"""A worker process for the fcl checker's fuzz test (``test_fcl_checker.py``): reads one
scene per line on stdin (JSON), answers one line on stdout. If python-fcl aborts, only this
process dies; the test sees the exit status.

A scene: ``{"half": [[hx, hy], ...], "corridors": [{"id", "rects", "margin"}, ...],
"poses": [[[x, y, heading], ...], ...], "skip": [...]}``. Every pose set is checked in
turn by one checker (so the later ones move only some boxes); the answer lists, per pose
set, ``[agv, corridor, depth]`` (JSON floats round-trip exactly).
"""

from __future__ import annotations

import json
import sys

import numpy as np
import shapely

from warerover_phys.faults.corridors import Corridor
from warerover_phys.faults.intrusion_fcl import FclIntrusionChecker


def corridor(spec: dict) -> Corridor:
    """A corridor with the given rectangles and margin (the checkers read nothing else)."""
    poly = shapely.box(*spec["rects"][0])
    return Corridor(id=spec["id"], agv=0, access=(0, 0), route=((0, 0),),
                    rects=tuple(tuple(r) for r in spec["rects"]), margin_m=spec["margin"],
                    polygon=poly, zone=poly, cells=frozenset())


def answer(scene: dict) -> list:
    chk = FclIntrusionChecker(np.array(scene["half"], dtype=float).reshape(-1, 2))
    chk.set_corridors([corridor(c) for c in scene["corridors"]])
    return [[[h.agv, h.corridor, h.depth_m]
             for h in chk.check(np.array(p, dtype=float).reshape(-1, 3), set(scene["skip"]))]
            for p in scene["poses"]]


def main() -> None:
    for line in sys.stdin:
        print(json.dumps(answer(json.loads(line))), flush=True)


if __name__ == "__main__":
    main()
