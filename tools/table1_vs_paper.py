"""Our Table 1 next to the paper's, row by row, from a `warerover sweep` of
`tools/reproduce_table1.yaml`.

The paper's Table 1 is one-shot orders (OS); its third planner is DHC (learned), in whose
place we run PIBT. The paper gives CT without a unit; we show ours in ms per tick and in
seconds per episode (scheduler + planner wall time). Cells: mean ± 95% CI half-width.

    .venv/bin/python tools/table1_vs_paper.py runs/table1 [--pattern oneshot]
        [--out tools/out/table1_vs_paper.md]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from warerover_phys.sweep.report import aggregate, load_rows

# (env, scheduler, paper planner) -> (SR %, CT, TP), from the paper's Table 1.
PAPER = {
    ("Ho", "rd", "astar"): (100.0, 0.53, 0.21), ("Ho", "rd", "cbs"): (100.0, 0.55, 0.22),
    ("Ho", "rd", "dhc"): (99.9, 7.70, 0.21), ("Ho", "ta", "astar"): (100.0, 0.34, 0.34),
    ("Ho", "ta", "cbs"): (100.0, 0.31, 0.36), ("Ho", "ta", "dhc"): (100.0, 4.87, 0.33),
    ("He", "ta", "astar"): (100.0, 0.19, 0.42), ("He", "ta", "cbs"): (98.8, 0.40, 0.45),
    ("He", "ta", "dhc"): (72.9, 9.52, 0.10), ("FT", "ta", "astar"): (100.0, 1.45, 0.25),
    ("FT", "ta", "cbs"): (99.9, 14.15, 0.26), ("FT", "ta", "dhc"): (98.9, 7.93, 0.20),
}
STANDS_IN = {"pibt": "dhc"}
"""Our planner -> the paper's planner it is compared with."""
LABEL = {"astar": "A*", "cbs": "CBS", "pibt": "PIBT", "dhc": "DHC", "ta": "TA", "rd": "RD"}


def cell(stat: tuple[float, float], decimals: int) -> str:
    mean, half = stat
    if math.isnan(mean):
        return "-"
    return f"{mean:.{decimals}f}" + ("" if math.isnan(half) else f" ± {half:.{decimals}f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweep_dir", type=Path)
    ap.add_argument("--pattern", default="oneshot")
    ap.add_argument("--out", type=Path, default=Path("tools/out/table1_vs_paper.md"))
    args = ap.parse_args()
    rows, spec, _ = load_rows(args.sweep_dir)
    groups = [g for g in aggregate(rows, spec) if g.pattern == args.pattern and not g.variant]
    head = ("| Env. | Method (ours / paper) | n | SR % ours | SR % paper | TP ours | TP paper "
            "| CT ours (ms/tick) | CT ours (s/episode) | CT paper (no unit) |")
    lines = [f"# Table 1, ours vs the paper ({args.pattern} orders)", "",
             f"From `{args.sweep_dir}` ({len(rows)} episodes). Ours: mean ± 95% CI "
             "half-width over the repetitions, grid executor. The paper's DHC rows are "
             "compared with our PIBT; rows the paper does not have show '-'.", "",
             head, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for g in groups:
        theirs = STANDS_IN.get(g.planner, g.planner)
        paper = PAPER.get((g.env, g.scheduler, theirs))
        method = f"{LABEL.get(g.scheduler, g.scheduler)} + {LABEL.get(g.planner, g.planner)}"
        if theirs != g.planner:
            method += f" / {LABEL.get(theirs, theirs)}"
        psr, pct, ptp = (f"{paper[0]:.1f}", f"{paper[1]:.2f}", f"{paper[2]:.2f}") if paper \
            else ("-", "-", "-")
        lines.append(f"| {g.env} | {method} | {g.n} | {cell(g.stats['sr_pct'], 1)} | {psr} | "
                     f"{cell(g.stats['tp'], 3)} | {ptp} | {cell(g.stats['ct_ms'], 2)} | "
                     f"{cell(g.stats['ct_total_s'], 3)} | {pct} |")
    text = "\n".join(lines) + "\n"
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
