"""Benchmark of ``executor.reorder`` (issue 34): MAPF plans executed open loop on physics
under random delays with the plain dependency graph (``none``), ``greedy`` and ``milp``
reordering; AET, executed makespan and dependency waits with 95% confidence intervals.

Plans (made once, kept in ``--plans``): the project's LaCAM (``warerover solve``), LaCAM
with ``--refine`` (large-neighbourhood search until the time limit) and the reference C++
lacam3 (``--lacam3 BIN``, run ``-t SECONDS --no-star``), for the first N agents of
``<map>-random-1.scen`` (``../shared/data/movingai``; ``--scens 2 3``: of
``-random-2.scen`` and ``-random-3.scen`` too, labelled ``warehouse-r2``, ...; a plan the
loader cannot repair for execution is skipped, with the reason). Each run executes a plan
as ``warerover gap --plan`` does (:func:`warerover_phys.gap.open_loop.execute_timed`, physics,
dt 0.02 s) with delays ``MODEL:PROB`` (1-10 ticks, uniform) and seed ``s``; the same seed
draws the same delays in every mode until the modes' executions part. A run stops at
``MAX_TICKS_PER_PLAN_TICK`` (40) times the plan's makespan + 200 ticks, not at ``gap``'s
10x: in room-32-32-4 at 200 agents and probability 0.1 the plain graph takes up to 11x
the plan (a run cut short has no AET and shows as not ``completed``).

Per run: **AET** (mean over agents of the executed finish time, s), executed makespan (s),
measured dependency wait per AGV (s), the reorder gain per AGV (s, the estimated wait the
switches saved), switches, the decision wall time per tick (ms), the real-time factor and
the run's wall seconds; AGV-AGV contacts, deadlocks and the independent check of the
executed states (:func:`warerover_phys.executors.reorder.check_executed`: every AGV visits
exactly its plan's cells in order, no two AGVs on one cell at a tick).

Runs are appended to ``--out`` (JSON lines) as they finish and skipped when found there:
the benchmark can be stopped and resumed, and the table printed from what is there
(``--table``). The summary per (map, planner, agents, delays, mode): mean and 95% CI
(Student t over seeds) and the AET change against ``none`` on the same seeds (paired).

    PYTHONPATH=. python tools/bench_reorder.py --maps warehouse --agents 400 \\
        --planners lacam3 --delays bernoulli:0.1 --seeds 0..9 --workers 2 \\
        --lacam3 /work/lacam3-build/main --out runs/bench_reorder/runs.jsonl
    PYTHONPATH=. python tools/bench_reorder.py --out runs/bench_reorder/runs.jsonl --table
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT.parent / "shared" / "data" / "movingai"
MAPS = {"warehouse": "warehouse-10-20-10-2-1", "room": "room-32-32-4"}
MODES = ("none", "greedy", "milp")
PLANNERS = ("lacam", "lacam-refine", "lacam3")
FIGURES = ("aet_s", "makespan_s", "dependency_wait_s_per_agv", "reorder_gain_s_per_agv",
           "switches", "decision_ms_per_tick", "decision_cpu_ms_per_tick",
           "real_time_factor", "wall_s", "cpu_s")


def instance(name: str, scen: int) -> str:
    """The label of a map and scenario file: ``warehouse`` for ``-random-1.scen``,
    ``warehouse-r2`` for ``-random-2.scen``."""
    return name if scen == 1 else f"{name}-r{scen}"


def map_files(label: str, data: Path) -> tuple[Path, Path]:
    name, _, scen = label.partition("-r")
    base = MAPS[name]
    return (data / "maps" / f"{base}.map",
            data / "scen-random" / f"{base}-random-{scen or 1}.scen")


def make_plan(name: str, planner: str, agents: int, folder: Path, data: Path,
              lacam3: Path | None, time_limit: float) -> Path | None:
    """The plan file (made now if missing); None if the planner found none."""
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / f"{name}-{planner}-{agents}.txt"
    if out.exists():
        return out
    mp, scen = map_files(name, data)
    if planner == "lacam3":
        if lacam3 is None:
            return None
        cmd = [str(lacam3), "-m", str(mp), "-i", str(scen), "-N", str(agents), "-t",
               str(int(time_limit)), "--no-star", "-v", "0", "-o", str(out)]
    else:
        cmd = [sys.executable, "-m", "warerover_phys", "solve", str(mp), str(scen),
               "--agents", str(agents), "--time-limit", str(time_limit), "--out", str(out),
               "--json"] + (["--refine"] if planner == "lacam-refine" else [])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get(
        "PYTHONPATH", "")])}
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if r.returncode or not out.exists() or "solved=0" in out.read_text()[:400]:
        print(f"no plan: {' '.join(cmd)}\n{r.stderr[-400:]}", file=sys.stderr)
        out.unlink(missing_ok=True)
        return None
    return out


def executable(plan_file: Path, map_file: Path) -> bool:
    """Whether the plan loads for execution (a rotation of AGVs that the loader's repair
    cannot detour does not); if not, say why on stderr."""
    from warerover_phys.errors import WareroverError
    from warerover_phys.gap.ideal_plan import plan_from_file

    try:
        plan_from_file(map_file, plan_file, None)
    except WareroverError as e:
        print(f"skipped, not executable: {e}", file=sys.stderr)
        return False
    return True


MAX_TICKS_PER_PLAN_TICK = 40
"""A run stops at this many times the plan's makespan (+ 200 ticks)."""


def run_one(job: dict) -> dict:
    """One execution (in a worker process)."""
    from warerover_phys.config import ExecutorSpec
    from warerover_phys.execute import parse_delays
    from warerover_phys.executors.reorder import check_executed
    from warerover_phys.gap.ideal_plan import plan_from_file
    from warerover_phys.gap.open_loop import execute_timed, open_loop_report

    plan, _ = plan_from_file(job["map_file"], job["plan_file"], None)
    spec = ExecutorSpec(name="physics", dt_s=job["dt_s"], delays=parse_delays(job["delays"]),
                        trajectory_hz=1.0, reorder=job["mode"], **job["options"])
    t0, c0 = time.perf_counter(), time.process_time()
    horizon = max(len(p.states) - 1 for p in plan.paths.values())
    run = execute_timed(plan, spec, seed=job["seed"],
                        max_ticks=MAX_TICKS_PER_PLAN_TICK * horizon + 200)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    report, agents, _ = open_loop_report(run)
    n = len(agents)
    s = run.summary
    problems = check_executed({i: p.states for i, p in plan.paths.items()}, run.executed,
                              plan.layout.cols)
    return {**{k: job[k] for k in KEY}, "agents_n": n, "completed": report["completed"],
            "aet_s": float(np.mean([a["executed_finish_s"] for a in agents])),
            "makespan_s": report["executed_makespan_s"],
            "planned_aet_s": float(np.mean([a["planned_finish_s"] for a in agents])),
            "dependency_wait_s_per_agv": s["delay_dependency_wait_s"] / n,
            "lost_dependency_s_per_agv": report["lost_dependency_s_per_agv_mean"],
            "reorder_gain_s_per_agv": report["lost_reorder_gain_s_per_agv_mean"],
            "switches": s.get("reorder_switches", 0),
            "switches_driving": s.get("reorder_switches_driving", 0),
            "refused": s.get("reorder_refused", 0),
            "milp_fallbacks": s.get("reorder_milp_fallbacks", 0),
            "decision_ms_per_tick": s.get("reorder_wall_ms_per_tick", 0.0),
            "decision_cpu_ms_per_tick": s.get("reorder_cpu_ms_per_tick", 0.0),
            "real_time_factor": s["real_time_factor"], "wall_s": wall, "cpu_s": cpu,
            "sim_s": report["executed_makespan_s"],
            "agv_contacts": s["agv_contacts"], "deadlocks": s["deadlocks"],
            "execution_problems": problems[:5], "load": os.getloadavg()[0],
            "audit_s_per_agv": {k[len("reorder_audit_"):-2]: v / n for k, v in s.items()
                                if k.startswith("reorder_audit_")}}


KEY = ("map", "planner", "agents", "delays", "mode", "seed", "dt_s", "options")


def key_of(row: dict) -> str:
    return json.dumps([row[k] for k in KEY], sort_keys=True)


def parse_seeds(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("..")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


def ci95(values: list[float]) -> tuple[float, float]:
    """Mean and half-width of the 95% confidence interval (Student t)."""
    from scipy.stats import t as student

    x = np.asarray(values, dtype=float)
    if len(x) < 2:
        return float(x.mean()) if len(x) else math.nan, math.nan
    return float(x.mean()), float(student.ppf(0.975, len(x) - 1) * x.std(ddof=1)
                                  / math.sqrt(len(x)))


def summarise(rows: list[dict]) -> list[dict]:
    """Per (map, planner, agents, delays, options, mode): means with 95% CIs, and the
    AET change against ``none`` (whose runs take no options) on the seeds both ran
    (paired)."""
    groups: dict[tuple, dict[int, dict]] = {}
    for r in rows:
        k = (r["map"], r["planner"], r["agents"], r["delays"], r["dt_s"],
             json.dumps(r["options"], sort_keys=True), r["mode"])
        groups.setdefault(k, {})[r["seed"]] = r
    out = []
    for k, by_seed in sorted(groups.items(), key=lambda kv: (kv[0][:6], MODES.index(
            kv[0][6]) if kv[0][6] in MODES else 9)):
        row: dict = dict(zip(("map", "planner", "agents", "delays", "dt_s", "options", "mode"),
                             k, strict=True))
        row["seeds"] = sorted(by_seed)
        for f in FIGURES:
            row[f] = ci95([r[f] for r in by_seed.values()])
        row["contacts"] = sum(r["agv_contacts"] for r in by_seed.values())
        row["deadlocks"] = sum(r["deadlocks"] for r in by_seed.values())
        row["problems"] = sum(len(r["execution_problems"]) for r in by_seed.values())
        row["completed"] = all(r["completed"] for r in by_seed.values())
        base = groups.get((*k[:5], "{}", "none"), {})  # (none runs take no options)
        both = sorted(set(base) & set(by_seed))
        row["aet_change_pct"] = ci95([100 * (by_seed[s]["aet_s"] / base[s]["aet_s"] - 1)
                                      for s in both]) if both else (math.nan, math.nan)
        for what in ("wall", "cpu"):
            row[f"{what}_ratio"] = ci95([by_seed[s][f"{what}_s"] / base[s][f"{what}_s"]
                                         for s in both]) if both else (math.nan, math.nan)
        out.append(row)
    return out


def _pm(v: tuple[float, float], spec: str = ".1f") -> str:
    m, h = v
    if m != m:
        return "-"
    return f"{m:{spec}}" + ("" if h != h else f" ± {h:{spec}}")


def print_table(summary: list[dict]) -> None:
    head = ("map", "planner", "N", "delays", "mode", "seeds", "AET (s)", "dAET vs none (%)",
            "makespan (s)", "dep. wait/AGV (s)", "gain/AGV (s)", "switches",
            "decide CPU ms/tick", "RTF", "wall x none", "CPU x none", "contacts", "problems")
    print(" | ".join(head))
    print(" | ".join("---" for _ in head))
    for r in summary:
        print(" | ".join(str(x) for x in (
            r["map"], r["planner"], r["agents"], r["delays"], r["mode"], len(r["seeds"]),
            _pm(r["aet_s"]), _pm(r["aet_change_pct"]), _pm(r["makespan_s"]),
            _pm(r["dependency_wait_s_per_agv"]), _pm(r["reorder_gain_s_per_agv"], ".2f"),
            _pm(r["switches"], ".0f"), _pm(r["decision_cpu_ms_per_tick"], ".2f"),
            _pm(r["real_time_factor"]), _pm(r["wall_ratio"], ".2f"),
            _pm(r["cpu_ratio"], ".2f"), r["contacts"], r["problems"])))


AUDIT = {  # the audit's reasons (executors.reorder.Reorderer.audit), grouped
    "switchable": ("switched", "declined", "refused", "overlap"),
    "held: delayed AGV": ("held_delayed",),
    "held: AGV driving off": ("held_moving",),
    "unmovable visit": ("claimed", "sweep", "plan_end", "unmovable"),
    "itself delayed": ("delayed",),
    "other": ("other",),
}


def audit_groups(audit: dict[str, float]) -> dict[str, float]:
    """Seconds per AGV by :data:`AUDIT` group; a chain's wait (``chain_X``) goes with the
    group of ``X`` (as ``chain: ...``), ``chain_moving`` with the AGVs driving off."""
    out = {g: 0.0 for g in AUDIT} | {f"chain: {g}": 0.0 for g in AUDIT}
    for k, v in audit.items():
        chain = k.startswith("chain_")
        name = k[len("chain_"):] if chain else k
        name = "held_moving" if name == "moving" else name
        g = next((g for g, ks in AUDIT.items() if name in ks), "other")
        out[f"chain: {g}" if chain else g] += v
    return out


def print_audit(rows: list[dict]) -> None:
    """Where the dependency wait goes (seconds per AGV, mean ± 95% CI over seeds), per
    (map, planner, agents, delays, mode, options) of the runs that carry an audit."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        if r.get("audit_s_per_agv"):
            k = (r["map"], r["planner"], r["agents"], r["delays"], r["mode"],
                 json.dumps(r["options"], sort_keys=True))
            groups.setdefault(k, []).append(r)
    names = [*AUDIT, *(f"chain: {g}" for g in AUDIT)]
    head = ("map", "planner", "N", "delays", "mode", "options", "seeds", "dep. wait/AGV (s)",
            *names)
    print(" | ".join(head))
    print(" | ".join("---" for _ in head))
    for k, rs in sorted(groups.items()):
        by = [audit_groups(r["audit_s_per_agv"]) for r in rs]
        print(" | ".join(str(x) for x in (
            *k, len(rs), _pm(ci95([r["dependency_wait_s_per_agv"] for r in rs])),
            *(_pm(ci95([b[n] for b in by])) for n in names))))


def print_pooled(rows: list[dict]) -> None:
    """ΔAET against ``none`` per (map, planner, agents, delays, options, mode) pooled over
    the scenario files (``warehouse``, ``warehouse-r2``, ...): the mean and 95% CI over
    every (scenario, seed) pair, the instances' own means, and the pairs at -10% or
    better."""
    base = {(r["map"], r["planner"], r["agents"], r["delays"], r["dt_s"], r["seed"]): r
            for r in rows if r["mode"] == "none"}
    groups: dict[tuple, dict[str, list[float]]] = {}
    for r in rows:
        b = base.get((r["map"], r["planner"], r["agents"], r["delays"], r["dt_s"], r["seed"]))
        if r["mode"] == "none" or b is None:
            continue
        k = (r["map"].partition("-r")[0], r["planner"], r["agents"], r["delays"],
             json.dumps(r["options"], sort_keys=True), r["mode"])
        groups.setdefault(k, {}).setdefault(r["map"], []).append(
            100 * (r["aet_s"] / b["aet_s"] - 1))
    head = ("map", "planner", "N", "delays", "options", "mode", "scenarios", "pairs",
            "dAET vs none (%)", "per scenario (%)", "pairs at -10%")
    print(" | ".join(head))
    print(" | ".join("---" for _ in head))
    for k, by in sorted(groups.items()):
        every = [d for ds in by.values() for d in ds]
        per = ", ".join(f"{m}: {np.mean(ds):.1f}" for m, ds in sorted(by.items()))
        print(" | ".join(str(x) for x in (
            *k, len(by), len(every), _pm(ci95(every)), per,
            sum(round(d, 9) <= -10 for d in every))))


def load_rows(path: Path) -> list[dict]:
    if not path.exists():
        return []
    return [json.loads(x) for x in path.read_text().splitlines() if x.strip()]


def jobs_for(args, plans: dict) -> list[dict]:
    options = json.loads(args.options)
    out = []
    for (name, planner, n), plan_file in plans.items():
        mp, _ = map_files(name, args.data)
        for delays in args.delays:
            for seed in parse_seeds(args.seeds):
                for mode in args.modes:
                    out.append({"map": name, "planner": planner, "agents": n,
                                "delays": delays, "mode": mode, "seed": seed,
                                "dt_s": args.dt, "options": options if mode != "none" else {},
                                "map_file": str(mp), "plan_file": str(plan_file)})
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", nargs="+", default=["warehouse"], choices=sorted(MAPS))
    ap.add_argument("--agents", nargs="+", type=int, default=[100, 400, 1000],
                    help="agent counts (room-32-32-4 takes those <= --room-max)")
    ap.add_argument("--room-max", type=int, default=200)
    ap.add_argument("--scens", nargs="+", type=int, default=[1],
                    help="the MovingAI random scenario files, by number (default 1)")
    ap.add_argument("--planners", nargs="+", default=list(PLANNERS), choices=PLANNERS)
    ap.add_argument("--delays", nargs="+", default=[
        "bernoulli:0.05", "bernoulli:0.1", "bernoulli:0.2", "poisson:0.1"])
    ap.add_argument("--modes", nargs="+", default=list(MODES), choices=MODES)
    ap.add_argument("--seeds", default="0..19", help="0..19, or 0,3,5")
    ap.add_argument("--dt", type=float, default=0.02)
    ap.add_argument("--options", default="{}",
                    help='other executor fields for greedy / milp, JSON: {"reorder_every_s": 0.2}')
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--plans", type=Path, default=Path("runs/bench_reorder/plans"))
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--lacam3", type=Path, help="the reference lacam3 binary")
    ap.add_argument("--plan-time", type=float, default=60.0,
                    help="seconds per plan (lacam3 -t, warerover solve --time-limit)")
    ap.add_argument("--out", type=Path, default=Path("runs/bench_reorder/runs.jsonl"))
    ap.add_argument("--table", action="store_true", help="only print the table of --out")
    ap.add_argument("--audit", action="store_true",
                    help="also print where the dependency wait goes (runs with an audit)")
    ap.add_argument("--pool", action="store_true",
                    help="also print the AET change pooled over the scenario files")
    ap.add_argument("--json", type=Path, help="also write the summary here")
    ap.add_argument("--more", type=Path, nargs="*", default=[],
                    help="more run files for the table (batches run side by side)")
    ap.add_argument("--max-runs", type=int, help="stop after this many new runs")
    args = ap.parse_args(argv)
    if not args.table:
        plans = {}
        for name in [instance(m, s) for m in args.maps for s in args.scens]:
            for n in args.agents:
                if name.startswith("room") and n > args.room_max:
                    continue
                for planner in args.planners:
                    f = make_plan(name, planner, n, args.plans, args.data, args.lacam3,
                                  args.plan_time)
                    if f is not None and executable(f, map_files(name, args.data)[0]):
                        plans[(name, planner, n)] = f
        done = {key_of(r) for r in load_rows(args.out)}
        todo = [j for j in jobs_for(args, plans) if key_of(j) not in done]
        if args.max_runs is not None:
            todo = todo[:args.max_runs]
        print(f"{len(todo)} runs to do ({len(done)} in {args.out})", file=sys.stderr)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        with ProcessPoolExecutor(max_workers=args.workers) as pool, args.out.open("a") as f:
            futures = {pool.submit(run_one, j): j for j in todo}
            for fut in as_completed(futures):
                row = fut.result()
                f.write(json.dumps(row, sort_keys=True) + "\n")
                f.flush()
                print(f"{row['map']} {row['planner']} {row['agents']} {row['delays']} "
                      f"{row['mode']} seed {row['seed']}: AET {row['aet_s']:.1f} s, "
                      f"wall {row['wall_s']:.0f} s (load {row['load']:.1f})",
                      file=sys.stderr, flush=True)
    rows = [r for path in [args.out, *args.more] for r in load_rows(path)]
    summary = summarise(rows)
    print_table(summary)
    if args.audit:
        print()
        print_audit(rows)
    if args.pool:
        print()
        print_pooled(rows)
    if args.json:
        args.json.write_text(json.dumps(summary, indent=1, sort_keys=True, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
