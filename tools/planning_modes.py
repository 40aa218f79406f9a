"""Plain vs rotation-aware vs duration-aware planning: the open-loop gap over many seeds.

For each scenario and each planning mode, the ideal grid run's plan is executed unchanged on
physics (``warerover gap``, open loop) over the same seeds, and the figures a sceptic asks
for are tabulated side by side:

- ``plain``: ``planner.rotations: false``, ``planner.timing: unit`` (one move per tick,
  turns free: the default);
- ``rotations``: ``planner.rotations: true`` (state = cell + heading; a quarter turn takes
  its ticks in place);
- ``motion``: ``planner.timing: motion`` (the same plan as ``plain``, its planned time
  reckoned by the motion model over the dependency graph);
- ``rotations+motion``: both.

Figures per mode (mean with its 95% CI over the seeds that ran in every mode): executed /
planned makespan (the gap; target with motion timing: <= 1.10), executed / planned makespan
of the orders, physics throughput (orders per executed second, the orders' makespan),
planned and executed makespan in seconds, lost time to turning per AGV, AGV-AGV contacts.
Seeds where a mode fails (e.g. a grid run whose plan has a rotation the dependency graph
cannot order) are listed and left out of every mode, so the modes compare the same seeds.

    .venv/bin/python tools/planning_modes.py layouts/paper_homogeneous.yaml \\
        layouts/paper_heterogeneous.yaml layouts/industrial.yaml --seeds 0..19 --workers 2

``--set KEY=VALUE`` overrides a scenario field in every mode (e.g. ``--set max_ticks=100``
on ``layouts/industrial.yaml``, whose 320 AGVs on physics take minutes a seed: the gap is
then that of the plan the ideal run made in its first 100 ticks, stated with the table).

``plain`` and ``motion`` execute the same plan (the grid run does not depend on the timing;
only the planned side of the figures differs), and so do ``rotations`` and
``rotations+motion``: when both of a pair are asked for, the plan is run once, with motion
timing, and the unit-timing mode's figures are its ``*_unit`` figures (``--run-all`` runs
each mode on its own, e.g. to check that).

Writes ``tools/out/planning_modes.json`` (every seed's figures) and prints a markdown table.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from warerover_phys.config import load_scenario  # noqa: E402
from warerover_phys.gap.open_loop import MOTION_UNIT_KEYS  # noqa: E402
from warerover_phys.gap.stats import parse_seeds, run_seeds  # noqa: E402
from warerover_phys.sweep.report import mean_ci  # noqa: E402

MODES = {
    "plain": [],
    "rotations": [("planner.rotations", True)],
    "motion": [("planner.timing", "motion")],
    "rotations+motion": [("planner.rotations", True), ("planner.timing", "motion")],
}

UNIT_TWIN = {"plain": "motion", "rotations": "rotations+motion"}
"""A unit-timing mode and the motion-timed mode that executes the same plan."""

FIGURES = (
    ("executed / planned makespan", "makespan_ratio", 3),
    ("executed / planned orders makespan", "orders_makespan_ratio", 3),
    ("physics throughput (orders / s)", "tp_phys", 4),
    ("planned makespan (s)", "planned_makespan_s", 1),
    ("planned makespan, unit timing (s)", "planned_makespan_unit_s", 1),
    ("executed / planned makespan, unit timing", "makespan_ratio_unit", 3),
    ("executed makespan (s)", "executed_makespan_s", 1),
    ("lost to turning per AGV (s)", "lost_turning_s_per_agv_mean", 1),
    ("AGV-AGV contacts", "agv_contacts", 2),
)


def _figures(report: dict) -> dict:
    out = {k: report.get(k) for _, k, _ in FIGURES if k != "tp_phys"}
    # Unit timing: the planned figures are the unit ones; motion timing keeps them as KEY_unit.
    out["planned_makespan_unit_s"] = report.get("planned_makespan_s_unit",
                                                report.get("planned_makespan_s"))
    out["makespan_ratio_unit"] = report.get("makespan_ratio_unit", report.get("makespan_ratio"))
    orders, span = report.get("orders"), report.get("executed_orders_makespan_s")
    out["tp_phys"] = orders / span if orders and span else None
    return out


def unit_report(report: dict) -> dict:
    """A motion-timed open-loop report as its unit-timing twin reports it: every figure that
    motion timing takes from the schedule back at its unit value (``KEY_unit``)."""
    if report.get("timing") != "motion":
        return report
    out = {k: v for k, v in report.items() if not k.endswith("_unit")}
    for k in MOTION_UNIT_KEYS:
        if f"{k}_unit" in report:
            out[k] = report[f"{k}_unit"]
    out["timing"] = "unit"
    return out


def plan_runs(modes: list[str], run_all: bool = False) -> dict[str, str]:
    """Each mode -> the mode whose run gives its figures: a unit-timing mode whose motion
    twin is also asked for is read off the twin's run (:data:`UNIT_TWIN`)."""
    return {m: (UNIT_TWIN[m] if not run_all and m in UNIT_TWIN and UNIT_TWIN[m] in modes
                else m) for m in modes}


def _cell(values: list[float], digits: int) -> str:
    vals = [v for v in values if v is not None and math.isfinite(v)]
    if not vals:
        return "-"
    mean, half = mean_ci(vals)
    half = 0.0 if math.isnan(half) else half
    return f"{mean:.{digits}f} ± {half:.{digits}f}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenarios", nargs="+")
    ap.add_argument("--seeds", default="0..19")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--modes", nargs="+", default=list(MODES), choices=list(MODES))
    ap.add_argument("--json", default="tools/out/planning_modes.json")
    ap.add_argument("--run-all", action="store_true",
                    help="run every mode on its own (default: a unit-timing mode whose "
                         "motion twin is asked for is read off the twin's run)")
    ap.add_argument("--set", dest="overrides", action="append", default=[],
                    metavar="KEY=VALUE",
                    help="override a scenario field in every mode (YAML value), e.g. "
                         "max_ticks=100: the ideal run stops there, and the gap is measured "
                         "over the plan it made by then")
    args = ap.parse_args(argv)
    extra = []
    for item in args.overrides:
        key, sep, value = item.partition("=")
        if not sep or not key:
            ap.error(f"--set: expected KEY=VALUE (got {item!r})")
        extra.append((key.strip(), yaml.safe_load(value)))
    seeds = parse_seeds(args.seeds)
    out = Path(args.json)
    rows: dict = {}
    lines = []
    for path in args.scenarios:
        per_mode: dict[str, dict[int, dict]] = {}
        failed: dict[str, list] = {}
        walls: dict[str, float] = {}
        source = plan_runs(args.modes, args.run_all)
        runs = [m for m in args.modes if source[m] == m]
        for mode in runs:
            sc = load_scenario(path, extra + MODES[mode])
            t0 = time.perf_counter()
            results, bad = run_seeds(sc, seeds, "open", args.workers)
            walls[mode] = time.perf_counter() - t0
            per_mode[mode] = {r["seed"]: _figures(r["report"]) for r in results}
            failed[mode] = bad
            for twin in (m for m in args.modes if source[m] == mode and m != mode):
                per_mode[twin] = {r["seed"]: _figures(unit_report(r["report"]))
                                  for r in results}
                failed[twin] = bad
            print(f"{sc.name} {mode}: {len(results)} seeds ({len(bad)} failed) in "
                  f"{walls[mode]:.0f} s", file=sys.stderr, flush=True)
            # every mode's figures on disk as soon as they exist (runs take long)
            partial = dict(rows, **{Path(path).stem: {"partial": True, "per_mode": per_mode,
                                                      "wall_s": walls, "source": source,
                                                      "overrides": args.overrides}})
            out.parent.mkdir(parents=True, exist_ok=True)
            out.write_text(json.dumps(partial, indent=1, default=str) + "\n",
                           encoding="utf-8")
        common = sorted(set.intersection(*(set(v) for v in per_mode.values())))
        name = Path(path).stem
        rows[name] = {"seeds": common, "per_mode": per_mode, "wall_s": walls, "source": source,
                      "overrides": args.overrides,
                      "failed": {m: [list(f) for f in v] for m, v in failed.items()}}
        left = sorted(set(seeds) - set(common))
        lines += [f"### {name}: {len(common)} seeds in every mode"
                  + (f" (left out: {left})" if left else "")
                  + (f", with {', '.join(args.overrides)}" if args.overrides else ""), "",
                  "| figure | " + " | ".join(args.modes) + " |",
                  "|---|" + "---|" * len(args.modes)]
        for label, key, digits in FIGURES:
            cells = [_cell([per_mode[m][s][key] for s in common], digits) for m in args.modes]
            lines.append(f"| {label} | " + " | ".join(cells) + " |")
        read = [f"{m} from {source[m]}'s run" for m in args.modes if source[m] != m]
        lines += ["", "wall: " + ", ".join(f"{m} {w:.0f} s" for m, w in walls.items())
                  + (f" ({'; '.join(read)})" if read else ""), ""]
    text = "\n".join(lines)
    print(text)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rows, indent=1, default=str) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
