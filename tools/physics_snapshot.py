"""Everything the physics executor produces, for a few cases, to compare before / after a
change that must not change results (issue 12's speed-ups).

Per case it keeps the metrics (timing keys left out), the events, the executed states, the
recorded trajectories (every array) and the cause log (every array and the blockers), and
compares them exactly (float arrays bit for bit):

    python tools/physics_snapshot.py --out before.pkl [--plans DIR]
    ... change ...
    python tools/physics_snapshot.py --out after.pkl --compare before.pkl [--atol 1e-9]

(``--atol``: floats may differ by that much, for a change that moves results by float
error only; the largest difference of each case is printed. ``--allow-new``: keys found only
in the new snapshot, such as a field added to the recording, are listed but do not count as
differences; everything both have must still be identical.) Or compare two saved
snapshots: ``--out after.pkl --compare before.pkl --reuse``.

Cases: ``layouts/paper_homogeneous`` / ``paper_heterogeneous`` / ``paper_fault`` on physics,
seeds 0 and 1; with ``--plans DIR`` also ``warerover execute``-style runs of the lacam3
plans ``DIR/plan100.txt`` and ``DIR/plan500.txt`` on ``warehouse-10-20-10-2-1`` (made by
``tools/bench_execute.py``'s lacam3 call), at dt 0.02 and 0.05 s.
"""

from __future__ import annotations

import argparse
import json
import math
import pickle
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
TIMING = ("ct_", "wall", "real_time_factor", "_ms", "_per_s")
LAYOUTS = ("paper_homogeneous", "paper_heterogeneous", "paper_fault")
MAP = ROOT / "tests" / "data" / "warehouse-10-20-10-2-1.map"


def _clean(metrics: dict) -> dict:
    return {k: v for k, v in sorted(metrics.items()) if not any(t in k for t in TIMING)}


def _arrays(d: dict | None) -> dict:
    if d is None:
        return {}
    return {k: np.array(v) for k, v in d.items()}


def _causes(log) -> dict:
    if log is None:
        return {}
    out = {k: np.asarray(getattr(log, k)) for k in (
        "agv", "seq", "src", "dst", "tick", "ticks", "start_step", "finish_step", "counts")}
    out["steps"] = log.steps
    out["blockers"] = sorted(log.blockers.items())
    return out


def run_case(layout: str, seed: int) -> dict:
    from warerover_phys import load_scenario
    from warerover_phys.sim import Simulation

    sc = load_scenario(ROOT / "layouts" / f"{layout}.yaml", [("executor.name", "physics")])
    sim = Simulation(sc, seed)
    res = sim.run()
    return {"metrics": _clean(res.metrics), "events": json.dumps(res.events, sort_keys=True),
            "actual": {i: list(map(tuple, s)) for i, s in res.actual.items()},
            "trajectory": _arrays(res.trajectory), "causes": _causes(sim.executor.cause_log())}


def execute_case(plan_file: Path, dt_s: float) -> dict:
    import warerover_phys.registry as registry
    from warerover_phys.execute import (
        execute_plan,
        load_fleet,
        load_floor,
        repair_cycles,
        validate_plan,
    )
    from warerover_phys.plans import read_plan

    layout, _, _ = load_floor(MAP)
    plan = read_plan(plan_file)
    sizes = [1] * plan.num_agents
    validate_plan(plan, layout, sizes)
    plan, repairs = repair_cycles(plan, layout, sizes)
    types = load_fleet(None, plan.num_agents, None, [])
    built = []
    real = registry.build

    def keep(*a, **k):
        obj = real(*a, **k)
        built.append(obj)
        return obj

    registry.build = keep
    try:
        res = execute_plan(plan, layout, types, executor="physics", seed=0, repairs=repairs,
                           dt_s=dt_s)
    finally:
        registry.build = real
    return {"metrics": _clean(res.metrics), "events": json.dumps(res.events, sort_keys=True),
            "actual": {i: list(map(tuple, s)) for i, s in res.executed.items()},
            "trajectory": _arrays(res.trajectory), "causes": _causes(built[-1].cause_log())}


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and a.dtype == b.dtype and bool(
            np.array_equal(a, b, equal_nan=a.dtype.kind == "f"))
    return a == b


def _gap(a, b) -> float:
    """Largest absolute difference between two equally shaped values (floats, arrays,
    nested lists / dicts / tuples); inf where their shape, keys or non-float parts
    differ."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            return math.inf
        if a.dtype.kind in "fc" or b.dtype.kind in "fc":
            d = np.abs(a.astype(float) - b.astype(float))
            d[np.isnan(a) & np.isnan(b)] = 0.0
            return float(d.max()) if d.size else 0.0
        return 0.0 if np.array_equal(a, b) else math.inf
    if isinstance(a, float) or isinstance(b, float):
        if isinstance(a, (int, float)) and isinstance(b, (int, float)):
            return 0.0 if a == b else abs(a - b)
        return math.inf
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return math.inf
        return max((_gap(a[k], b[k]) for k in a), default=0.0)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        if len(a) != len(b):
            return math.inf
        return max((_gap(x, y) for x, y in zip(a, b, strict=True)), default=0.0)
    return 0.0 if a == b else math.inf


def compare(old: dict, new: dict, atol: float = 0.0, allow_new: bool = False) -> list[str]:
    """What differs between two snapshots of a case; with ``atol`` > 0 floats (and float
    arrays, and the numbers in the events) may differ by that much; with ``allow_new`` keys
    only in ``new`` are not differences."""
    diffs = []
    for part in ("metrics", "trajectory", "causes"):
        o, n = old[part], new[part]
        for k in sorted(set(o) | set(n)):
            if allow_new and k not in o:
                continue
            if k not in o or k not in n:
                diffs.append(f"{part}.{k}: only in {'after' if k in n else 'before'}")
            elif not _same(o[k], n[k]) and not (atol > 0 and _gap(o[k], n[k]) <= atol):
                diffs.append(f"{part}.{k}: {str(o[k])[:80]} -> {str(n[k])[:80]}")
    if old["events"] != new["events"] and not (
            atol > 0 and _gap(json.loads(old["events"]), json.loads(new["events"])) <= atol):
        diffs.append("events differ")
    if old["actual"] != new["actual"]:
        diffs.append("actual differ")
    return diffs


def largest_gap(old: dict, new: dict) -> float:
    """The largest difference of any float between two snapshots of a case."""
    gaps = [_gap(old[p], new[p]) for p in ("metrics", "trajectory", "causes")]
    gaps.append(_gap(json.loads(old["events"]), json.loads(new["events"])))
    return max(gaps)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--compare", type=Path)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--plans", type=Path, help="folder with plan100.txt, plan500.txt")
    ap.add_argument("--agents", type=int, nargs="+", default=[100, 500])
    ap.add_argument("--dt", type=float, nargs="+", default=[0.02, 0.05])
    ap.add_argument("--only", help="run only the cases whose key contains this")
    ap.add_argument("--atol", type=float, default=0.0,
                    help="floats may differ by this much (default 0: bit for bit)")
    ap.add_argument("--allow-new", action="store_true",
                    help="keys only in the new snapshot (new recorded fields) are no difference")
    ap.add_argument("--reuse", action="store_true",
                    help="compare the snapshot already in --out instead of running")
    args = ap.parse_args()
    cases = [(f"{lay}/physics/{s}", run_case, (lay, s)) for lay in LAYOUTS for s in args.seeds]
    if args.plans:
        cases += [(f"execute/{n}/dt{dt}", execute_case, (args.plans / f"plan{n}.txt", dt))
                  for n in args.agents for dt in args.dt]
    if args.only:
        cases = [c for c in cases if args.only in c[0]]
    out = {}
    if args.reuse:
        with args.out.open("rb") as f:
            out = pickle.load(f)
        cases = []
    for key, fn, a in cases:
        t0 = time.process_time()
        out[key] = fn(*a)
        print(f"{key}: {time.process_time() - t0:.1f} s CPU", file=sys.stderr, flush=True)
    if not args.reuse:
        with args.out.open("wb") as f:
            pickle.dump(out, f)
    if args.compare is None:
        return 0
    with args.compare.open("rb") as f:
        before = pickle.load(f)
    bad = 0
    for key, snap in out.items():
        old = before.get(key)
        if old is None:
            print(f"{key}: not in {args.compare}")
            continue
        diffs = compare(old, snap, args.atol, args.allow_new)
        new = [f"{p}.{k}" for p in ("metrics", "trajectory", "causes")
               for k in sorted(set(snap[p]) - set(old[p]))]
        if new:
            print(f"{key}: new in this snapshot: {', '.join(new)}")
        if diffs:
            bad += 1
            print(f"DIFF {key}:\n  " + "\n  ".join(diffs[:20]))
        elif args.atol > 0:
            print(f"{key}: largest float difference {largest_gap(old, snap):.3g}")
    print(f"{len(out) - bad} of {len(out)} cases identical")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
