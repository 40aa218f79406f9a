"""The table of tools/README_learned.md: ``learned`` beside astar / cbs / pibt / lacam.

1. Paper scenarios (closed loop, grid executor): ``python -m warerover_phys run SCENARIO
   --planner X --json --seed S`` for each planner and seed; mean SR, TP (orders/tick) and CT
   (total scheduler + planner wall seconds per episode). ``learned`` runs as the plugin
   ``warerover_phys.planning.learned.planner:LearnedPlanner`` (the scenario schema does not list
   the name ``learned`` yet).
2. MovingAI one-shot instances (``random-32-32-10``, ``warehouse-10-20-10-2-1``; scenario
   ``random-1``, first N agents): ``oneshot.solve`` for lacam / pibt / astar (prioritized),
   :func:`learned_oneshot` for learned. CBS has no one-shot entry point in this project.
   A run succeeds only if it returns paths that start and end right and the independent
   validator finds no conflict; SoC / LB as in ``warerover solve``.

Every process is pinned to one BLAS thread (``OPENBLAS_NUM_THREADS=1``): on a shared 2-core
machine a threaded BLAS makes the 50-agent network call ~100x slower.

    PYTHONPATH=. .venv/bin/python tools/learned_table.py                 # ~10-15 min
    PYTHONPATH=. .venv/bin/python tools/learned_table.py --seeds 0 1 --agents 50 100
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from warerover_phys.planning.learned.planner import learned_oneshot  # noqa: E402
from warerover_phys.planning.oneshot.core import grid_graph, solve  # noqa: E402
from warerover_phys.problems.movingai import read_map, read_scen  # noqa: E402
from warerover_phys.validate import validate_states  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PLUGIN = "warerover_phys.planning.learned.planner:LearnedPlanner"
DATA = Path("/work/shared/data/movingai")
MAPS = ["random-32-32-10", "warehouse-10-20-10-2-1"]


def paper_rows(scenarios: list[str], planners: list[str], seeds: list[int], tmp: Path):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NO_COLOR": "1"}
    rows = []
    for scen in scenarios:
        for planner in planners:
            runs = []
            for seed in seeds:
                name = PLUGIN if planner == "learned" else planner
                proc = subprocess.run(
                    [sys.executable, "-m", "warerover_phys", "run", str(ROOT / "layouts" / scen),
                     "--planner", name, "--seed", str(seed), "--json", "--quiet",
                     "--out", str(tmp / f"{Path(scen).stem}-{planner}-{seed}")],
                    capture_output=True, text=True, env=env, timeout=1800)
                if proc.returncode != 0:
                    runs.append({"error": proc.stderr.strip().splitlines()[-1:]})
                    continue
                runs.append(json.loads(proc.stdout))
            ok = [r for r in runs if "error" not in r]
            row = {"scenario": Path(scen).stem, "planner": planner, "runs": len(runs),
                   "errors": len(runs) - len(ok)}
            if ok:
                row.update(
                    sr=float(np.mean([r["success_rate"] for r in ok])),
                    tp=float(np.mean([r["throughput"] for r in ok])),
                    ct_s=float(np.mean([r["ct_total_s"] for r in ok])),
                    ticks=float(np.mean([r["ticks"] for r in ok])),
                    collisions=int(sum(r["collisions"] for r in ok)),
                    budget_hits=int(sum(r.get("planner_budget_hits", 0) for r in ok)))
            print(json.dumps(row), flush=True)
            rows.append(row)
    return rows


def _soc(paths, goals) -> tuple[int, int]:
    soc = 0
    for path, goal in zip(paths, goals, strict=True):
        t = len(path) - 1
        while t > 0 and path[t - 1] == goal:
            t -= 1
        soc += t
    return soc, max(len(p) - 1 for p in paths)


def oneshot_rows(maps: list[str], planners: list[str], agents: list[int], time_limit: float):
    rows = []
    for name in maps:
        m = read_map(DATA / "maps" / f"{name}.map")
        scen = read_scen(DATA / "scen-random" / f"{name}-random-1.scen")
        graph = grid_graph(m.obstacles)
        failed: set[str] = set()
        for n in agents:
            starts = [a.start for a in scen[:n]]
            goals = [a.goal for a in scen[:n]]
            lb = sum(graph.distance(s, g) for s, g in zip(starts, goals, strict=True))
            for planner in planners:
                row = {"map": name, "agents": n, "planner": planner, "lb": lb}
                if planner in failed:
                    row.update(status="skipped (failed on fewer agents)")
                    rows.append(row)
                    print(json.dumps(row), flush=True)
                    continue
                t0 = time.perf_counter()
                if planner == "learned":
                    paths, stats = learned_oneshot(graph, starts, goals,
                                                   time.monotonic() + time_limit)
                else:
                    res = solve(m.obstacles, starts, goals, planner, time_limit)
                    paths, stats = (res.paths if res.success else None), res.stats
                wall = time.perf_counter() - t0
                row["wall_s"] = round(wall, 2)
                row["fallback_steps"] = stats.get("fallback_steps")
                if paths is None:
                    row["status"] = "fail"
                    failed.add(planner)
                else:
                    states = {i: [(r * m.cols + c,) * 2 for r, c in p]
                              for i, p in enumerate(paths)}
                    conflicts = validate_states(states, m.obstacles, max_conflicts=1)
                    right = all(p[0] == s and p[-1] == g
                                for p, s, g in zip(paths, starts, goals, strict=True))
                    soc, makespan = _soc(paths, goals)
                    row.update(status="ok" if not conflicts and right else "invalid",
                               soc=soc, makespan=makespan, soc_lb=round(soc / lb, 3))
                    if row["status"] != "ok":
                        failed.add(planner)
                rows.append(row)
                print(json.dumps(row), flush=True)
    return rows


def markdown(paper, oneshot) -> str:
    out = ["| scenario | planner | SR | TP (orders/tick) | CT total (s) | ticks | "
           "collisions | fallback ticks |", "|---|---|---|---|---|---|---|---|"]
    for r in paper:
        if "sr" not in r:
            out.append(f"| {r['scenario']} | {r['planner']} | error | | | | | |")
            continue
        out.append(f"| {r['scenario']} | {r['planner']} | {r['sr']:.3f} | {r['tp']:.3f} | "
                   f"{r['ct_s']:.3f} | {r['ticks']:.0f} | {r['collisions']} | "
                   f"{r['budget_hits'] if r['planner'] == 'learned' else ''} |")
    out += ["", "| map | agents | planner | result | SoC / LB | makespan | wall (s) |",
            "|---|---|---|---|---|---|---|"]
    for r in oneshot:
        ok = r.get("status") == "ok"
        out.append(f"| {r['map']} | {r['agents']} | {r['planner']} | {r['status']} | "
                   f"{r['soc_lb'] if ok else ''} | {r['makespan'] if ok else ''} | "
                   f"{r.get('wall_s', '')} |")
    return "\n".join(out) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenarios", nargs="+",
                    default=["paper_homogeneous.yaml", "paper_heterogeneous.yaml",
                             "paper_fault.yaml"])
    ap.add_argument("--planners", nargs="+", default=["astar", "cbs", "pibt", "lacam",
                                                      "learned"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4])
    ap.add_argument("--maps", nargs="+", default=MAPS)
    ap.add_argument("--agents", nargs="+", type=int, default=[50, 100, 200, 400])
    ap.add_argument("--time-limit", type=float, default=60.0)
    ap.add_argument("--skip-paper", action="store_true")
    ap.add_argument("--weights", type=Path, default=None,
                    help="weights of the learned planner (default: the shipped ones); set "
                         "as $WAREROVER_LEARNED_WEIGHTS for every run")
    ap.add_argument("--out", type=Path, default=ROOT / "tools" / "out" / "learned_table.json")
    args = ap.parse_args()
    if args.weights is not None:
        os.environ["WAREROVER_LEARNED_WEIGHTS"] = str(args.weights.resolve())
    tmp = Path(os.environ.get("TMPDIR", "/tmp")) / "learned_table_runs"
    paper = [] if args.skip_paper else paper_rows(args.scenarios, args.planners, args.seeds,
                                                  tmp)
    one = oneshot_rows(args.maps, [p for p in args.planners if p != "cbs"], args.agents,
                       args.time_limit)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"paper": paper, "oneshot": one,
                                    "weights": os.environ.get("WAREROVER_LEARNED_WEIGHTS"),
                                    "machine": platform.platform(),
                                    "time_limit_s": args.time_limit}, indent=2) + "\n")
    print(markdown(paper, one))


if __name__ == "__main__":
    main()
