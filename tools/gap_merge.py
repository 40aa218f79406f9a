"""Merge the folders of several ``warerover gap --seeds`` runs (chunks of one seed range,
run one after another or on other machines) into one set of statistics.

    PYTHONPATH=. python tools/gap_merge.py runs/chunks/c42-46 runs/chunks/c47-51 ... \\
        --out runs/basic-42-141 [--json]

Each folder's ``seeds.csv`` (one row per seed, every scalar figure at full precision) is
read back; the folders must be of one scenario, scheduler, planner and mode, with no seed
twice. Written as one set into ``--out``: ``summary.json`` (as ``gap --seeds`` writes it:
mean, median, p95, min, max, std and the 95% Student-t CI of the mean of every figure, the
seeds, the failed seeds of every folder) and ``seeds.csv``; ``agents.csv`` is the folders'
concatenated when every one has it. Prints the headline figures (mean [95% CI] / median /
p95 / max) as a markdown table.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from warerover_phys.gap.stats import _csv, _finite, summarise  # noqa: E402

HEADLINE = ("makespan_ratio", "sum_of_costs_ratio", "orders_makespan_ratio", "tp_ratio",
            "latency_ratio", "lost_s_per_agv_mean", "lost_dependency_s_per_agv_mean",
            "lost_accel_decel_s_per_agv_mean", "lost_turning_s_per_agv_mean",
            "lost_control_s_per_agv_mean", "lost_faster_than_plan_s_per_agv_mean",
            "lost_plan_waits_skipped_s_per_agv_mean", "cycle_repairs", "agv_contacts",
            "static_contacts", "min_clearance_m", "deadlocks")


def _value(text: str):
    """A ``seeds.csv`` cell back as int, float, bool, None or text."""
    if text == "":
        return None
    if text in ("True", "False"):
        return text == "True"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def _rows(path: Path) -> list[dict]:
    with path.open(newline="", encoding="utf-8") as f:
        return [{k: _value(v) for k, v in r.items()} for r in csv.DictReader(f)]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--json", action="store_true", help="print the statistics as JSON")
    args = ap.parse_args(argv)
    header: dict | None = None
    seeds: list[dict] = []
    agents: list[dict] | None = []
    failed: list = []
    for d in args.folders:
        summ = json.loads((d / "summary.json").read_text(encoding="utf-8"))
        head = {k: summ.get(k) for k in ("mode", "scenario", "scheduler", "planner")}
        if header is None:
            header = {**head, "source": summ.get("source")}
        elif head != {k: header[k] for k in head}:
            raise SystemExit(f"{d}: {head} differs from {header}")
        seeds += _rows(d / "seeds.csv")
        failed += summ.get("failed", [])
        if agents is not None and (d / "agents.csv").is_file():
            agents += _rows(d / "agents.csv")
        else:
            agents = None
    got = [r["seed"] for r in seeds]
    if len(set(got)) != len(got):
        raise SystemExit(f"seeds given twice: {sorted({s for s in got if got.count(s) > 1})}")
    seeds.sort(key=lambda r: r["seed"])
    results = [{"seed": r["seed"], "report": r} for r in seeds]
    stats = summarise(results)
    summary = {**header, "seeds": [r["seed"] for r in seeds], "failed": failed,
               "merged_from": [str(d) for d in args.folders], "statistics": stats,
               "statistics_note": "over seeds: mean, median, p95 (95th percentile), min, max, "
                                  "std (n - 1), ci95_low / ci95_high: 95% Student-t "
                                  "confidence interval of the mean"}
    from warerover_phys.util.atomic import write_set

    writers = {"summary.json": lambda p: p.write_text(
        json.dumps(_finite(summary), indent=2, sort_keys=True) + "\n", encoding="utf-8"),
        "seeds.csv": lambda p: p.write_text(_csv(seeds), encoding="utf-8")}
    if agents:
        writers["agents.csv"] = lambda p: p.write_text(_csv(agents), encoding="utf-8")
    write_set(args.out, writers, meta={"mode": header["mode"], "scenario": header["scenario"]})
    if args.json:
        print(json.dumps(_finite(summary), indent=2, sort_keys=True))
        return 0
    print(f"{header['mode']} gap: {header['scenario']} ({header['scheduler']} + "
          f"{header['planner']}), {len(seeds)} seeds {seeds[0]['seed']}..{seeds[-1]['seed']}"
          f", {len(failed)} failed\n")
    print("| figure | mean [95% CI] | median | p95 | max |\n|---|---|---|---|---|")
    for k in HEADLINE:
        s = stats.get(k)
        if not s or not s["n"]:
            continue
        print(f"| {k} | {s['mean']:.3f} [{s['ci95_low']:.3f}, {s['ci95_high']:.3f}] | "
              f"{s['median']:.3f} | {s['p95']:.3f} | {s['max']:.3f} |")
    print(f"\nwrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
