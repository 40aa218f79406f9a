"""Benchmark of the one lifelong loop at warehouse scale: busy AGVs on the grid and on
physics, Robot Runners problems on physics, planners invoked every tick, periodically or on
an event, with and without a planning latency.

Two kinds of case, each run in its own process (its peak memory its own):

- ``loop``: ``layouts/industrial.yaml`` (1,680 shelves, 24 stations) with N AGVs and a busy
  order stream (``orders.constant.batch = N / 5`` every 10 ticks: most AGVs get work), TA,
  lifelong PIBT; ``--set`` overrides apply;
- ``lorr``: a Robot Runners problem (``--problem``; default the 2026 fulfill example grown
  to N robots by ``tools/make_lorr_agents.py``, written under ``tools/out``), its rotation
  model, the league's task pool.

Per case: wall and CPU seconds of the run (set-up excluded), the real-time factor by wall
clock and by CPU (simulated seconds over each), peak RSS, the moving share (physics), the
dependency deadlocks the executor found (cycles of the graph) and the freezes (no progress
for ``executor.freeze_s``), both per 1,000 AGV-minutes, AGV-AGV contacts, throughput
(orders or tasks finished per tick), scheduler and planner milliseconds per call (mean,
p99) and the AGV-seconds lost waiting for plans, with the load average at the end.

    python tools/bench_lifelong.py --cases loop:1000:physics:0.05 loop:1000:physics:0.02 \\
        lorr:5000:physics:0.02 --ticks 120 --json out.json

A case is ``kind:agents:executor:dt[:invoke[:latency]]`` (``invoke`` and ``latency`` as
``planner.invoke`` / ``planner.latency``, e.g. ``loop:1000:physics:0.05:periodic=5:fixed=1``
with ``=`` for ``:``). ``--all`` runs the issue's table (slow: about an hour on 2 cores).

For reference (not measured here): LSMART (2026) runs 1,000 robots on
warehouse-10-20-10-2-1 with windowed PIBT, 600 simulated seconds in 268 s of wall clock on a
16-core desktop, about 2.2x real time.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FULFILL = ROOT.parent / "shared" / "data" / "robotrunners" / "lorr2026_warehouse_fulfill" / \
    "fulfill-example_2500.json"
ALL = [f"loop:{n}:{ex}:{dt}" for n in (100, 1000) for ex in ("grid", "physics")
       for dt in ((0.05,) if ex == "grid" else (0.02, 0.05))] + [
    "loop:5000:grid:0.05", "loop:5000:physics:0.05",
    "loop:1000:physics:0.05:every_tick:measured", "loop:1000:physics:0.05:periodic=5:none",
    "loop:1000:physics:0.05:periodic=5:fixed=1", "loop:1000:physics:0.05:event=3:measured",
    "lorr:1000:grid:0.02", "lorr:1000:physics:0.02", "lorr:1000:physics:0.05",
    "lorr:5000:physics:0.02", "lorr:5000:physics:0.05"]
LSMART = {"robots": 1000, "map": "warehouse-10-20-10-2-1", "planner": "windowed PIBT",
          "sim_s": 600, "wall_s": 268, "real_time_factor": 600 / 268, "cores": 16}


def problem_for(n: int, given: Path | None) -> Path:
    """The Robot Runners problem of a ``lorr`` case: ``given``, or the fulfill example with
    ``n`` robots (its 2,500 plus robots on free cells, ``make_lorr_agents.py``, seed 0)."""
    if given is not None:
        return given
    out = ROOT / "tools" / "out" / f"fulfill_{n}"
    if not (out / "problem.json").exists():
        subprocess.run([sys.executable, str(ROOT / "tools" / "make_lorr_agents.py"),
                        str(FULFILL), "--agents", str(n), "--out", str(out)], check=True,
                       capture_output=True)
    return out / "problem.json"


def run_case(case: str, ticks: int, problem: Path | None, sets: list[str]) -> dict:
    from warerover_phys.config import parse_override
    from warerover_phys.sim import Simulation

    parts = case.split(":")
    kind, n, executor, dt = parts[0], int(parts[1]), parts[2], float(parts[3])
    invoke = parts[4].replace("=", ":") if len(parts) > 4 else "every_tick"
    latency = parts[5].replace("=", ":") if len(parts) > 5 else "none"
    over = [f"executor={executor}", f"executor.dt_s={dt}", f"planner.invoke={invoke}",
            f"planner.latency={latency}", f"max_ticks={ticks}", *sets]
    t0 = time.perf_counter()
    if kind == "loop":
        from warerover_phys import load_scenario

        over = [f"fleet.agvs.0.count={n}", f"orders.constant.batch={max(1, n // 5)}",
                "scheduler=ta", "planner=pibt", *over]
        sc = load_scenario(ROOT / "layouts" / "industrial.yaml",
                           [parse_override(s) for s in over])
    else:
        from warerover_phys.problems.robotrunners import problem_scenario, read_problem

        prob = read_problem(problem_for(n, problem))
        sc = problem_scenario(prob, ticks=ticks, executor=executor,
                              overrides=[parse_override(s) for s in over])
    sim = Simulation(sc)
    setup_s = time.perf_counter() - t0
    w0, c0 = time.perf_counter(), time.process_time()
    result = sim.run()
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    m = result.metrics
    sim_s = m["ticks"] * sc.tick_s
    agv_min = len(result.world.agvs) * sim_s / 60 / 1000
    adg = m.get("deadlocks", 0) - m.get("freezes", 0)
    return {
        "case": case, "kind": kind, "agents": n, "executor": executor, "dt_s": dt,
        "invoke": invoke, "latency": latency, "ticks": m["ticks"], "setup_s": setup_s,
        "wall_s": wall, "cpu_s": cpu, "rtf_wall": sim_s / wall, "rtf_cpu": sim_s / cpu,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "moving_share": m.get("moving_share"), "adg_deadlocks": adg,
        "freezes": m.get("freezes", 0), "adg_deadlocks_per_1000_agv_min": adg / agv_min,
        "freezes_per_1000_agv_min": m.get("freezes", 0) / agv_min,
        "agv_contacts": m.get("agv_contacts"), "throughput": m["throughput"],
        "completed": m["orders_completed"], "sched_ms_mean": m["ct_sched_mean_ms"],
        "sched_ms_p99": m["ct_sched_p99_ms"], "plan_call_ms_mean": m["ct_plan_call_mean_ms"],
        "plan_call_ms_p99": m["ct_plan_call_p99_ms"], "planner_calls": m["planner_calls"],
        "plan_wait_agv_s": m["plan_wait_agv_s"], "load_avg": os.getloadavg()[0],
    }


COLUMNS = ["case", "ticks", "wall_s", "cpu_s", "rtf_wall", "rtf_cpu", "peak_rss_mb",
           "moving_share", "adg_deadlocks_per_1000_agv_min", "freezes_per_1000_agv_min",
           "agv_contacts", "throughput", "sched_ms_mean", "sched_ms_p99", "plan_call_ms_mean",
           "plan_call_ms_p99", "plan_wait_agv_s", "load_avg"]


def fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.3g}" if abs(v) < 100 else f"{v:.0f}"
    return "-" if v is None else str(v)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["loop:1000:physics:0.05"])
    ap.add_argument("--all", action="store_true", help="the issue's table (see the docstring)")
    ap.add_argument("--ticks", type=int, default=120, help="ticks per case (default 120)")
    ap.add_argument("--problem", type=Path, help="Robot Runners problem of lorr cases")
    ap.add_argument("--set", dest="sets", action="append", default=[],
                    help="scenario override for every case (repeatable)")
    ap.add_argument("--json", type=Path, help="write the rows here (kept between runs: "
                                              "cases already there are not run again)")
    ap.add_argument("--_one", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args._one:
        print(json.dumps(run_case(args._one, args.ticks, args.problem, args.sets)))
        return 0
    rows = json.loads(args.json.read_text()) if args.json and args.json.exists() else []
    done = {r["case"] for r in rows}
    for case in ALL if args.all else args.cases:
        if case in done:
            continue
        cmd = [sys.executable, __file__, "--_one", case, "--ticks", str(args.ticks)]
        cmd += ["--problem", str(args.problem)] if args.problem else []
        for s in args.sets:
            cmd += ["--set", s]
        proc = subprocess.run(cmd, capture_output=True, text=True,
                              env={**os.environ, "PYTHONPATH": str(ROOT)})
        if proc.returncode != 0:
            print(f"{case}: failed\n{proc.stderr[-2000:]}", file=sys.stderr)
            continue
        row = json.loads(proc.stdout.strip().splitlines()[-1])
        rows.append(row)
        print(json.dumps(row), flush=True)
        if args.json:
            args.json.write_text(json.dumps(rows, indent=1) + "\n")
    print("| " + " | ".join(COLUMNS) + " |")
    print("|" + "---|" * len(COLUMNS))
    for r in rows:
        print("| " + " | ".join(fmt(r.get(k)) for k in COLUMNS) + " |")
    print(f"LSMART (published, not measured here): {json.dumps(LSMART)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
