"""Benchmark one-shot MAPF on the MovingAI map warehouse-10-20-10-2-1, side by side with pymapf.

For every planner, scenario (``random-1..3``) and agent count N (the first N agents of the
scenario), solves the instance, rebuilds every agent's per-tick states from the returned paths
and checks them with the project's independent validator
(:func:`warerover_phys.validate.validate_states`). A run counts as a success only if the
planner reports a solution, the validator finds no conflict, and every path starts at its start
and ends at its goal. Sum of costs, makespan and the lower bound (sum of single-agent
shortest-path lengths, 4-connected grid) are recomputed here from the paths, so both sides are
measured the same way.

- Our side: ``warerover_phys.planning.oneshot.solve`` (``--planners``, default ``lacam pibt``),
  called in-process; it honours ``--time-limit`` itself.
- pymapf side: the PyPI package ``pymapf`` (not a project dependency; install it with
  ``.venv/bin/pip install pymapf``), its ``LaCAM`` and ``PIBT`` solvers (``--pymapf-planners``).
  Each run happens in a child process that is killed at ``--time-limit`` + ``--grace``
  seconds. pymapf uses ``(row, col)`` cells like this project; the script checks that on a
  small asymmetric grid before the benchmark. Left out with ``--no-pymapf`` or when pymapf is
  not installed.

Data: ``tests/data/warehouse-10-20-10-2-1.map`` and ``...-random-{1,2,3}.scen`` (unmodified
MovingAI benchmark files). A planner that runs out of time on N agents of a scenario is not
run on the larger N of that scenario (status ``skipped``; ``--no-skip`` runs them anyway: the
first N agents are a subset of the first N' > N). Prints one row per run, then per-N
aggregates over the scenarios, and writes everything, with machine info, as JSON (default
``tools/out/bench_mapf.json``).

    .venv/bin/python tools/bench_mapf.py --quick            # N = 100 200 400, random-1 only
    .venv/bin/python tools/bench_mapf.py                    # N = 100 ... 1000, random-1..3
    .venv/bin/python tools/bench_mapf.py --agents 100 200 --scens 1 2 --planners lacam --no-pymapf
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import multiprocessing as mp
import os
import platform
import subprocess
import sys
import time
import traceback
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import shortest_path

from warerover_phys.movingai import read_map, read_scen
from warerover_phys.validate import validate_states

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
MAP_NAME = "warehouse-10-20-10-2-1"
MAP_PATH = DATA / f"{MAP_NAME}.map"
DEFAULT_AGENTS = [100, 200, 400, 700, 1000]
DEFAULT_SCENS = [1, 2, 3]
QUICK_AGENTS = [100, 200, 400]
QUICK_SCENS = [1]
PLANNERS = ["lacam", "pibt"]
MAX_CONFLICTS = 1000
"""Validator cap: a plan with this many conflicts is reported as ``1000+``."""
PYMAPF_INSTALL = ".venv/bin/pip install pymapf"

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


# ----------------------------------------------------------------------------- our side


def our_solve_available() -> tuple[bool, str]:
    """Whether ``oneshot.solve`` imports and solves a 3x3 swap; else the reason."""
    try:
        from warerover_phys.planning.oneshot import solve
        free = np.zeros((3, 3), dtype=bool)
        for planner in ("lacam", "pibt"):
            res = solve(free, [(0, 0), (2, 2)], [(2, 2), (0, 0)], planner=planner,
                        time_limit_s=5.0)
            if not res.success:
                return False, f"solve(planner={planner!r}) failed on a 3x3 swap"
    except Exception as exc:
        return False, f"{type(exc).__name__}: {exc}"
    return True, ""


def run_ours(planner: str, obstacles: np.ndarray, starts: list[Cell], goals: list[Cell],
             time_limit: float, seed: int) -> tuple[dict, list[list[Cell]] | None]:
    from warerover_phys.planning.oneshot import solve
    t0 = time.perf_counter()
    try:
        res = solve(obstacles, starts, goals, planner=planner, time_limit_s=time_limit,
                    seed=seed)
    except Exception as exc:
        wall = time.perf_counter() - t0
        return {"solved": False, "status": f"error: {type(exc).__name__}: {exc}",
                "wall_s": wall}, None
    wall = time.perf_counter() - t0
    info = {"solved": bool(res.success),
            "status": "solved" if res.success else _fail_status(wall, time_limit),
            "wall_s": wall, "solver_wall_s": res.wall_s, "reported_soc": res.sum_of_costs,
            "reported_makespan": res.makespan, "reported_lower_bound": res.lower_bound,
            "stats": _jsonable(res.stats)}
    return info, (res.paths if res.success else None)


def _fail_status(wall: float, time_limit: float) -> str:
    """Status of a run whose planner returned no solution."""
    return "fail (time limit)" if wall >= time_limit else "fail (gave up)"


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


# ----------------------------------------------------------------------------- pymapf side


def pymapf_status(wanted: list[str]) -> tuple[bool, str, str]:
    """(usable, version, message) for the pymapf planners in ``wanted``."""
    if importlib.util.find_spec("pymapf") is None:
        return False, "", (f"pymapf is not installed; install it with `{PYMAPF_INSTALL}` "
                           "(it is not a project dependency). pymapf side skipped.")
    try:
        import pymapf
    except Exception as exc:
        return False, "", f"pymapf does not import ({type(exc).__name__}: {exc}); skipped."
    version = getattr(pymapf, "__version__", "?")
    have = set(pymapf.available_solvers()) if hasattr(pymapf, "available_solvers") else set()
    missing = [p for p in wanted if p not in have]
    if missing:
        return False, version, (f"pymapf {version} has no solver named {', '.join(missing)} "
                                f"(it has: {', '.join(sorted(have)) or 'none'}); skipped.")
    ok, msg = _check_pymapf_convention()
    if not ok:
        return False, version, f"pymapf {version}: {msg}; skipped."
    return True, version, f"pymapf {version}: {msg}"


def _check_pymapf_convention() -> tuple[bool, str]:
    """Check on a 3x5 grid with a wall in the middle row that pymapf reads cells as
    (row, col): the wall is blocked, paths start at the starts and never enter the wall."""
    import pymapf
    obstacles = np.zeros((3, 5), dtype=bool)
    obstacles[1, 1:4] = True
    grid = pymapf.GridMap(obstacles)
    if (grid.height, grid.width) != (3, 5) or grid.is_free((1, 2)) or not grid.is_free((0, 4)):
        return False, "GridMap does not index obstacles as [row][col]"
    starts, goals = [(0, 0), (2, 4)], [(2, 4), (0, 0)]
    for name in ("lacam", "pibt"):
        problem = pymapf.MAPFProblem(grid, [pymapf.Agent(str(i), s, g) for i, (s, g)
                                            in enumerate(zip(starts, goals, strict=True))])
        sol = pymapf.solve(problem, name, time_limit=10.0)
        if sol is None:
            return False, f"{name} failed on the 3x5 convention check"
        paths = [sol.paths[str(i)] for i in range(2)]
        if [tuple(p[0]) for p in paths] != starts or [tuple(p[-1]) for p in paths] != goals:
            return False, f"{name} paths do not start/end at the (row, col) starts/goals"
        if any(obstacles[r, c] for p in paths for r, c in p):
            return False, f"{name} paths cross the wall read as (row, col)"
    return True, "cells are (row, col), checked on a 3x5 grid"


def _pymapf_child(conn, planner: str, obstacles: np.ndarray, starts: list[Cell],
                  goals: list[Cell], time_limit: float, seed: int) -> None:
    """Child process: solve with pymapf, send (status, paths, wall_s, info) back."""
    try:
        import pymapf
        grid = pymapf.GridMap(obstacles)
        problem = pymapf.MAPFProblem(grid, [pymapf.Agent(str(i), s, g) for i, (s, g)
                                            in enumerate(zip(starts, goals, strict=True))])
        if planner == "lacam":
            # The expansion cap is lifted so that only the time limit ends the search.
            solver = pymapf.LaCAM(time_limit=time_limit, max_expansions=10**12, seed=seed)
        else:
            solver = pymapf.PIBT(time_limit=time_limit, seed=seed)
        t0 = time.perf_counter()
        sol = solver.solve(problem)
        wall = time.perf_counter() - t0
        if sol is None:
            conn.send((_fail_status(wall, time_limit), None, wall, {}))
        else:
            paths = [list(sol.paths[str(i)]) for i in range(len(starts))]
            conn.send(("solved", paths, wall, {"expansions": sol.expansions,
                                               "pymapf_soc": sol.sum_of_costs,
                                               "pymapf_makespan": sol.makespan}))
    except Exception as exc:
        conn.send((f"error: {type(exc).__name__}: {exc}", None, 0.0,
                   {"traceback": traceback.format_exc()}))
    finally:
        conn.close()


def run_pymapf(planner: str, obstacles: np.ndarray, starts: list[Cell], goals: list[Cell],
               time_limit: float, grace: float, seed: int
               ) -> tuple[dict, list[list[Cell]] | None]:
    ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_pymapf_child, daemon=True,
                       args=(child, planner, obstacles, starts, goals, time_limit, seed))
    t0 = time.perf_counter()
    proc.start()
    child.close()
    hard = time_limit + grace
    msg = None
    try:
        if parent.poll(hard):
            msg = parent.recv()
    except EOFError:
        msg = None
    elapsed = time.perf_counter() - t0
    if proc.is_alive():
        proc.join(timeout=2.0)
    if proc.is_alive():
        proc.kill()
        proc.join()
    parent.close()
    if msg is None:
        status = (f"timeout (killed at {hard:g} s)" if elapsed >= hard
                  else f"child died (exit code {proc.exitcode})")
        return {"solved": False, "status": status, "wall_s": elapsed}, None
    status, paths, wall, info = msg
    run = {"solved": status == "solved", "status": status, "wall_s": wall,
           "process_s": elapsed, **_jsonable(info)}
    return run, paths


# ----------------------------------------------------------------------------- report

COLUMNS = [("impl", "impl", "{}"), ("planner", "planner", "{}"), ("scen", "scen", "{}"),
           ("N", "agents", "{}"), ("ok", "ok", "{}"), ("status", "status", "{}"),
           ("SoC", "sum_of_costs", "{}"), ("LB", "lower_bound", "{}"),
           ("SoC/LB", "soc_ratio", "{:.3f}"), ("makespan", "makespan", "{}"),
           ("wall s", "wall_s", "{:.2f}"), ("conflicts", "conflicts_str", "{}")]

SUMMARY_COLUMNS = [("impl", "impl", "{}"), ("planner", "planner", "{}"), ("N", "agents", "{}"),
                   ("solved", "solved_str", "{}"), ("SoC/LB mean", "soc_ratio_mean", "{:.3f}"),
                   ("SoC/LB max", "soc_ratio_max", "{:.3f}"),
                   ("makespan mean", "makespan_mean", "{:.1f}"),
                   ("wall s mean", "wall_s_mean", "{:.2f}"), ("wall s max", "wall_s_max",
                                                             "{:.2f}")]


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


def summarise(runs: list[dict]) -> list[dict]:
    """Per (impl, planner, N): successes and means over the scenarios (ratios and makespans
    over successful runs only; wall times over every run that was not skipped)."""
    groups: dict[tuple[str, str, int], list[dict]] = {}
    for r in runs:
        groups.setdefault((r["impl"], r["planner"], r["agents"]), []).append(r)
    out = []
    for (impl, planner, n), rs in groups.items():
        done = [r for r in rs if r["status"] != "skipped"]
        ok = [r for r in done if r.get("success")]
        walls = [r["wall_s"] for r in done if r.get("wall_s") is not None]
        ratios = [r["soc_ratio"] for r in ok]
        out.append({
            "impl": impl, "planner": planner, "agents": n, "scens": [r["scen"] for r in rs],
            "runs": len(done), "skipped": len(rs) - len(done), "solved": len(ok),
            "solved_str": f"{len(ok)}/{len(rs)}",
            "soc_ratio_mean": float(np.mean(ratios)) if ratios else None,
            "soc_ratio_max": float(np.max(ratios)) if ratios else None,
            "sum_of_costs_mean": float(np.mean([r["sum_of_costs"] for r in ok])) if ok else None,
            "makespan_mean": float(np.mean([r["makespan"] for r in ok])) if ok else None,
            "wall_s_mean": float(np.mean(walls)) if walls else None,
            "wall_s_max": float(np.max(walls)) if walls else None,
        })
    return out


def machine_info() -> dict:
    info = {"platform": platform.platform(), "machine": platform.machine(),
            "processor": platform.processor(), "python": platform.python_version(),
            "cpu_count": os.cpu_count(), "numpy": np.__version__}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                info["cpu_model"] = line.split(":", 1)[1].strip()
                break
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                info["mem_total_gib"] = round(int(line.split()[1]) / 2**20, 1)
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


# ----------------------------------------------------------------------------- main


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--agents", type=int, nargs="+", default=None,
                        help=f"agent counts (default: {' '.join(map(str, DEFAULT_AGENTS))}; "
                             f"--quick: {' '.join(map(str, QUICK_AGENTS))})")
    parser.add_argument("--scens", type=int, nargs="+", default=None, choices=DEFAULT_SCENS,
                        help="random scenario numbers (default: 1 2 3; --quick: 1)")
    parser.add_argument("--planners", nargs="*", default=PLANNERS, choices=PLANNERS,
                        help="our planners; give the flag with no names to skip our side "
                             "(default: %(default)s)")
    parser.add_argument("--pymapf-planners", nargs="*", default=PLANNERS, choices=PLANNERS,
                        help="pymapf planners (default: %(default)s)")
    parser.add_argument("--no-pymapf", action="store_true", help="leave pymapf out")
    parser.add_argument("--time-limit", type=float, default=60.0,
                        help="seconds per instance (default: %(default)s)")
    parser.add_argument("--grace", type=float, default=15.0,
                        help="pymapf's child process is killed at time limit + grace seconds "
                             "(default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="planner seed (default: 0)")
    parser.add_argument("--quick", action="store_true",
                        help=f"N = {' '.join(map(str, QUICK_AGENTS))} on random-1 only "
                             "(unless --agents/--scens are given)")
    parser.add_argument("--no-skip", action="store_true",
                        help="also run larger N on a scenario after a planner ran out of "
                             "time on a smaller N there (default: skip them; the agents of N "
                             "are a prefix of those of any larger N)")
    parser.add_argument("--json", type=Path, default=ROOT / "tools" / "out" / "bench_mapf.json",
                        help="where to write the figures (default: tools/out/bench_mapf.json)")
    args = parser.parse_args(argv)
    agents = sorted(set(args.agents or (QUICK_AGENTS if args.quick else DEFAULT_AGENTS)))
    scens = args.scens or (QUICK_SCENS if args.quick else DEFAULT_SCENS)

    grid = read_map(MAP_PATH)
    obstacles = np.asarray(grid.obstacles, dtype=bool)
    print(f"map {MAP_PATH.relative_to(ROOT)}: {grid.rows} x {grid.cols}, "
          f"{int((~obstacles).sum())} free cells; scens {scens}, N {agents}, "
          f"time limit {args.time_limit:g} s", flush=True)

    notes: list[str] = []
    ours = list(dict.fromkeys(args.planners))
    if ours:
        ok, why = our_solve_available()
        if not ok:
            msg = (f"OUR SIDE SKIPPED: warerover_phys.planning.oneshot.solve is not usable "
                   f"({why})")
            print(msg, flush=True)
            notes.append(msg)
            ours = []
    else:
        notes.append("our side not requested (--planners with no names)")
        print(notes[-1])

    theirs = [] if args.no_pymapf else list(dict.fromkeys(args.pymapf_planners))
    pymapf_info = {"requested": bool(theirs), "available": False, "version": None,
                   "message": "left out (--no-pymapf)" if args.no_pymapf else ""}
    if theirs:
        usable, version, msg = pymapf_status(theirs)
        pymapf_info.update(available=usable, version=version or None, message=msg)
        print(("" if usable else "PYMAPF SKIPPED: ") + msg, flush=True)
        if not usable:
            notes.append(msg)
            theirs = []

    plan = [("ours", p) for p in ours] + [("pymapf", p) for p in theirs]
    runs: list[dict] = []
    for k in scens:
        path = scen_path(k)
        scen = read_scen(path, max(agents), grid)
        all_starts = [a.start for a in scen]
        all_goals = [a.goal for a in scen]
        dists = distances_to_goals(obstacles, all_starts, all_goals)
        if min(dists) < 0:
            raise SystemExit(f"{path}: some goal is unreachable from its start")
        failed: set[tuple[str, str]] = set()
        for n in agents:
            starts, goals = all_starts[:n], all_goals[:n]
            lb = sum(dists[:n])
            for impl, planner in plan:
                run = {"impl": impl, "planner": planner, "scen": k, "agents": n,
                       "lower_bound": lb, "time_limit_s": args.time_limit}
                if (impl, planner) in failed and not args.no_skip:
                    run.update(status="skipped", solved=False, success=False, wall_s=None,
                               conflicts=None, sum_of_costs=None, makespan=None,
                               soc_ratio=None,
                               note="ran out of time on a smaller N of this scenario")
                    runs.append(run)
                    continue
                print(f"  {impl} {planner} random-{k} N={n} ...", file=sys.stderr, flush=True)
                if impl == "ours":
                    info, paths = run_ours(planner, obstacles, starts, goals, args.time_limit,
                                           args.seed)
                    if info.get("reported_lower_bound") not in (None, lb):
                        info["lb_mismatch"] = (f"solve() reported lower bound "
                                               f"{info['reported_lower_bound']}, BFS gives {lb}")
                else:
                    info, paths = run_pymapf(planner, obstacles, starts, goals,
                                             args.time_limit, args.grace, args.seed)
                run.update(info)
                finish_run(run, paths, starts, goals, obstacles)
                if run["status"].startswith(("fail (time limit)", "timeout")):
                    failed.add((impl, planner))
                print(f"    -> {run['status']}, ok={run['success']}, wall {run['wall_s']:.2f} s"
                      + (f", SoC/LB {run['soc_ratio']:.3f}" if run.get("soc_ratio") else "")
                      + (f", conflicts {run['conflicts']}" if run.get("conflicts") else ""),
                      file=sys.stderr, flush=True)
                runs.append(run)

    if runs:
        print_table(f"per run ({MAP_NAME}, time limit {args.time_limit:g} s)",
                    [_display(r) for r in runs], COLUMNS)
        summary = summarise(runs)
        print_table("per N over the scenarios (SoC/LB and makespan over solved runs)",
                    summary, SUMMARY_COLUMNS)
    else:
        summary = []
        print("\nnothing was run")
    for note in notes:
        print(f"note: {note}")

    args.json.parent.mkdir(parents=True, exist_ok=True)
    out = {"machine": machine_info(),
           "config": {"map": str(MAP_PATH.relative_to(ROOT)),
                      "scens": [str(scen_path(k).relative_to(ROOT)) for k in scens],
                      "agents": agents, "time_limit_s": args.time_limit,
                      "pymapf_grace_s": args.grace, "seed": args.seed,
                      "our_planners": ours, "pymapf_planners": theirs,
                      "skip_larger_after_timeout": not args.no_skip,
                      "pymapf_lacam_max_expansions": 10**12,
                      "validator_max_conflicts": MAX_CONFLICTS},
           "pymapf": pymapf_info, "notes": notes, "summary": summary, "runs": runs}
    args.json.write_text(json.dumps(_jsonable(out), indent=2) + "\n", encoding="utf-8")
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
