"""Run a study on the sweep's machinery: the results folder's lock, an append-only results
file written by this process alone (one line per cell, fsync-ed: a SIGKILL loses at most the
cells of the tasks in flight), the sweep's process pool or Ray, and a resumed run doing only
the cells without a row. After each run the tidy table is rewritten from the results file:
``results.parquet`` and ``results.csv`` (one row per cell, the columns of
:data:`COLUMNS` first).

>>> from warerover_phys.study import load_study, run_study  # doctest: +SKIP
>>> run_study(load_study("studies/tradeoffs.yaml"), "runs/tradeoffs", workers=2)  # doctest: +SKIP
"""

from __future__ import annotations

import csv
import io
import json
import os
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..sweep.lock import sweep_lock
from ..sweep.results import RESULTS_NAME, ResultsFile
from ..sweep.runner import (
    SweepSummary,
    _term_as_interrupt,
    dispatch,
    row_sink,
    write_spec_json,
)
from .cells import (
    LifelongTask,
    PlanTask,
    check_lifelong,
    expand,
    lifelong_tasks,
    resolve_solvers,
    tasks_for,
)
from .execution import fail_task, run_any
from .spec import StudySpec

__all__ = ["StudySummary", "run_study", "plan_study", "write_tables", "load_results",
           "COLUMNS", "SPEC_NAME", "PARQUET_NAME", "CSV_NAME"]

SPEC_NAME = "study.json"
PARQUET_NAME = "results.parquet"
CSV_NAME = "results.csv"
COLUMNS = ("kind", "status", "stage", "error", "instance", "map", "scen", "scen_index",
           "agents", "planner", "planner_kind", "solver", "rotations", "refine", "timing",
           "robot", "mismatch", "delays", "seed", "solved", "solve_s", "lower_bound", "soc",
           "makespan", "soc_over_lb", "planned_soc_s", "planned_makespan_s", "aet_s",
           "executed_makespan_s", "executed_soc_s", "makespan_ratio", "soc_ratio",
           "aet_over_planned", "lost_s_total")
"""The leading columns of the tidy table (the rest follow in name order)."""


StudySummary = SweepSummary
"""What a run did: cells in the study, already done before, run now, failed (the sweep's)."""


def plan_study(spec: StudySpec, out_dir: str | Path, *, retry_failed: bool = False,
               solvers: dict[str, str] | None = None,
               ) -> tuple[list[PlanTask | LifelongTask], StudySummary, ResultsFile]:
    """Validate, read what ``out_dir`` holds, and return the tasks with cells still to run
    (each task narrowed to those cells)."""
    from .planners import forget

    out_dir = Path(out_dir).resolve()
    cells = expand(spec)
    life = lifelong_tasks(spec, out_dir)
    keys = {c.key for c in cells} | {t.key for t in life}
    results = ResultsFile(out_dir / RESULTS_NAME)
    rows = results.load()
    retry: set[str] = set()
    if retry_failed:
        rows, retry = results.drop_failed(rows, keys)
    todo = [c for c in cells if c.key not in rows]
    needs = {n for p in spec.planners.values() for n in p.solver_names()}
    found = resolve_solvers(spec, solvers) if needs and todo else {}
    tasks: list[PlanTask | LifelongTask] = []
    for task in tasks_for(spec, cells, out_dir, found):
        mine = tuple(c for c in task.cells if c.key not in rows)
        if mine:
            if any(c.key in retry for c in task.cells):
                forget(task)
            tasks.append(replace(task, cells=mine))
    todo_life = [t for t in life if t.key not in rows]
    check_lifelong(spec, todo_life)
    tasks += todo_life
    total = len(keys)
    summary = StudySummary(total=total, done_before=sum(1 for k in rows if k in keys),
                           failed_total=sum(1 for k, r in rows.items()
                                            if k in keys and r.get("status") != "ok"),
                           out_dir=out_dir)
    return tasks, summary, results


def run_study(spec: StudySpec, out_dir: str | Path, *, workers: int | None = None,
              ray_address: str | None = None, retry_failed: bool = False,
              solvers: dict[str, str] | None = None,
              on_start: Callable[[StudySummary, int], None] | None = None,
              on_row: Callable[[dict[str, Any]], None] | None = None,
              max_wall_s: float | None = None) -> StudySummary:
    """Run the cells of ``spec`` that ``out_dir`` has no row for, then rewrite the tidy
    table. ``workers``: local processes (default: CPU count); ``ray_address``: on Ray
    (``auto``, ``local`` or an address). ``solvers``: binaries by name (``--solver``).
    ``max_wall_s``: the run's deadline, from now: past it no plan or cell starts and a cell
    it cuts short gets no row (``summary.left`` says how many; running again finishes
    them). Raises :class:`KeyboardInterrupt` through (what finished is on disk; SIGTERM alike) and
    a :class:`~warerover_phys.errors.WareroverError` when another run holds the folder."""
    with sweep_lock(out_dir), _term_as_interrupt():
        t0 = time.perf_counter()
        deadline = None if max_wall_s is None else time.time() + max_wall_s
        tasks, summary, results = plan_study(spec, out_dir, retry_failed=retry_failed,
                                             solvers=solvers)
        if deadline is not None:
            tasks = [replace(t, deadline=deadline) if isinstance(t, PlanTask) else t
                     for t in tasks]
        write_spec_json(spec, summary.out_dir, SPEC_NAME)
        if on_start is not None:
            on_start(summary, sum(len(t.keys) for t in tasks))
        workers = max(1, workers or os.cpu_count() or 1)
        one = row_sink(results, summary, on_row)
        results.open_for_append()
        try:
            # the biggest tasks first: the pool's last minutes are not one long task alone
            tasks.sort(key=task_cost, reverse=True)
            dispatch(tasks, ray_address, workers, lambda rows: [one(r) for r in rows],
                     fn=run_any, fail=fail_task)
        finally:
            results.close()
            summary.wall_s = time.perf_counter() - t0
        write_tables(summary.out_dir)
    return summary


EXEC_S_PER_AGENT = 0.02
"""Seconds of one CPU to execute one agent's plan on physics, about (the trade-offs study
measured 0.005-0.025: longer plans on bigger maps cost more)."""


def task_cost(task: PlanTask | LifelongTask) -> float:
    """A task's expected seconds of work, to start the big ones first: its solver's time
    limit (an anytime solver spends all of it) and its cells' executions."""
    if isinstance(task, LifelongTask):
        return 0.0
    return task.entry.time_limit_s + len(task.cells) * task.n * EXEC_S_PER_AGENT


def load_results(out_dir: str | Path) -> tuple[list[dict[str, Any]], dict[str, Any] | None]:
    """The rows of the study as last run in ``out_dir`` (``study.json``) and that spec;
    rows of cells the spec no longer has are left out."""
    from .spec import StudySpec

    out_dir = Path(out_dir)
    rows = ResultsFile(out_dir / RESULTS_NAME).load()
    spec_path = out_dir / SPEC_NAME
    if not spec_path.exists():
        return list(rows.values()), None
    data = json.loads(spec_path.read_text(encoding="utf-8"))
    source = data.pop("source", None)
    spec = StudySpec.model_validate({**data, "source": source})
    keys = {c.key for c in expand(spec)} | {t.key for t in lifelong_tasks(spec, out_dir)}
    order = {k: i for i, k in enumerate([c.key for c in expand(spec)] +
                                        [t.key for t in lifelong_tasks(spec, out_dir)])}
    kept = sorted((r for k, r in rows.items() if k in keys), key=lambda r: order[r["key"]])
    return kept, data


def _columns(rows: list[dict[str, Any]]) -> list[str]:
    names = {k for r in rows for k in r if k not in ("traceback",)}
    return [c for c in COLUMNS if c in names] + sorted(names - set(COLUMNS))


def write_tables(out_dir: str | Path) -> dict[str, Path]:
    """``results.parquet`` and ``results.csv`` from the results file (each written to a
    temporary file and renamed)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    out_dir = Path(out_dir)
    rows, _ = load_results(out_dir)
    cols = _columns(rows)
    table = {c: [_scalar(r.get(c)) for r in rows] for c in cols}
    arrays = {}
    for c, values in table.items():
        try:
            arrays[c] = pa.array(values)
        except (pa.ArrowInvalid, pa.ArrowTypeError):
            arrays[c] = pa.array([None if v is None else str(v) for v in values])
    tmp = out_dir / (PARQUET_NAME + ".tmp")
    pq.write_table(pa.table(arrays) if arrays else pa.table({}), tmp)
    os.replace(tmp, out_dir / PARQUET_NAME)
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(cols)
    for r in rows:
        w.writerow(["" if r.get(c) is None else _scalar(r.get(c)) for c in cols])
    tmp = out_dir / (CSV_NAME + ".tmp")
    tmp.write_text(buf.getvalue(), encoding="utf-8")
    os.replace(tmp, out_dir / CSV_NAME)
    return {"parquet": out_dir / PARQUET_NAME, "csv": out_dir / CSV_NAME}


def _scalar(v: Any) -> Any:
    if isinstance(v, dict | list | tuple):
        return json.dumps(v, default=str)
    return v
