"""Time reading and writing a plan of AGENTS x STEPS in every plan format.

    python tools/bench_plans.py [AGENTS] [STEPS]      (default 1000 x 1000)

Prints, per format, the file size and the best of three write / read times in seconds.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from warerover_phys.plans import FORMATS, Plan, format_plan, parse_plan
from warerover_phys.plans.model import HEADING_STEPS


def random_plan(agents: int, steps: int, seed: int = 0) -> Plan:
    """Random actions F / R / C / W from random starts: cells and headings (valid in every
    format, Robot Runners included)."""
    rng = np.random.default_rng(seed)
    paths, headings = [], []
    for _ in range(agents):
        r, c, h = int(rng.integers(500, 600)), int(rng.integers(500, 600)), int(rng.integers(4))
        cells, heads = [(r, c)], [h]
        for a in rng.integers(0, 4, steps - 1):
            if a == 1:
                r, c = r + HEADING_STEPS[h][0], c + HEADING_STEPS[h][1]
            elif a == 2:
                h = (h + 1) % 4
            elif a == 3:
                h = (h + 3) % 4
            cells.append((r, c))
            heads.append(h)
        paths.append(tuple(cells))
        headings.append(tuple(heads))
    return Plan(paths=tuple(paths), headings=tuple(headings))


def best(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    agents = int(sys.argv[1]) if len(sys.argv) > 1 else 1000
    steps = int(sys.argv[2]) if len(sys.argv) > 2 else 1000
    plan = random_plan(agents, steps)
    cells_only = Plan(paths=plan.paths)
    print(f"{agents} agents x {steps} timesteps")
    print(f"{'format':>13} {'MB':>7} {'write s':>8} {'read s':>8}")
    for fmt in FORMATS:
        text = format_plan(plan, fmt)
        write_s = best(lambda fmt=fmt: format_plan(plan, fmt))
        read_s = best(lambda fmt=fmt, text=text: parse_plan(text, fmt))
        back = parse_plan(text, fmt)
        assert back.paths == (plan if back.headings else cells_only).paths, fmt
        print(f"{fmt:>13} {len(text) / 1e6:7.1f} {write_s:8.3f} {read_s:8.3f}")


if __name__ == "__main__":
    main()
