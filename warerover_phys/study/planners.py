"""Getting a study's plan: a built-in one-shot solver, an external command, or a plan file;
then the checks every plan goes through, whatever made it.

:func:`obtain_plan` returns a :class:`PlanOutcome`: the plan (or the error that stopped it,
and at which stage: ``solve``, ``read``, ``validate``) with its figures. Outcomes are kept
in ``DIR/plans/PLAN_ID.npz`` / ``.json`` so that a resumed study reads them back instead of
solving again.
"""

from __future__ import annotations

import json
import math
import os
import shlex
import subprocess
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import WareroverError
from ..plans import Plan
from .cells import PlanTask

__all__ = ["PlanOutcome", "obtain_plan", "check_plan", "COMMAND_GRACE_S"]

COMMAND_GRACE_S = 30.0
"""An external command is killed after its time limit x 2 + this many seconds."""


@dataclass
class PlanOutcome:
    plan: Plan | None
    solve_s: float | None = None
    """Wall seconds the solver took (built-in: the call; command: the process; plan file:
    its ``comp_time`` if it says)."""
    lower_bound: int | None = None
    error: str | None = None
    stage: str | None = None
    stats: dict[str, Any] = field(default_factory=dict)

    def meta(self) -> dict[str, Any]:
        out = asdict(self)
        out.pop("plan")
        return out


# ----------------------------------------------------------------------------- cache


def _cache_paths(task: PlanTask) -> tuple[Path, Path]:
    d = Path(task.out_dir) / "plans"
    return d / f"{task.plan_id}.npz", d / f"{task.plan_id}.json"


def _save(task: PlanTask, out: PlanOutcome) -> None:
    npz, meta = _cache_paths(task)
    npz.parent.mkdir(parents=True, exist_ok=True)
    if out.plan is not None:
        p = out.plan
        horizon = p.makespan + 1
        cells = np.empty((horizon, p.num_agents, 2), dtype=np.int32)
        heads = np.zeros((horizon, p.num_agents), dtype=np.int8)
        for i, path in enumerate(p.paths):
            arr = np.asarray(path, dtype=np.int32).reshape(-1, 2)
            cells[:len(arr), i], cells[len(arr):, i] = arr, arr[-1]
            if p.headings is not None:
                h = np.asarray(p.headings[i], dtype=np.int8)
                heads[:len(h), i], heads[len(h):, i] = h, h[-1]
        tmp = npz.with_suffix(".npz.tmp")
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, cells=cells, headings=heads,
                                has_headings=np.array(p.headings is not None))
        os.replace(tmp, npz)
    tmp = meta.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(out.meta(), default=float) + "\n", encoding="utf-8")
    os.replace(tmp, meta)  # last: the outcome counts once its meta is there


def _load(task: PlanTask) -> PlanOutcome | None:
    npz, meta = _cache_paths(task)
    try:
        data = json.loads(meta.read_text(encoding="utf-8"))
        plan = None
        if data.get("error") is None:
            with np.load(npz) as z:
                cells, heads = z["cells"], z["headings"]
                has = bool(z["has_headings"])
            paths = tuple(tuple(map(tuple, cells[:, i].tolist())) for i in range(cells.shape[1]))
            plan = Plan(paths, headings=tuple(tuple(heads[:, i].tolist())
                                              for i in range(heads.shape[1])) if has else None)
        return PlanOutcome(plan=plan, **{k: data.get(k) for k in
                                         ("solve_s", "lower_bound", "error", "stage", "stats")})
    except (OSError, ValueError, KeyError, TypeError):
        return None


def forget(task: PlanTask) -> None:
    """Drop a kept outcome (``--retry-failed`` solves a failed plan again)."""
    for p in _cache_paths(task):
        p.unlink(missing_ok=True)


# ----------------------------------------------------------------------------- obtain


def obtain_plan(task: PlanTask) -> PlanOutcome:
    """The task's plan, checked (:func:`check_plan`): kept from an earlier run, or made now
    and kept. Never raises for a bad plan or a failing solver: the outcome carries it."""
    kept = _load(task)
    if kept is not None:
        kept.stats["kept"] = True
        return kept
    from ..problems.movingai import read_map, read_scen

    grid = read_map(task.map_path)
    scen = read_scen(task.scen_path, task.n, grid)
    starts, goals = [a.start for a in scen], [a.goal for a in scen]
    entry = task.entry
    try:
        if entry.kind == "builtin":
            out = _builtin(task, grid.obstacles, starts, goals)
        elif entry.kind == "command":
            out = _command(task)
        else:
            out = _from_folder(task)
    except WareroverError as err:  # a plan file that cannot be read
        out = PlanOutcome(None, error=str(err), stage="read")
    if out.plan is not None:
        from ..planning.oneshot.core import goal_tables, grid_graph

        graph = grid_graph(grid.obstacles)
        tables = goal_tables(graph, goals)
        out.lower_bound = int(sum(int(t[graph.node(s)]) for s, t in zip(starts, tables,
                                                                        strict=True)))
        problem = check_plan(out.plan, grid.obstacles, starts, goals, task)
        if problem:
            out = PlanOutcome(None, out.solve_s, out.lower_bound, problem, "validate", out.stats)
    _save(task, out)
    return out


def _builtin(task: PlanTask, obstacles: np.ndarray, starts: list, goals: list) -> PlanOutcome:
    entry = task.entry
    if entry.rotations:
        from .rotations import solve_rotations

        t0 = time.perf_counter()
        plan, stats = solve_rotations(obstacles, starts, goals, task.planner_model,
                                      planner=entry.solver or "", seed=task.seed,
                                      time_limit_s=entry.time_limit_s,
                                      tick_s=task.execution.tick_s)
        wall = time.perf_counter() - t0
        if plan is None:
            return PlanOutcome(None, wall, error=str(stats.pop("reason")),
                               stage="solve", stats=stats)
        return PlanOutcome(plan, wall, stats=stats)
    from ..errors import PlanningError
    from ..planning.oneshot.core import solve

    try:
        res = solve(obstacles, starts, goals, planner=entry.solver or "",
                    time_limit_s=entry.time_limit_s, seed=task.seed, guide=entry.guide,
                    refine=entry.refine)
    except PlanningError as err:
        return PlanOutcome(None, error=str(err), stage="solve")
    stats = {k: v for k, v in res.stats.items() if isinstance(v, int | float | str)}
    if entry.refine and "refine" in res.stats:
        stats["first_soc"] = res.stats["refine"].get("first_soc")
    if not res.success:
        # (a planner may give up before its limit: prioritized A* when an agent finds no
        # path or its search hits the expansion cap)
        return PlanOutcome(None, res.wall_s, res.lower_bound, "no solution found (stopped "
                           f"after {res.wall_s:.1f} s of its {entry.time_limit_s:g} s limit)",
                           "solve", stats)
    return PlanOutcome(Plan(tuple(tuple(p) for p in res.paths)), res.wall_s, res.lower_bound,
                       stats=stats)


def _command(task: PlanTask) -> PlanOutcome:
    """Run the planner's command template; read the plan it wrote to ``{out}``."""
    from ..plans import read_plan

    entry = task.entry
    out = Path(task.out_dir) / "plans" / f"{task.plan_id}.out"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.unlink(missing_ok=True)
    values = {"map": task.map_path, "scen": task.scen_path, "n": task.n, "out": str(out),
              "time": f"{entry.time_limit_s:g}", "seed": task.seed, **task.solvers}
    argv = [tok.format(**values) for tok in shlex.split(entry.command or "")]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(argv, stdin=subprocess.DEVNULL, capture_output=True,
                              timeout=2 * entry.time_limit_s + COMMAND_GRACE_S, check=False)
    except subprocess.TimeoutExpired:
        return PlanOutcome(None, time.perf_counter() - t0, error="command "
                           f"still running after {2 * entry.time_limit_s + COMMAND_GRACE_S:g} "
                           "s (killed)", stage="solve")
    except OSError as err:
        return PlanOutcome(None, error=f"cannot run {argv[0]!r}: "
                           f"{err.strerror or err}", stage="solve")
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        tail = proc.stderr.decode("utf-8", "replace").strip().splitlines()[-1:] or \
            proc.stdout.decode("utf-8", "replace").strip().splitlines()[-1:]
        return PlanOutcome(None, wall, error=f"command exited with code "
                           f"{proc.returncode}" + (f": {tail[0][:200]}" if tail else ""),
                           stage="solve")
    if not out.is_file() or out.stat().st_size == 0:
        return PlanOutcome(None, wall, error=f"the command wrote no plan to "
                           f"{{out}} ({out.name})", stage="solve")
    plan = read_plan(out, entry.format)
    if str(plan.meta.get("solved", "1")).strip() == "0":
        return PlanOutcome(None, wall, error="the solver reports no solution "
                           "(solved=0)", stage="solve")
    return PlanOutcome(plan, wall, stats=_meta_figures(plan))


def _meta_figures(plan: Plan) -> dict[str, Any]:
    out = {}
    for k in ("soc", "makespan", "comp_time", "comp_time_initial_solution"):
        v = plan.meta.get(k)
        try:
            out[f"reported_{k}"] = float(v) if v is not None else None
        except (TypeError, ValueError):
            pass
    return {k: v for k, v in out.items() if v is not None}


def _from_folder(task: PlanTask) -> PlanOutcome:
    from ..plans import read_plan

    entry = task.entry
    name = entry.pattern.format(map=Path(task.map_path).stem, scen=Path(task.scen_path).stem,
                                n=task.n, seed=task.seed)
    path = Path(entry.plans or ".") / name  # made absolute by tasks_for
    if not path.is_file():
        return PlanOutcome(None, error=f"plan file not found: {path}",
                           stage="read")
    plan = read_plan(path, entry.format)
    stats = _meta_figures(plan)
    ms = stats.get("reported_comp_time")
    return PlanOutcome(plan, ms / 1000 if ms is not None and math.isfinite(ms) else None,
                       stats=stats)


def check_plan(plan: Plan, obstacles: np.ndarray, starts: list, goals: list,
               task: PlanTask) -> str | None:
    """The first problem of ``plan`` for this instance (one line), or None: its agent
    count, every agent's start and goal, the cells, moves and conflicts
    (:func:`~warerover_phys.execute.validate_plan`), and for a plan with headings its turns
    (:func:`~warerover_phys.validate.validate_headings`)."""
    from ..execute import PlanError, load_floor, validate_plan

    if plan.num_agents != len(starts):
        return f"the plan has {plan.num_agents} agents, the instance {len(starts)}"
    for i, (p, s, g) in enumerate(zip(plan.paths, starts, goals, strict=True)):
        if p[0] != s:
            return f"agent {i} starts at {p[0]}, the scen says {s}"
        if p[-1] != g:
            return f"agent {i} ends at {p[-1]}, its goal is {g}"
    layout = load_floor(task.map_path)[0]
    try:
        validate_plan(plan, layout, [1] * plan.num_agents, source="plan")
    except PlanError as err:
        return str(err)
    if plan.headings is not None:
        return _check_headings(plan, layout.cols, task)
    return None


def _check_headings(plan: Plan, cols: int, task: PlanTask) -> str | None:
    from ..planning.rotation import agent_turn_ticks
    from ..validate import validate_headings

    tt = agent_turn_ticks(task.planner_model, task.execution.tick_s) or (0, 0)
    assert plan.headings is not None
    states = {i: [(r * cols + c, r * cols + c) for r, c in p] for i, p in enumerate(plan.paths)}
    heads = {i: list(h) for i, h in enumerate(plan.headings)}
    bad = validate_headings(states, heads, cols, turn_ticks=dict.fromkeys(states, tt),
                            max_conflicts=1)
    return f"heading check: {bad[0]}" if bad else None
