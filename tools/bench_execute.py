"""Benchmark of ``warerover execute``: another solver's plan on a MovingAI warehouse map,
executed on the physics executor.

For each agent count: the plan is made by the reference C++ lacam3 (``--lacam3 BIN``, or
built from ``../shared/reference/lacam3`` with cmake; with ``--own`` the project's LaCAM
makes it instead), read, validated (conflicts and rotations, rotations repaired), executed
on physics, and the executed per-tick states are checked by the independent validator.
Each count runs in its own process so that its peak memory (max RSS) is its own.

    python tools/bench_execute.py --agents 100 500 1000 [--dt 0.02 0.05] --json out.json

``real_time_factor`` is simulated time over the executor's wall time; ``rtf_cpu`` the
simulated time over the CPU time of the whole execution (steadier on a loaded machine);
``load_avg`` the 1-minute load average when it ended; ``executed_digest`` a hash of the
executed per-tick states of every agent (equal digests at two ``--dt``: the same
execution). ``--plans DIR`` keeps the plans
(``DIR/planN.txt``) and reuses them, for before / after comparisons on the same plans.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MAP = ROOT / "tests" / "data" / "warehouse-10-20-10-2-1.map"
SCEN = ROOT / "tests" / "data" / "warehouse-10-20-10-2-1-random-1.scen"
REFERENCE = ROOT.parent / "shared" / "reference" / "lacam3"


def build_lacam3() -> Path | None:
    """Build the reference lacam3 into a temporary folder (None if it cannot be built)."""
    if not REFERENCE.is_dir() or shutil.which("cmake") is None:
        return None
    build = Path(tempfile.gettempdir()) / "warerover-lacam3-build"
    exe = build / "main"
    if exe.exists():
        return exe
    try:
        subprocess.run(["cmake", "-S", str(REFERENCE), "-B", str(build),
                        "-DCMAKE_BUILD_TYPE=Release"], check=True, capture_output=True)
        subprocess.run(["cmake", "--build", str(build), "-j2"], check=True,
                       capture_output=True)
    except (subprocess.CalledProcessError, OSError):
        return None
    return exe if exe.exists() else None


def make_plan(n: int, lacam3: Path | None, out: Path, planner: str = "lacam") -> str:
    """Write a plan for the first ``n`` agents of the scenario: by ``lacam3`` (the C++
    reference, 30 s of LaCAM*) when given, else by the project's one-shot ``planner``
    (``lacam`` or ``pibt``, 120 s at most)."""
    if lacam3 is not None:
        subprocess.run([str(lacam3), "-m", str(MAP), "-i", str(SCEN), "-N", str(n),
                        "-t", "30", "-o", str(out), "-s", "0"], check=True,
                       capture_output=True)
        return "lacam3 (C++ reference)"
    from warerover_phys.planning.oneshot.core import solve, write_plan
    from warerover_phys.problems.movingai import read_map, read_scen

    m = read_map(MAP)
    agents = read_scen(SCEN, n)
    res = solve(m.obstacles, [a.start for a in agents], [a.goal for a in agents],
                planner=planner, time_limit_s=120)
    write_plan(out, res)
    return f"warerover {planner}"


def one(n: int, plan_file: Path, solver: str, dt_s: float = 0.02) -> dict:
    import numpy as np

    from warerover_phys.execute import (
        execute_plan,
        find_cycles,
        load_fleet,
        load_floor,
        repair_cycles,
        validate_plan,
    )
    from warerover_phys.plans import read_plan
    from warerover_phys.validate import validate_states

    layout, _, _ = load_floor(MAP)
    t0 = time.perf_counter()
    plan = read_plan(plan_file)
    t_read = time.perf_counter() - t0
    sizes = [1] * plan.num_agents
    t0 = time.perf_counter()
    validate_plan(plan, layout, sizes)
    cycles = find_cycles(plan, layout.cols)
    t_validate = time.perf_counter() - t0
    t0 = time.perf_counter()
    plan, repairs = repair_cycles(plan, layout, sizes)
    if repairs:
        validate_plan(plan, layout, sizes)
    t_repair = time.perf_counter() - t0
    types = load_fleet(None, plan.num_agents, None, [])
    t0, c0 = time.perf_counter(), time.process_time()
    result = execute_plan(plan, layout, types, executor="physics", seed=0, repairs=repairs,
                          dt_s=dt_s)
    t_exec, c_exec = time.perf_counter() - t0, time.process_time() - c0
    blocked = np.asarray(layout.grid) == 1
    conflicts = [c for c in validate_states(result.executed, blocked) if c.kind != "move"]
    m = result.metrics
    return {
        "agents": n, "solver": solver, "dt_s": dt_s, "plan_makespan": m["planned_makespan_ticks"],
        "read_s": round(t_read, 3), "validate_s": round(t_validate, 3),
        "rotations": len(cycles), "repairs": len(repairs), "repair_s": round(t_repair, 3),
        "execute_wall_s": round(t_exec, 2), "real_time_factor": round(m["real_time_factor"], 1),
        "execute_cpu_s": round(c_exec, 2),
        "rtf_cpu": round(m["ticks"] * m["tick_s"] / c_exec, 1),
        "load_avg": round(os.getloadavg()[0], 1),
        "executed_makespan": m["executed_makespan_ticks"],
        "makespan_ratio": round(m["makespan_ratio"], 3),
        "agv_contacts": m["agv_contacts"], "static_contacts": m["static_contacts"],
        "min_clearance_m": m["min_clearance_m"], "limit_violations": m["limit_violations"],
        "completed": m["completed"],
        "validator_conflicts": len(conflicts),
        "executed_digest": hashlib.sha256(json.dumps(
            [result.executed[i] for i in range(n)]).encode()).hexdigest()[:16],
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agents", type=int, nargs="+", default=[100, 500, 1000])
    ap.add_argument("--lacam3", type=Path, help="lacam3 binary (default: build the reference)")
    ap.add_argument("--own", action="store_true", help="plan with the project's own LaCAM")
    ap.add_argument("--solver", choices=("lacam3", "lacam", "pibt"),
                    help="who makes the plans: the reference lacam3 (default), or the "
                         "project's one-shot lacam or pibt (--own = --solver lacam); plans "
                         "are kept as DIR/SOLVER-planN.txt with --plans")
    ap.add_argument("--json", type=Path, help="write the figures here")
    ap.add_argument("--plans", type=Path,
                    help="reuse DIR/planN.txt if there (else make it and keep it there): the "
                         "same plans for a before / after comparison")
    ap.add_argument("--dt", type=float, nargs="+", default=[0.02],
                    help="physics steps (s) to measure at (default 0.02)")
    ap.add_argument("--_one", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args._one:
        n, plan, solver, dt = args._one
        print(json.dumps(one(int(n), Path(plan), solver, float(dt))))
        return 0
    who = args.solver or ("lacam" if args.own else "lacam3")
    lacam3 = None if who != "lacam3" else (args.lacam3 or build_lacam3())
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.agents:
            # (lacam3 plans keep their old names, planN.txt, for earlier comparisons)
            name = f"plan{n}.txt" if who == "lacam3" else f"{who}-plan{n}.txt"
            plan = (args.plans or Path(tmp)) / name
            if args.plans is not None and plan.exists():
                solver = "given plan (" + ("lacam3 (C++ reference)" if who == "lacam3"
                                          else f"warerover {who}") + ")"
            else:
                solver = make_plan(n, lacam3, plan, planner=who)
            for dt in args.dt:
                proc = subprocess.run([sys.executable, __file__, "--_one", str(n), str(plan),
                                       solver, str(dt)], capture_output=True, text=True,
                                      env={**os.environ, "PYTHONPATH": str(ROOT)})
                if proc.returncode != 0:
                    print(proc.stderr, file=sys.stderr)
                    return 1
                row = json.loads(proc.stdout.strip().splitlines()[-1])
                rows.append(row)
                print(json.dumps(row), flush=True)
    keys = ["agents", "solver", "dt_s", "validate_s", "rotations", "repairs", "execute_wall_s",
            "real_time_factor", "execute_cpu_s", "rtf_cpu", "load_avg", "makespan_ratio",
            "agv_contacts", "validator_conflicts", "peak_rss_mb"]
    print("| " + " | ".join(keys) + " |")
    print("|" + "---|" * len(keys))
    for r in rows:
        print("| " + " | ".join(str(r[k]) for k in keys) + " |")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
