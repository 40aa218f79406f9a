"""Run a study task: obtain its plan once, repair its rotations once, execute it on physics
once per cell, and make each cell's row.

Execution is the open-loop gap's (:func:`warerover_phys.gap.open_loop.execute_timed`: the plan
unchanged on the physics executor through the action dependency graph, every AGV's lost
time split into causes). The robots are the cell's true model: its robot model with the
mismatch factors applied; the planner's side (turn ticks of rotation-aware plans, the
motion-timed schedule of ``timing: motion``) uses the model without them.

**AET** (average execution time) is the mean over agents of the executed finish time in
seconds: the end of the agent's last action on physics (the gap's ``executed_finish_s``).
"""

from __future__ import annotations

import math
import os
import socket
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np

from ..config import AgvTypeSpec
from ..errors import WareroverError
from .cells import Cell, LifelongTask, PlanTask, cell_id
from .guard import WallGuard, wall_guard
from .planners import PlanOutcome, obtain_plan

__all__ = ["run_plan_task", "fail_task", "run_lifelong_task", "cell_row", "ROW_PARTS"]

ROW_PARTS = ("dependency", "accel_decel", "turning", "control", "injected",
             "rotation_repair", "dwell_overrun", "faster_than_plan", "plan_waits_skipped")
"""The lost-time causes kept in a row (seconds summed over agents; see
:data:`warerover_phys.gap.open_loop.PARTS`)."""


def _cpu() -> float:
    """CPU seconds of this process and its finished children (an external solver)."""
    import resource

    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _now() -> str:
    import datetime as dt

    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")


def _base(task: PlanTask, cell: Cell) -> dict[str, Any]:
    e = task.entries[cell.planner]
    return {"key": cell.key, "kind": "oneshot", "status": "ok", "stage": None, "error": None,
            "instance": cell.instance, "map": Path(task.map_path).stem, "scen": cell.scen,
            "scen_index": cell.scen_index, "agents": cell.n, "planner": cell.planner,
            "planner_kind": e.kind, "solver": e.solver or "", "rotations": e.rotations,
            "refine": e.refine, "timing": e.timing, "time_limit_s": e.time_limit_s,
            "robot": cell.robot, "mismatch": cell.mismatch, "delays": cell.delays,
            "seed": cell.seed, "plan_id": task.plan_id, "cell_id": cell_id(cell.key),
            "host": socket.gethostname(), "pid": os.getpid()}


def fail_task(task: PlanTask | LifelongTask, error: str) -> list[dict[str, Any]]:
    """The rows of a task that did not finish (a dead worker, an error outside a cell)."""
    if isinstance(task, LifelongTask):
        return [{**_life_base(task), "status": "failed", "stage": "run", "error": error,
                 "finished": _now()}]
    return [{**_base(task, c), "status": "failed", "stage": "task", "error": error,
             "finished": _now()} for c in task.cells]


def run_plan_task(task: PlanTask) -> list[dict[str, Any]]:
    """One row per cell of ``task``; never raises for an error of a plan or a cell."""
    t0 = time.perf_counter()
    c0 = _cpu()
    if _past(task):
        return []
    guard = WallGuard(_within(plan_guard_s(task), task), "obtaining and repairing the plan")
    try:
        with wall_guard(guard):
            outcome = obtain_plan(task)
            prepared = _prepare(task, outcome) if outcome.plan is not None else None
        solve_cpu = _cpu() - c0
        if outcome.plan is None and guard.expired():  # a solver swallowed the guard's error
            raise guard.timeout()
    except Exception as err:  # noqa: BLE001 - recorded in the rows
        if guard.stopped(err) and _past(task):
            return []  # the run's deadline: no rows, a resumed study runs the cells
        if guard.stopped(err):
            return [{**r, "status": "timeout", "stage": "solve",
                     "solve_s": time.perf_counter() - t0} for r in fail_task(task, guard.error)]
        tb = "".join(traceback.format_exception(err)[-8:])
        return [{**r, "traceback": tb} for r in fail_task(task, f"{type(err).__name__}: {err}")]
    rows = []
    schedules: dict[str, Any] = {}
    for cell in task.cells:
        if _past(task):
            break
        w0, c0 = time.perf_counter(), _cpu()
        row = {**_base(task, cell), **_plan_figures(outcome, task), "plan_cpu_s": solve_cpu}
        if outcome.plan is None or isinstance(prepared, str):
            error = outcome.error if outcome.plan is None else prepared
            row.update(status="failed", stage=outcome.stage or "repair", error=error)
        else:
            guard = WallGuard(_within(task.execution.cell_timeout_s, task), "the execution")
            try:
                with wall_guard(guard):
                    row.update(_execute_cell(task, cell, prepared, schedules, guard))
            except Exception as err:  # noqa: BLE001 - one cell's failure is its row
                if guard.stopped(err) and _past(task):
                    break  # the run's deadline: no row, a resumed study runs the cell
                if guard.stopped(err):
                    row.update(status="timeout", stage="execute", error=guard.error)
                else:
                    row.update(status="failed", stage="execute",
                               error=f"{type(err).__name__}: {err}",
                               traceback="".join(traceback.format_exception(err)[-8:]))
        row["cell_wall_s"] = time.perf_counter() - w0
        row["cell_cpu_s"] = _cpu() - c0
        row["finished"] = _now()
        rows.append(row)
    for row in rows:
        row["task_wall_s"] = time.perf_counter() - t0
    return rows


def _plan_figures(out: PlanOutcome, task: PlanTask) -> dict[str, Any]:
    plan = out.plan
    lb = out.lower_bound
    soc = plan.sum_of_costs if plan is not None else None
    return {"solved": plan is not None, "solve_s": out.solve_s, "lower_bound": lb,
            "soc": soc, "makespan": plan.makespan if plan is not None else None,
            "soc_over_lb": soc / lb if soc is not None and lb else None,
            "first_soc": out.stats.get("first_soc"), "plan_kept": bool(out.stats.get("kept"))}


def _prepare(task: PlanTask, outcome: PlanOutcome) -> dict[str, Any] | str:
    """The floor, the repaired plan and its repairs (or the one-line reason it has none)."""
    from ..execute import PlanError, load_floor, plan_to_paths, repair_cycles, validate_plan
    from ..planning.base import TimedPath

    layout = load_floor(task.map_path)[0]
    given = outcome.plan
    assert given is not None
    sizes = [1] * given.num_agents
    try:
        plan, repairs = repair_cycles(given, layout, sizes, source="plan")
        if repairs:
            validate_plan(plan, layout, sizes, source="plan")
    except PlanError as err:
        return f"rotation repair: {err}"
    paths = plan_to_paths(plan, layout.cols)
    if plan.headings is not None:  # the planner's headings stay with the plan (no repair)
        paths = {i: TimedPath(i, 0, p.states, tuple(plan.headings[i]))
                 for i, p in paths.items()}
    given_finish = tuple(given.costs) if repairs else None
    return {"layout": layout, "paths": paths, "repairs": tuple(repairs),
            "given_finish": given_finish}


def _timed_plan(task: PlanTask, prepared: dict[str, Any], types: list[AgvTypeSpec]):
    from ..gap.ideal_plan import TimedPlan

    return TimedPlan(layout=prepared["layout"], types=types, tick_s=task.execution.tick_s,
                     paths=prepared["paths"], dwells={}, source=f"study plan {task.plan_id}",
                     repairs=prepared["repairs"], given_finish=prepared["given_finish"])


def _past(task: PlanTask) -> bool:
    """Whether the run's deadline (``--max-minutes``) has passed."""
    return task.deadline is not None and time.time() >= task.deadline


def _within(limit_s: float | None, task: PlanTask) -> float | None:
    """A guard's limit, cut to the time left before the run's deadline."""
    if task.deadline is None:
        return limit_s
    left = max(0.0, task.deadline - time.time())
    return left if limit_s is None else min(limit_s, left)


def plan_guard_s(task: PlanTask) -> float | None:
    """The wall-clock guard of obtaining and repairing the task's plan (seconds)."""
    grace = task.execution.plan_grace_s
    return None if grace is None else 2 * task.entry.time_limit_s + grace


def _execute_cell(task: PlanTask, cell: Cell, prepared: dict[str, Any],
                  schedules: dict[str, Any], guard: WallGuard) -> dict[str, Any]:
    from ..execute import executor_spec
    from ..gap.open_loop import execute_timed, motion_timed, open_loop_report

    model = task.robots[cell.robot]
    true = task.mismatch[cell.mismatch].apply(model)
    n = len(prepared["paths"])
    plan = _timed_plan(task, prepared, [true] * n)
    ex = task.execution
    spec = executor_spec("physics", dt_s=ex.dt_s, delays=task.delays[cell.delays],
                         trajectory_hz=ex.trajectory_hz, options=ex.options)
    horizon = max(len(p.states) for p in prepared["paths"].values())
    run = execute_timed(plan, spec, seed=cell.seed,
                        max_ticks=int(ex.max_ticks_factor * horizon) + 200,
                        progress=guard.check)
    report, agents, actions = open_loop_report(run)
    unit = {"planned_soc_unit_s": report["planned_sum_of_costs_s"],
            "planned_makespan_unit_s": report["planned_makespan_s"]}
    if task.entries[cell.planner].timing == "motion":
        if cell.robot not in schedules:  # the planner's model: no mismatch
            from ..planning.timing import schedule_plan

            schedules[cell.robot] = schedule_plan(_timed_plan(task, prepared, [model] * n),
                                                  payload=False,
                                                  comm_latency_s=float(spec.comm_latency_s))
        report, agents, _ = motion_timed(report, agents, actions, plan, schedules[cell.robot])
    if ex.keep_trajectories and run.trajectory is not None:
        _keep_trajectory(task, cell, run.trajectory)
    return cell_row(report, agents, run.wall_s, unit)


def cell_row(report: dict[str, Any], agents: list[dict[str, Any]], wall_s: float,
             unit: dict[str, Any]) -> dict[str, Any]:
    """A cell's execution figures from the open-loop report and its per-AGV rows."""
    finish = [a["executed_finish_s"] for a in agents]
    complete = bool(report["completed"]) and all(math.isfinite(f) for f in finish)
    n = len(finish)
    aet = float(np.mean(finish)) if complete and n else None
    psoc = report["planned_sum_of_costs_s"]
    row: dict[str, Any] = {
        "completed": complete, "aet_s": aet,
        "planned_soc_s": psoc, "planned_makespan_s": report["planned_makespan_s"],
        "planned_mean_s": psoc / n if n else None,
        "executed_makespan_s": report["executed_makespan_s"] if complete else None,
        "executed_soc_s": report["executed_sum_of_costs_s"] if complete else None,
        "makespan_ratio": report["makespan_ratio"] if complete else None,
        "soc_ratio": report["sum_of_costs_ratio"] if complete else None,
        "aet_over_planned": aet / (psoc / n) if aet is not None and psoc else None,
        "lost_s_total": report["lost_s_fleet_total"],
        **{f"lost_{k}_s_total": report[f"lost_{k}_s_fleet_total"] for k in ROW_PARTS},
        "agv_contacts": report.get("agv_contacts"),
        "static_contacts": report.get("static_contacts"),
        "min_clearance_m": report.get("min_clearance_m"),
        "deadlocks": report.get("deadlocks"),
        "cycle_repairs": report.get("cycle_repairs"),
        "cycle_repair_added_ticks": report.get("cycle_repair_added_ticks"),
        "real_time_factor": report.get("real_time_factor"),
        "execute_wall_s": wall_s,
        **unit,
    }
    if not complete:
        row.update(status="failed", stage="execute",
                   error="the execution did not complete (a deadlock, or the tick limit)")
    return row


def _keep_trajectory(task: PlanTask, cell: Cell, traj: dict) -> None:
    from ..outputs import _savez

    d = Path(task.out_dir) / "cells" / cell_id(cell.key)
    d.mkdir(parents=True, exist_ok=True)
    data = {k: np.asarray(v) for k, v in traj.items()}
    tmp = d / "trajectories.npz.tmp"
    _savez(tmp, data)
    os.replace(tmp, d / "trajectories.npz")


# ----------------------------------------------------------------------------- lifelong


def _life_base(task: LifelongTask) -> dict[str, Any]:
    return {"key": task.key, "kind": "lifelong", "status": "ok", "stage": None, "error": None,
            "instance": task.scenario, "planner": task.planner, "seed": task.seed,
            "variant": "; ".join(f"{k}={v}" for k, v in task.variant),
            "overrides": "; ".join(f"{k}={v}" for k, v in task.overrides),
            "host": socket.gethostname(), "pid": os.getpid()}


LIFELONG_KEYS = ("throughput", "success_rate", "orders_completed", "orders_generated",
                 "ticks", "ct_total_s", "ct_mean_ms", "agv_contacts", "static_contacts",
                 "deadlocks", "real_time_factor")


def run_lifelong_task(task: LifelongTask) -> list[dict[str, Any]]:
    """One closed-loop episode (``warerover run``); throughput in place of AET."""
    from ..sim import run_episode
    from .cells import lifelong_scenario

    row = _life_base(task)
    t0 = time.perf_counter()
    try:
        sc = lifelong_scenario(task.file, task.overrides, task.seed)
        metrics = run_episode(sc, seed=task.seed).metrics
        row.update({k: metrics.get(k) for k in LIFELONG_KEYS})
        row["agents"] = sc.fleet.size
    except (WareroverError, Exception) as err:  # noqa: BLE001 - the episode's error is its row
        row.update(status="failed", stage="run", error=f"{type(err).__name__}: {err}")
    row["cell_wall_s"] = time.perf_counter() - t0
    row["finished"] = _now()
    return [row]


def run_any(task: PlanTask | LifelongTask) -> list[dict[str, Any]]:
    """A worker's entry point (module level: pickled by name)."""
    if isinstance(task, LifelongTask):
        return run_lifelong_task(task)
    return run_plan_task(task)
