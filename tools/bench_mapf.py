"""Benchmark one-shot MAPF on MovingAI warehouse-10-20-10-2-1: ours beside the C++ lacam3.

Two modes, each run by both sides as a user would run them (a subprocess each; the wall time
is the whole process: start-up, reading, distance tables, solving, validating, writing):

- ``first`` (first solution): ours ``warerover solve --planner lacam`` (guide paths on;
  ``--no-guide`` turns them off), lacam3 ``--no-star`` (LaCAM, stopping at its first solution);
  both with ``--time-limit`` (default 60 s).
- ``refined`` (anytime, ``--refine-time`` seconds, default 30): ours ``warerover solve
  --refine``, lacam3 without ``--no-star`` (LaCAM* with its refiners until the limit).

For every run the plan file is read back here (an independent reader of the ``t:(x,y),...``
format both write), the sum of costs, makespan and lower bound (sum of single-agent BFS
distances, 4-connected, via scipy) are recomputed from the paths, and the plan is checked
with the project's validator (:func:`warerover_phys.validate.validate_states`) and for its
endpoints. A run succeeds only if its solver reports a solution and the check passes.

lacam3: ``--lacam3 PATH`` or ``$WARERO_LACAM3`` names a binary; otherwise it is built from
``../shared/reference/lacam3`` (beside the repository; ``--lacam3-src``) with cmake and g++
into ``build/lacam3`` (reused when present). Without cmake or g++ (or the sources) the script
says so plainly and runs our side alone. lacam3 takes whole seconds as its limit (rounded up).

Prints one row per run, then per (N, mode) the ratios ours / lacam3 (SoC, wall time and CPU
time: user + system of the whole process), with the load average, and writes everything as
JSON (default ``tools/out/bench_mapf.json``).

    .venv/bin/python tools/bench_mapf.py --quick            # N = 100 400 on random-1
    .venv/bin/python tools/bench_mapf.py                    # N = 100 200 400 700 1000, random-1
    .venv/bin/python tools/bench_mapf.py --agents 400 --modes refined --refine-time 30
    .venv/bin/python tools/bench_mapf.py --parts 400 700 [--parts-engine python]

Before the runs (where some N reaches ``NUMBA_MIN_AGENTS``, 300) our one-shot numba kernels
are compiled into numba's cache where it is cold (``--no-warm-up``: not), so that the runs
time the steady state; the warm-up's CPU time is
printed and kept in the JSON notes.

``--parts N ...`` instead times our first solution part by part (CPU seconds each, a fresh
interpreter per N: start-up, imports, reading, numba's import, distance tables, guide paths,
LaCAM, validation, plan file), with the one-shot kernels as ``solve`` chooses them or as
``--parts-engine`` says.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import shortest_path

from warerover_phys.problems.movingai import read_map, read_scen
from warerover_phys.validate import validate_states

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
MAP_NAME = "warehouse-10-20-10-2-1"
MAP_PATH = DATA / f"{MAP_NAME}.map"
DEFAULT_AGENTS = [100, 200, 400, 700, 1000]
DEFAULT_SCENS = [1]
QUICK_AGENTS = [100, 400]
MODES = ["first", "refined"]
MAX_CONFLICTS = 1000
"""Validator cap: a plan with this many conflicts is reported as ``1000+``."""
LACAM3_SRC = ROOT.parent / "shared" / "reference" / "lacam3"
LACAM3_BUILD = ROOT / "build" / "lacam3"

Cell = tuple[int, int]


def scen_path(k: int) -> Path:
    return DATA / f"{MAP_NAME}-random-{k}.scen"


# ----------------------------------------------------------------------------- measuring


def distances_to_goals(obstacles: np.ndarray, starts: list[Cell], goals: list[Cell]) -> list[int]:
    """4-connected shortest-path length from each start to its goal (BFS via scipy); -1 if
    unreachable. Independent of both planners."""
    rows, cols = obstacles.shape
    free = ~obstacles
    idx = np.arange(rows * cols).reshape(rows, cols)
    right = free[:, :-1] & free[:, 1:]
    down = free[:-1, :] & free[1:, :]
    a = np.concatenate([idx[:, :-1][right], idx[:-1, :][down]])
    b = np.concatenate([idx[:, 1:][right], idx[1:, :][down]])
    graph = coo_matrix((np.ones(2 * len(a)), (np.concatenate([a, b]), np.concatenate([b, a]))),
                       shape=(rows * cols, rows * cols)).tocsr()
    goal_nodes = sorted({r * cols + c for r, c in goals})
    row_of = {g: i for i, g in enumerate(goal_nodes)}
    dist = shortest_path(graph, directed=False, unweighted=True, indices=goal_nodes)
    out = []
    for (sr, sc), (gr, gc) in zip(starts, goals, strict=True):
        d = dist[row_of[gr * cols + gc], sr * cols + sc]
        out.append(int(d) if np.isfinite(d) else -1)
    return out


def plan_figures(paths: list[list[Cell]], goals: list[Cell]) -> tuple[int, int]:
    """(sum of costs, makespan): an agent's cost is the tick it reaches its goal for good
    (paths shorter than the longest wait at their last cell)."""
    soc = makespan = 0
    for path, goal in zip(paths, goals, strict=True):
        t = len(path) - 1
        if path[t] == goal:
            while t > 0 and path[t - 1] == goal:
                t -= 1
        else:
            t = len(path)  # never arrives: counted as the whole path (the plan is invalid)
        soc += t
        makespan = max(makespan, t)
    return soc, makespan


def check_plan(paths: list[list[Cell]], starts: list[Cell], goals: list[Cell],
               obstacles: np.ndarray) -> dict:
    """Validate ``paths`` with :func:`validate_states`; also check endpoints."""
    cols = obstacles.shape[1]
    n = len(starts)
    if len(paths) != n:
        return {"conflicts": None, "conflict_kinds": {}, "endpoints_ok": False,
                "check_note": f"{len(paths)} paths for {n} agents", "validate_s": 0.0}
    bad_start = sum(1 for p, s in zip(paths, starts, strict=True) if not p or tuple(p[0]) != s)
    bad_goal = sum(1 for p, g in zip(paths, goals, strict=True) if not p or tuple(p[-1]) != g)
    trajectories = {i: [(r * cols + c, r * cols + c) for r, c in p] for i, p in enumerate(paths)}
    t0 = time.perf_counter()
    conflicts = validate_states(trajectories, obstacles, max_conflicts=MAX_CONFLICTS)
    validate_s = time.perf_counter() - t0
    kinds: dict[str, int] = {}
    for c in conflicts:
        kinds[c.kind] = kinds.get(c.kind, 0) + 1
    note = ""
    if bad_start or bad_goal:
        note = f"{bad_start} paths off their start, {bad_goal} off their goal"
    return {"conflicts": len(conflicts), "conflict_kinds": kinds,
            "conflicts_capped": len(conflicts) >= MAX_CONFLICTS,
            "first_conflicts": [str(c) for c in conflicts[:3]],
            "endpoints_ok": not (bad_start or bad_goal), "check_note": note,
            "validate_s": validate_s}


def finish_run(run: dict, paths: list[list[Cell]] | None, starts: list[Cell], goals: list[Cell],
               obstacles: np.ndarray) -> dict:
    """Fill in validation, costs and the success flag of a run that returned ``paths``."""
    if paths is None:
        run.update(success=False, conflicts=None, sum_of_costs=None, makespan=None,
                   soc_ratio=None)
        return run
    paths = [[tuple(c) for c in p] for p in paths]
    run.update(check_plan(paths, starts, goals, obstacles))
    soc, makespan = plan_figures(paths, goals)
    lb = run["lower_bound"]
    run.update(sum_of_costs=soc, makespan=makespan, soc_ratio=soc / lb if lb else 1.0,
               plan_len=max((len(p) for p in paths), default=0))
    run["success"] = bool(run["solved"] and run["conflicts"] == 0 and run["endpoints_ok"])
    if run["solved"] and not run["success"]:
        run["status"] = "invalid"
    return run


# ----------------------------------------------------------------------------- plan files


_STEP = re.compile(r"^(\d+):(.*)$")
_CELL = re.compile(r"\((-?\d+),(-?\d+)\)")


def read_plan_file(path: Path) -> tuple[dict[str, str], list[list[Cell]] | None]:
    """(header ``key=value`` pairs, per-agent (row, col) paths) of a ``t:(x,y),...`` plan
    (x = column); paths None when the file has no ``solution=`` section or no steps."""
    header: dict[str, str] = {}
    steps: list[list[Cell]] = []
    in_solution = False
    for line in path.read_text(encoding="utf-8").splitlines():
        line = line.strip()
        if not line:
            continue
        if not in_solution:
            if line == "solution=":
                in_solution = True
            elif "=" in line:
                key, _, value = line.partition("=")
                header[key] = value
            continue
        m = _STEP.match(line)
        if m is None:
            break
        if int(m.group(1)) != len(steps):
            raise ValueError(f"{path}: timestep {m.group(1)} out of order")
        steps.append([(int(y), int(x)) for x, y in _CELL.findall(m.group(2))])
    if not steps:
        return header, None
    n = len(steps[0])
    if any(len(q) != n for q in steps):
        raise ValueError(f"{path}: timesteps with different agent counts")
    return header, [[q[i] for q in steps] for i in range(n)]


# ----------------------------------------------------------------------------- the two sides


def our_command(n: int, scen: Path, mode: str, time_limit: float, seed: int, guide: bool,
                out: Path) -> list[str]:
    cmd = [sys.executable, "-m", "warerover_phys", "solve", str(MAP_PATH), str(scen),
           "--agents", str(n), "--planner", "lacam", "--time-limit", f"{time_limit:g}",
           "--seed", str(seed), "--json", "--out", str(out)]
    if not guide:
        cmd.append("--no-guide")
    if mode == "refined":
        cmd.append("--refine")
    return cmd


def lacam3_command(binary: Path, n: int, scen: Path, mode: str, time_limit: float, seed: int,
                   out: Path) -> list[str]:
    cmd = [str(binary), "-m", str(MAP_PATH), "-i", str(scen), "-N", str(n),
           "-t", str(max(1, math.ceil(time_limit))), "-s", str(seed), "-v", "0",
           "-o", str(out)]
    if mode == "first":
        cmd.append("--no-star")
    return cmd


def _children_cpu() -> float:
    """CPU seconds (user + system) of the child processes waited for so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_process(cmd: list[str], out: Path, timeout: float, env: dict | None = None,
                ) -> tuple[dict, list[list[Cell]] | None]:
    """Run ``cmd`` (it writes its plan to ``out``); the whole process is timed, in wall
    time and in CPU time (user + system, of the process and anything it waited for)."""
    t0 = time.perf_counter()
    cpu0 = _children_cpu()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"solved": False, "status": f"timeout (killed at {timeout:g} s)",
                "process_s": time.perf_counter() - t0}, None
    wall = time.perf_counter() - t0
    info: dict = {"process_s": wall, "process_cpu_s": _children_cpu() - cpu0,
                  "returncode": proc.returncode}
    try:
        info["stdout_json"] = json.loads(proc.stdout)
    except ValueError:
        pass
    if not out.exists():
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
        info.update(solved=False, status=f"no plan (exit {proc.returncode})", stderr_tail=tail)
        return info, None
    header, paths = read_plan_file(out)
    info["header"] = header
    solved = header.get("solved") == "1" and paths is not None
    info.update(solved=solved, status="solved" if solved else "unsolved")
    if "comp_time" in header:
        info["solver_s"] = float(header["comp_time"]) / 1000.0
    stderr = [ln for ln in proc.stderr.splitlines() if ln.startswith("refine:")]
    if stderr:
        info["improvements"] = len(stderr)
    return info, paths


def find_lacam3(given: str | None, src: Path) -> tuple[Path | None, str]:
    """The lacam3 binary and how it was found, or (None, why not)."""
    given = given or os.environ.get("WARERO_LACAM3")
    if given:
        p = Path(given)
        if p.is_file() and os.access(p, os.X_OK):
            return p, f"lacam3: {p} (given)"
        return None, f"lacam3 SKIPPED: {p} is not an executable file"
    binary = LACAM3_BUILD / "main"
    if binary.is_file():
        return binary, f"lacam3: {binary} (built before)"
    missing = [tool for tool in ("cmake", "g++") if shutil.which(tool) is None]
    if missing:
        return None, (f"lacam3 SKIPPED: {' and '.join(missing)} not found; both are needed to "
                      f"build {src} (or give --lacam3 PATH / $WARERO_LACAM3)")
    if not (src / "CMakeLists.txt").is_file():
        return None, f"lacam3 SKIPPED: no sources at {src} (give --lacam3-src or --lacam3)"
    print(f"building lacam3 from {src} into {LACAM3_BUILD} (cmake + g++) ...", flush=True)
    for cmd in (["cmake", "-S", str(src), "-B", str(LACAM3_BUILD),
                 "-DCMAKE_BUILD_TYPE=Release"],
                ["make", "-C", str(LACAM3_BUILD), f"-j{os.cpu_count() or 1}"]):
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            tail = " | ".join((proc.stderr or proc.stdout).strip().splitlines()[-3:])
            return None, f"lacam3 SKIPPED: `{' '.join(cmd)}` failed: {tail}"
    if not binary.is_file():
        return None, f"lacam3 SKIPPED: the build left no {binary}"
    return binary, f"lacam3: {binary} (built now)"


# ----------------------------------------------------------------------------- report

COLUMNS = [("impl", "impl", "{}"), ("mode", "mode", "{}"), ("scen", "scen", "{}"),
           ("N", "agents", "{}"), ("ok", "ok", "{}"), ("status", "status", "{}"),
           ("SoC", "sum_of_costs", "{}"), ("LB", "lower_bound", "{}"),
           ("SoC/LB", "soc_ratio", "{:.3f}"), ("makespan", "makespan", "{}"),
           ("process s", "process_s", "{:.2f}"), ("CPU s", "process_cpu_s", "{:.2f}"),
           ("solver s", "solver_s", "{:.2f}"),
           ("conflicts", "conflicts_str", "{}"), ("load", "load_1min", "{:.1f}")]

COMPARE_COLUMNS = [("scen", "scen", "{}"), ("N", "agents", "{}"), ("mode", "mode", "{}"),
                   ("ours SoC/LB", "ours_soc_ratio", "{:.3f}"),
                   ("lacam3 SoC/LB", "lacam3_soc_ratio", "{:.3f}"),
                   ("SoC ours/lacam3", "soc_ours_over_lacam3", "{:.3f}"),
                   ("ours s", "ours_process_s", "{:.2f}"), ("lacam3 s", "lacam3_process_s",
                                                            "{:.2f}"),
                   ("wall ours/lacam3", "wall_ours_over_lacam3", "{:.2f}"),
                   ("ours CPU s", "ours_process_cpu_s", "{:.2f}"),
                   ("lacam3 CPU s", "lacam3_process_cpu_s", "{:.2f}"),
                   ("CPU ours/lacam3", "cpu_ours_over_lacam3", "{:.2f}")]


def _cell(row: dict, key: str, fmt: str) -> str:
    value = row.get(key)
    if value is None:
        return "-"
    return fmt.format(value)


def print_table(title: str, rows: list[dict], columns) -> None:
    head = [h for h, _, _ in columns]
    body = [[_cell(r, key, fmt) for _, key, fmt in columns] for r in rows]
    widths = [max(len(h), *(len(b[i]) for b in body)) if body else len(h)
              for i, h in enumerate(head)]
    print(f"\n{title}")
    print("  ".join(h.rjust(w) for h, w in zip(head, widths, strict=True)))
    for b in body:
        print("  ".join(c.rjust(w) for c, w in zip(b, widths, strict=True)))


def _display(run: dict) -> dict:
    row = dict(run)
    row["scen"] = f"random-{run['scen']}"
    row["ok"] = "yes" if run.get("success") else "no"
    c = run.get("conflicts")
    row["conflicts_str"] = None if c is None else (f"{c}+" if run.get("conflicts_capped") else c)
    return row


def compare(runs: list[dict]) -> list[dict]:
    """Per (scenario, N, mode): ours beside lacam3, ratios over successful runs."""
    out = []
    keys = dict.fromkeys((r["scen"], r["agents"], r["mode"]) for r in runs)
    for k, n, mode in keys:
        side = {r["impl"]: r for r in runs
                if (r["scen"], r["agents"], r["mode"]) == (k, n, mode)}
        ours, theirs = side.get("ours"), side.get("lacam3")
        row = {"scen": f"random-{k}", "agents": n, "mode": mode}
        for name, r in (("ours", ours), ("lacam3", theirs)):
            if r is not None:
                row[f"{name}_success"] = r.get("success")
                row[f"{name}_sum_of_costs"] = r.get("sum_of_costs") if r.get("success") else None
                row[f"{name}_soc_ratio"] = r.get("soc_ratio") if r.get("success") else None
                row[f"{name}_process_s"] = r.get("process_s")
                row[f"{name}_process_cpu_s"] = r.get("process_cpu_s")
        if ours and theirs and ours.get("success") and theirs.get("success"):
            row["soc_ours_over_lacam3"] = ours["sum_of_costs"] / theirs["sum_of_costs"]
            row["wall_ours_over_lacam3"] = ours["process_s"] / theirs["process_s"]
            if ours.get("process_cpu_s") and theirs.get("process_cpu_s"):
                row["cpu_ours_over_lacam3"] = ours["process_cpu_s"] / theirs["process_cpu_s"]
        out.append(row)
    return out


def machine_info() -> dict:
    info = {"platform": platform.platform(), "machine": platform.machine(),
            "python": platform.python_version(), "cpu_count": os.cpu_count(),
            "numpy": np.__version__}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                info["cpu_model"] = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        info["git_commit"] = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True,
            timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        info["git_commit"] = None
    return info


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, str | int | float | bool) or obj is None:
        return obj
    return repr(obj)


# ----------------------------------------------------------------------------- main


WARM_UP = ("import sys\n"
           "from warerover_phys.planning.oneshot.scatter import NUMBA_MIN_AGENTS\n"
           "if int(sys.argv[1]) < NUMBA_MIN_AGENTS:\n"
           "    print('skipped')\n"
           "else:\n"
           "    from warerover_phys.planning.oneshot.core import warm_up\n"
           "    print(warm_up())\n")
"""Compiles (cold cache) or loads our one-shot numba kernels where ``solve`` would use them
for ``argv[1]`` agents (in the checkout measured: its own constant); prints the CPU seconds
or ``skipped``."""


def warm_up(max_agents: int, env: dict) -> str | None:
    """Run :data:`WARM_UP`; a line to print and note, or None when it was not needed."""
    proc = subprocess.run([sys.executable, "-c", WARM_UP, str(max_agents)],
                          capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        return f"numba warm-up failed: {proc.stderr.strip()[-300:]}"
    if proc.stdout.split()[-1] == "skipped":
        return None
    return (f"numba kernels warmed up: {float(proc.stdout.split()[-1]):.2f} s of CPU "
            "(a compile where the cache was cold)")

PARTS_SCRIPT = r"""
import json, sys, time
cpu = time.process_time
parts = {"interpreter": cpu()}
c = cpu()
import numpy as np
from warerover_phys.problems.movingai import read_map, read_scen
from warerover_phys.planning.oneshot import scatter
from warerover_phys.planning.lacam.reference import _to_paths, lacam_nodes
from warerover_phys.planning.oneshot.core import OneShotResult, _costs, goal_tables, grid_graph, write_plan
from warerover_phys.validate import validate_cell_paths
parts["imports"] = cpu() - c
map_file, scen_file, n, seed, engine, out = sys.argv[1:]
n, seed = int(n), int(seed)
c = cpu()
grid = read_map(map_file)
scen = read_scen(scen_file, n, grid)
graph = grid_graph(grid.obstacles)
parts["read map + scen, grid graph"] = cpu() - c
import gc
gc.freeze()
gc.set_threshold(50_000, 50, 100)
c = cpu()
if engine == "auto":
    engine = "numba" if scatter.use_numba(n, None) else "python"
if engine == "numba":
    from warerover_phys.cli.solve import numba_without_blas_probe
    numba_without_blas_probe()
parts["numba import"] = cpu() - c
goals = [a.goal for a in scen]
c = cpu()
tables = goal_tables(graph, goals, engine=engine)
parts["distance tables (+ numba's first load)"] = cpu() - c
s = [graph.node(a.start) for a in scen]
g = [graph.node(x) for x in goals]
c = cpu()
dists = tables if engine == "numba" else [t.tolist() for t in tables]
parts["tables as lists"] = cpu() - c
c = cpu()
rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
guide = scatter.guide_paths(graph.neighbors, s, g, dists, rng, engine=engine, arrays=tables)
parts["guide paths (+ load)"] = cpu() - c
c = cpu()
configs, stats = lacam_nodes(graph, s, g, dists, time.monotonic() + 1e9,
                             np.random.default_rng(seed), guide=guide.next, engine=engine)
parts["LaCAM (+ load)"] = cpu() - c
c = cpu()
paths = _to_paths(graph, configs)
soc, makespan = _costs(paths, goals)
parts["paths + costs"] = cpu() - c
c = cpu()
conflicts = validate_cell_paths(paths, grid.obstacles)  # as solve does
parts["validation"] = cpu() - c
c = cpu()
write_plan(out, OneShotResult(True, paths, soc, makespan, 0, 0.0, "lacam"))
parts["plan file"] = cpu() - c
parts["total"] = cpu()
print(json.dumps({"engine": engine, "soc": soc, "conflicts": len(conflicts), "parts": parts}))
"""
"""Our whole ``solve --planner lacam`` (random-k, first solution) as separate parts in a
fresh interpreter, each part's CPU time (``--parts``); the interpreter's own start-up is the
CPU time already spent when the script starts."""


def run_parts(counts: list[int], scens: list[int], seed: int, engine: str,
              env: dict) -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_mapf_parts_") as tmp:
        for k in scens:
            for n in counts:
                cmd = [sys.executable, "-c", PARTS_SCRIPT, str(MAP_PATH), str(scen_path(k)),
                       str(n), str(seed), engine, str(Path(tmp) / "plan.txt")]
                load = os.getloadavg()[0]
                proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
                if proc.returncode != 0:
                    raise SystemExit(f"--parts N={n}: {proc.stderr.strip()[-500:]}")
                out = json.loads(proc.stdout.strip().splitlines()[-1])
                rows.append({"scen": k, "agents": n, "load_1min": load, **out})
    return rows


def print_parts(rows: list[dict]) -> None:
    names = list(rows[0]["parts"]) if rows else []
    head = ["part, CPU s"] + [f"N={r['agents']} ({r['engine']})" for r in rows]
    table = [[name] + [f"{r['parts'][name]:.3f}" for r in rows] for name in names]
    table.append(["SoC, conflicts"] + [f"{r['soc']}, {r['conflicts']}" for r in rows])
    table.append(["load (1 min)"] + [f"{r['load_1min']:.2f}" for r in rows])
    widths = [max(len(str(x)) for x in col) for col in zip(head, *table, strict=True)]
    for line in [head, *table]:
        print("  ".join(str(x).rjust(w) for x, w in zip(line, widths, strict=True)))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--agents", type=int, nargs="+", default=None,
                        help=f"agent counts (default: {' '.join(map(str, DEFAULT_AGENTS))}; "
                             f"--quick: {' '.join(map(str, QUICK_AGENTS))})")
    parser.add_argument("--scens", type=int, nargs="+", default=DEFAULT_SCENS,
                        choices=[1, 2, 3], help="random scenario numbers (default: 1)")
    parser.add_argument("--modes", nargs="+", default=MODES, choices=MODES,
                        help="first solution and/or refined (default: both)")
    parser.add_argument("--time-limit", type=float, default=60.0,
                        help="seconds for a first solution (default: %(default)s)")
    parser.add_argument("--refine-time", type=float, default=30.0,
                        help="seconds of the refined mode, both sides (default: %(default)s)")
    parser.add_argument("--grace", type=float, default=30.0,
                        help="a process is killed at its limit + grace seconds "
                             "(default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="seed, both sides (default: 0)")
    parser.add_argument("--no-guide", action="store_true",
                        help="our side without guide paths")
    parser.add_argument("--no-ours", action="store_true", help="leave our side out")
    parser.add_argument("--no-lacam3", action="store_true", help="leave lacam3 out")
    parser.add_argument("--lacam3", default=None,
                        help="lacam3 binary (default: $WARERO_LACAM3, else build it)")
    parser.add_argument("--lacam3-src", type=Path, default=LACAM3_SRC,
                        help="lacam3 sources to build (default: ../shared/reference/lacam3)")
    parser.add_argument("--quick", action="store_true",
                        help=f"N = {' '.join(map(str, QUICK_AGENTS))} (unless --agents)")
    parser.add_argument("--json", type=Path, default=ROOT / "tools" / "out" / "bench_mapf.json",
                        help="where to write the figures (default: tools/out/bench_mapf.json)")
    parser.add_argument("--no-warm-up", action="store_true",
                        help="do not fill numba's cache of the one-shot kernels first (a cold "
                             "cache makes solve run Python unless 150 s are left)")
    parser.add_argument("--parts", type=int, nargs="+", default=None, metavar="N",
                        help="instead of the comparison: our first solution's parts (CPU s "
                             "each, a fresh interpreter per N)")
    parser.add_argument("--parts-engine", default="auto", choices=["auto", "numba", "python"],
                        help="--parts: the engine of the one-shot kernels (default: auto, "
                             "as solve chooses)")
    args = parser.parse_args(argv)
    agents = sorted(set(args.agents or (QUICK_AGENTS if args.quick else DEFAULT_AGENTS)))
    if args.parts:
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
        if not args.no_warm_up and args.parts_engine != "python":
            msg = warm_up(max(args.parts), env)
            if msg is not None:
                print(msg)
        rows = run_parts(args.parts, args.scens, args.seed, args.parts_engine, env)
        print(f"our first solution by parts ({MAP_NAME}, random-{args.scens}, seed {args.seed})")
        print_parts(rows)
        print(f"load average now: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        return 0

    grid = read_map(MAP_PATH)
    obstacles = np.asarray(grid.obstacles, dtype=bool)
    print(f"map {MAP_PATH.relative_to(ROOT)}: {grid.rows} x {grid.cols}, "
          f"{int((~obstacles).sum())} free cells; scens {args.scens}, N {agents}, modes "
          f"{args.modes} (first: limit {args.time_limit:g} s; refined: {args.refine_time:g} s)",
          flush=True)
    notes: list[str] = []
    lacam3 = None
    if args.no_lacam3:
        notes.append("lacam3 left out (--no-lacam3)")
    else:
        lacam3, msg = find_lacam3(args.lacam3, args.lacam3_src)
        print(msg, flush=True)
        if lacam3 is None:
            notes.append(msg)
    sides = ([] if args.no_ours else ["ours"]) + ([] if lacam3 is None else ["lacam3"])
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)

    if "ours" in sides and not args.no_warm_up:
        # solve compiles its numba kernels only with time to spare (a cold cache costs
        # 20-30 s of CPU once): fill the cache first, so that the runs time the steady state
        msg = warm_up(max(agents), env)
        if msg is not None:
            print(msg, flush=True)
            notes.append(msg)

    runs: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="bench_mapf_") as tmp:
        for k in args.scens:
            scen = scen_path(k)
            agents_all = read_scen(scen, max(agents), grid)
            all_starts = [a.start for a in agents_all]
            all_goals = [a.goal for a in agents_all]
            dists = distances_to_goals(obstacles, all_starts, all_goals)
            for n in agents:
                starts, goals = all_starts[:n], all_goals[:n]
                lb = sum(dists[:n])
                for mode in args.modes:
                    limit = args.time_limit if mode == "first" else args.refine_time
                    for impl in sides:
                        out = Path(tmp) / f"{impl}-{k}-{n}-{mode}.txt"
                        if impl == "ours":
                            cmd = our_command(n, scen, mode, limit, args.seed,
                                              not args.no_guide, out)
                        else:
                            cmd = lacam3_command(lacam3, n, scen, mode, limit, args.seed, out)
                        print(f"  {impl} {mode} random-{k} N={n} ...", file=sys.stderr,
                              flush=True)
                        load = os.getloadavg()[0]
                        info, paths = run_process(cmd, out, limit + args.grace, env)
                        run = {"impl": impl, "mode": mode, "scen": k, "agents": n,
                               "lower_bound": lb, "time_limit_s": limit, "command": cmd,
                               "load_1min": load, **info}
                        finish_run(run, paths, starts, goals, obstacles)
                        print(f"    -> {run['status']}, ok={run['success']}, "
                              f"process {run['process_s']:.2f} s"
                              + (f", SoC/LB {run['soc_ratio']:.3f}" if run.get("soc_ratio")
                                 else ""), file=sys.stderr, flush=True)
                        runs.append(run)

    comparison = compare(runs)
    if runs:
        print_table(f"per run ({MAP_NAME}; process s = whole process, as a user waits)",
                    [_display(r) for r in runs], COLUMNS)
        print_table("ours / lacam3 (SoC of valid plans; whole-process wall times)",
                    comparison, COMPARE_COLUMNS)
    else:
        print("\nnothing was run")
    for note in notes:
        print(f"note: {note}")
    print(f"load average now: {' '.join(f'{x:.2f}' for x in os.getloadavg())} "
          f"({os.cpu_count()} CPUs)")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    out_json = {"machine": machine_info(),
                "config": {"map": str(MAP_PATH.relative_to(ROOT)),
                           "scens": [str(scen_path(k).relative_to(ROOT)) for k in args.scens],
                           "agents": agents, "modes": args.modes,
                           "time_limit_s": args.time_limit, "refine_time_s": args.refine_time,
                           "seed": args.seed, "guide": not args.no_guide,
                           "lacam3": None if lacam3 is None else str(lacam3),
                           "validator_max_conflicts": MAX_CONFLICTS},
                "notes": notes, "comparison": comparison, "runs": runs}
    args.json.write_text(json.dumps(_jsonable(out_json), indent=2) + "\n", encoding="utf-8")
    print(f"\nwrote {args.json}")
    return 0 if all(r.get("success") for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
