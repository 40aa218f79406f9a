"""The gap over many seeds: run them in parallel, summarise every figure, keep tidy tables.

:func:`run_seeds` runs :func:`seed_gap` for every seed in the sweep's process pool
(:func:`warerover_phys.sweep.runner.pool_map`) and :func:`summarise` gives, for every
numeric figure of the per-seed reports, its mean, median, 95th percentile, min, max,
standard deviation and a 95% confidence interval of the mean (Student t, as
``warerover report``). :func:`write_outputs` writes a folder as one set
(:func:`warerover_phys.util.atomic.write_set`):

- ``summary.json``: mode, scenario, seeds, the statistics of every figure and the seeds
  that failed;
- ``seeds.csv``: one row per seed (every scalar figure);
- ``agents.csv`` and ``agents.parquet`` (open loop): one row per seed x AGV, full
  precision (lost time and its parts, planned and executed finish, top blockers);
- ``schedule.json`` (``planner.timing: motion``): every seed's motion-timed schedule;
- the pictures of :mod:`.gap_plots`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from ..config import Scenario

__all__ = ["parse_seeds", "seed_gap", "run_seeds", "summarise", "write_outputs",
           "wait_map", "STAT_KEYS"]

SCHEDULES_FORMAT = "warerover-schedules/1"
"""``format`` of a many-seed ``schedule.json``: ``{"seeds": {seed: one seed's schedule}}``
(motion timing; one seed's is :meth:`~.planning.timing.Schedule.to_json`)."""
STAT_KEYS = ("mean", "median", "p95", "min", "max", "std", "ci95_low", "ci95_high", "n")


MAX_SEEDS = 100_000
"""Most seeds one ``gap --seeds`` runs (each is a whole episode, or two)."""


def parse_seeds(text: str) -> list[int]:
    """``0..99`` (inclusive), ``3,5,8`` or a mix (``0..4,10``) as a list of seeds (each 0 ..
    2**63 - 1, at most :data:`MAX_SEEDS` of them, counted before any list is built)."""
    from ..errors import ScenarioError
    from ..inputs import MAX_SEED

    spans: list[tuple[int, int]] = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        try:
            a, _, b = part.partition("..")
            lo, hi = int(a), int(b if b else a)
            if hi < lo:
                raise ValueError
        except ValueError:
            raise ScenarioError("expected seeds like 0..99, 3,5,8 or 0..4,10",
                                field="--seeds", value=text) from None
        if lo < 0 or hi > MAX_SEED:
            raise ScenarioError(f"seeds are whole numbers from 0 to {MAX_SEED}",
                                field="--seeds", value=text)
        spans.append((lo, hi))
        if sum(h - lo_ + 1 for lo_, h in spans) > MAX_SEEDS:
            raise ScenarioError(f"at most {MAX_SEEDS:,} seeds (use `warerover sweep` for "
                                "more)", field="--seeds", value=text)
    if not spans:
        raise ScenarioError("no seeds given", field="--seeds", value=text)
    return list(dict.fromkeys(s for lo, hi in spans for s in range(lo, hi + 1)))


def wait_map(actions: list[dict], footprints: list[int], rows: int, cols: int) -> np.ndarray:
    """Seconds of dependency waits per cell (an AGV waits at its action's start cell; a
    k x k AGV's wait is counted on each of its cells)."""
    out = np.zeros((rows, cols))
    for a in actions:
        s = a.get("dependency_wait_s", 0.0)
        if s <= 0:
            continue
        r, c = a["src"]
        k = footprints[a["agv"]]
        out[r:r + k, c:c + k] += s
    return out


def seed_gap(args: tuple[Scenario, int, str]) -> dict[str, Any]:
    """One seed's gap (a pool task): the flat report, and in open loop the per-AGV rows,
    the per-action rows and the wait map."""
    from .core import closed_loop_report, open_loop_gap

    scenario, seed, mode = args
    if mode == "closed":
        rep = closed_loop_report(scenario, seed)
        return {"seed": seed, "report": _flat(rep)}
    g = open_loop_gap(scenario, seed)
    plan = g.run.plan
    fp = [t.footprint for t in plan.types]
    out = {"seed": seed, "report": _flat(g.report), "agents": g.agents,
           "actions": g.actions, "footprints": fp,
           "wait_map": wait_map(g.actions, fp, plan.layout.rows, plan.layout.cols),
           "grid": np.asarray(plan.layout.grid).copy()}
    if g.schedule is not None:  # planner.timing: motion
        out["schedule"] = g.schedule.to_json(plan.layout.cols, plan.source)
    return out


def _flat(rep: dict) -> dict:
    """The scalar figures of a report (no nested run metrics)."""
    return {k: v for k, v in rep.items() if not isinstance(v, dict | list)}


def run_seeds(scenario: Scenario, seeds: Iterable[int], mode: str, workers: int,
              on_done: Callable[[int, dict | None, BaseException | None], None] | None = None,
              ) -> tuple[list[dict], list[tuple[int, str]]]:
    """Every seed's :func:`seed_gap`, in seed order, and the seeds that failed with their
    error."""
    from ..sweep.runner import pool_map

    results, failed = [], []
    for (_, seed, _), res, err in pool_map(seed_gap, [(scenario, s, mode) for s in seeds],
                                           workers):
        if err is None:
            results.append(res)
        else:
            failed.append((seed, f"{type(err).__name__}: {err}"))
        if on_done is not None:
            on_done(seed, res, err)
    results.sort(key=lambda r: r["seed"])
    failed.sort()
    return results, failed


def _stats(values: list[float]) -> dict[str, float | int | None]:
    from ..sweep.report import mean_ci

    arr = np.asarray(values, dtype=float)
    arr = arr[np.isfinite(arr)]
    n = len(arr)
    if n == 0:
        return dict.fromkeys(STAT_KEYS, None) | {"n": 0}
    mean, half = mean_ci(arr.tolist())
    half = 0.0 if math.isnan(half) else half
    return {"mean": float(mean), "median": float(np.median(arr)),
            "p95": float(np.percentile(arr, 95)), "min": float(arr.min()),
            "max": float(arr.max()), "std": float(arr.std(ddof=1)) if n > 1 else 0.0,
            "ci95_low": float(mean - half), "ci95_high": float(mean + half), "n": int(n)}


def summarise(results: list[dict]) -> dict[str, dict]:
    """Statistics (:data:`STAT_KEYS`) of every numeric figure over the seeds."""
    keys: dict[str, None] = {}
    for r in results:
        for k, v in r["report"].items():
            if isinstance(v, int | float) and not isinstance(v, bool) and k != "seed":
                keys[k] = None
    out = {}
    for k in keys:
        vals = [r["report"].get(k) for r in results]
        out[k] = _stats([math.nan if v is None else float(v) for v in vals])
    return out


def agent_rows(results: list[dict]) -> list[dict]:
    """One row per seed x AGV (open loop)."""
    rows = []
    for r in results:
        for a in r.get("agents", ()):
            row = {"seed": r["seed"], **{k: v for k, v in a.items() if k != "top_blockers"}}
            tops = a.get("top_blockers", [])
            for j in range(3):
                row[f"blocker_{j + 1}"] = tops[j][0] if j < len(tops) else None
                row[f"blocker_{j + 1}_wait_s"] = tops[j][1] if j < len(tops) else None
            rows.append(row)
    return rows


def _csv(rows: list[dict]) -> str:
    import csv
    import io

    buf = io.StringIO()
    if rows:
        cols = list(dict.fromkeys(k for r in rows for k in r))
        w = csv.DictWriter(buf, fieldnames=cols, lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()})
    return buf.getvalue()


def _parquet(rows: list[dict], path: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    cols = list(dict.fromkeys(k for r in rows for k in r))
    table = pa.table({c: [r.get(c) for r in rows] for c in cols}) if rows else pa.table({})
    pq.write_table(table, str(path))


def write_outputs(out_dir: str | Path, *, header: dict, results: list[dict],
                  failed: list[tuple[int, str]], pictures: bool = True,
                  picture_agvs: list[int] | None = None) -> dict[str, Path]:
    """``summary.json``, ``seeds.csv``, ``agents.csv`` / ``agents.parquet`` (open loop) and
    the pictures, as one set; returns name -> path."""
    import json

    from ..util.atomic import write_set

    stats = summarise(results)
    summary = {**header, "seeds": [r["seed"] for r in results],
               "failed": [{"seed": s, "error": e} for s, e in failed],
               "statistics": stats,
               "statistics_note": "over seeds: mean, median, p95 (95th percentile), min, max, "
                                  "std (n - 1), ci95_low / ci95_high: 95% Student-t "
                                  "confidence interval of the mean"}
    seeds = [{"seed": r["seed"], **{k: v for k, v in r["report"].items() if k != "seed"}}
             for r in results]
    writers: dict[str, Callable[[Path], Any]] = {
        "summary.json": lambda p: p.write_text(
            json.dumps(_finite(summary), indent=2, sort_keys=True) + "\n", encoding="utf-8"),
        "seeds.csv": lambda p: p.write_text(_csv(seeds), encoding="utf-8"),
    }
    schedules = {str(r["seed"]): r["schedule"] for r in results if r.get("schedule")}
    if schedules:
        writers["schedule.json"] = lambda p: p.write_text(
            json.dumps(_finite({"format": SCHEDULES_FORMAT, "timing": "motion",
                                "seeds": schedules}), indent=1) + "\n", encoding="utf-8")
    if header.get("mode") == "open-loop":
        rows = agent_rows(results)
        writers["agents.csv"] = lambda p: p.write_text(_csv(rows), encoding="utf-8")
        writers["agents.parquet"] = lambda p: _parquet(rows, p)
        if pictures and results:
            from . import plots as gap_plots

            if gap_plots.available():
                writers.update(gap_plots.writers(results, picture_agvs))
            else:
                _no_pictures()
    return write_set(out_dir, writers, meta={"mode": header.get("mode"),
                                             "scenario": header.get("scenario")})


def _no_pictures() -> None:
    from ..util.console import err_console

    err_console.print("pictures skipped: matplotlib is not installed (pip install "
                      "'warerover-phys[report]')", markup=False, highlight=False)


def _finite(obj: Any) -> Any:
    """NaN and infinities as null (JSON has neither)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    return obj
