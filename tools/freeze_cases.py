"""Freeze cases of issue 13 (fault 3) on the physics executor: success rate, deadlocks,
freezes and the failure causes, per case, over a few seeds.

Three cases that ended in failed episodes with no deadlock counted:

- ``mixed4x_lacam``: paper_heterogeneous with four times the AGVs (24 small, 12 large;
  parking along the top and bottom rows), LaCAM;
- ``slow_turn_cbs``: paper_homogeneous with turn rate 0.3 rad/s and acceleration
  0.2 m/s^2, CBS;
- ``dense30_pibt``: paper_homogeneous with 30 AGVs (two parking rows), PIBT.

Run it on the code to measure (``PYTHONPATH`` picks the checkout); ``--label`` names the
JSON it writes (``tools/data/freeze_cases_<label>.json``); ``--compare A B`` prints two
saved runs side by side::

    PYTHONPATH=/path/to/old python tools/freeze_cases.py --label before --seeds 6
    PYTHONPATH=$PWD python tools/freeze_cases.py --label after --seeds 6
    python tools/freeze_cases.py --compare before after
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tools" / "data"

CASES = {
    "mixed4x_lacam": ("paper_heterogeneous.yaml", [
        ("planner.name", "lacam"), ("fleet.agvs.0.count", 24), ("fleet.agvs.1.count", 12),
        ("layout.parking", [{"origin": [0, 1], "rows": 2, "cols": 18},
                            {"origin": [13, 1], "rows": 2, "cols": 18}])]),
    "slow_turn_cbs": ("paper_homogeneous.yaml", [
        ("planner.name", "cbs"), ("fleet.types.agv.max_turn_rate_radps", 0.3),
        ("fleet.types.agv.max_accel_mps2", 0.2)]),
    "dense30_pibt": ("paper_homogeneous.yaml", [
        ("planner.name", "pibt"), ("fleet.agvs.0.count", 30),
        ("layout.parking", [{"origin": [13, 3], "rows": 2, "cols": 15}])]),
}


def run(label: str, seeds: int, max_ticks: int, cases: list[str] | None = None) -> dict:
    from warerover_phys import load_scenario, run_episode

    out: dict = {"label": label, "seeds": seeds, "max_ticks": max_ticks, "cases": {}}
    for case, (layout, sets) in CASES.items():
        if cases and case not in cases:
            continue
        overrides = [("executor.name", "physics"), ("max_ticks", max_ticks), *sets]
        scenario = load_scenario(ROOT / "layouts" / layout, overrides)
        rows = []
        for seed in range(seeds):
            t0 = time.perf_counter()
            m = run_episode(scenario, seed=seed).metrics
            rows.append({"seed": seed, "success_rate": m["success_rate"], "ticks": m["ticks"],
                         "deadlocks": m.get("deadlocks", 0), "freezes": m.get("freezes"),
                         "failure_cause": m.get("failure_cause"),
                         "failure_detail": m.get("failure_detail"),
                         "wall_s": round(time.perf_counter() - t0, 1)})
            print(f"{case} seed {seed}: SR {m['success_rate']:.2f} ticks {m['ticks']} "
                  f"deadlocks {rows[-1]['deadlocks']} freezes {rows[-1]['freezes']} "
                  f"cause {rows[-1]['failure_cause']}", flush=True)
        out["cases"][case] = rows
    return out


def summarise(data: dict) -> dict[str, dict]:
    table = {}
    for case, rows in data["cases"].items():
        failed = [r for r in rows if r["success_rate"] < 1.0]
        causes = Counter(r["failure_cause"] or "none reported" for r in failed)
        table[case] = {
            "episodes": len(rows),
            "sr_mean": sum(r["success_rate"] for r in rows) / len(rows),
            "failed": len(failed),
            "failed_without_cause": causes.get("none reported", 0),
            "causes": dict(causes),
            "deadlocks": sum(r["deadlocks"] or 0 for r in rows),
            "freezes": sum(r["freezes"] or 0 for r in rows) if rows[0]["freezes"] is not None
            else None,
            "ticks_mean": sum(r["ticks"] for r in rows) / len(rows),
        }
    return table


def print_table(labels: list[str], tables: list[dict]) -> None:
    head = f"| case | {' | '.join(f'{lb}: SR mean, failed (no cause), deadlocks, freezes, ticks mean' for lb in labels)} |"
    print(head)
    print("|" + "---|" * (len(labels) + 1))
    for case in CASES:
        cells = []
        for t in tables:
            s = t.get(case)
            if s is None:
                cells.append("-")
                continue
            fz = "-" if s["freezes"] is None else s["freezes"]
            cells.append(f"{s['sr_mean']:.3f}, {s['failed']}/{s['episodes']} "
                         f"({s['failed_without_cause']}), {s['deadlocks']}, {fz}, "
                         f"{s['ticks_mean']:.0f}")
        print(f"| {case} | {' | '.join(cells)} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--label", default="now")
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--max-ticks", type=int, default=600)
    ap.add_argument("--compare", nargs="+", metavar="LABEL")
    ap.add_argument("--cases", nargs="+", choices=list(CASES),
                    help="only these cases (default: all)")
    args = ap.parse_args()
    if args.compare:
        datas = [json.loads((DATA / f"freeze_cases_{lb}.json").read_text())
                 for lb in args.compare]
        print_table(args.compare, [summarise(d) for d in datas])
        return
    data = run(args.label, args.seeds, args.max_ticks, args.cases)
    data["summary"] = summarise(data)
    DATA.mkdir(parents=True, exist_ok=True)
    path = DATA / f"freeze_cases_{args.label}.json"
    path.write_text(json.dumps(data, indent=1) + "\n")
    print_table([args.label], [data["summary"]])
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
