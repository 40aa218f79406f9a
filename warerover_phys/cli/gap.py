"""The ``warerover gap`` command: one seed, many seeds, or an imported plan; tables,
JSON and the output folder. Bad input prints one line and exits with code 2."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from ..errors import ScenarioError, WareroverError
from ..gap.core import check_agv_ids
from ..inputs import check_seed
from ..util.console import err_console, fail_os
from ..util.console import fail as _fail
from .options import check_max_ticks, warn_incomplete

__all__ = ["run_gap"]

MODE_LABEL = {"open": "open-loop", "closed": "closed-loop"}
TIMINGS = ("unit", "motion")


def _f(x: Any, spec: str = ".3f") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return format(x, spec) if isinstance(x, float) else str(x)


def _parse_agvs(text: str | None) -> list[int] | None:
    if not text:
        return None
    try:
        out = [int(p) for p in text.split(",") if p.strip()]
    except ValueError:
        raise ScenarioError("expected AGV ids like 0,3,5", field="--agvs", value=text) from None
    if any(i < 0 for i in out):
        raise ScenarioError("AGV ids are >= 0", field="--agvs", value=text)
    return out or None


def run_gap(*, scenario: Path, mode: str, seed: int | None, seeds: str | None,
            workers: int | None, out: Path | None, json_out: bool, plan: Path | None,
            fmt: str | None, yx: bool, fleet: Path | None, delays: str | None,
            tick_s: float, dt_s: float, agvs: str | None, pictures: bool, quiet: bool,
            overrides: Callable[[], Any], timing: str | None = None,
            video: Path | None = None, ghost: bool = False,
            reorder: str | None = None, max_ticks: int | None = None) -> None:
    """See ``warerover gap --help``."""
    try:
        check_max_ticks(max_ticks)
        if max_ticks is not None and plan is None:
            raise WareroverError("--max-ticks limits the execution of a --plan only "
                                 f"(got --max-ticks {max_ticks} without --plan)")
        if reorder is not None:
            from ..execute import check_reorder

            check_reorder(reorder)
        if mode not in MODE_LABEL:
            raise WareroverError(f"--mode must be open or closed (got {mode!r})")
        if timing is not None and timing not in TIMINGS:
            raise WareroverError(f"--timing must be unit or motion (got {timing!r})")
        if video is not None and (mode != "open" or seeds):
            raise WareroverError("--video renders one open-loop execution: it takes neither "
                                 "--mode closed nor --seeds")
        if video is not None:
            _video_check(video)
        if out is not None:
            _check_out(out)
        picked = _parse_agvs(agvs)
        if seed is not None:
            check_seed(seed)
        if plan is not None:
            if mode != "open" or seeds:
                raise WareroverError("--plan runs one open-loop execution: it takes neither "
                                     "--mode closed nor --seeds")
            return _plan_gap(scenario, plan, fmt, yx, fleet, delays, tick_s, dt_s, seed or 0,
                             out, json_out, picked, pictures, quiet, timing or "unit", video,
                             ghost, reorder or "none", max_ticks)
        sc = _with_timing(overrides(), timing, mode)
        if seeds is not None:
            from ..gap.stats import parse_seeds

            return _many(sc, parse_seeds(seeds), mode, workers, out, json_out, picked,
                         pictures, quiet)
        return _one(sc, mode, out, json_out, picked, pictures, quiet, video, ghost)
    except ScenarioError as err:
        _fail(err.with_file(str(scenario)) if plan is None else err)
    except WareroverError as err:
        _fail(err)
    except OSError as err:
        fail_os(err)


def _check_out(out: Path) -> Path:
    """Refuse ``--out`` (a folder, or a ``.json`` report file) before any work."""
    from ..inputs import check_output_dir, check_output_file

    return check_output_file(out) if out.suffix == ".json" else check_output_dir(out)


def _with_timing(sc, timing: str | None, mode: str):
    """The scenario with ``--timing`` (if given) as its ``planner.timing``; motion timing
    with ``--mode closed`` is refused (it times the open loop's one plan)."""
    if timing is not None and timing != sc.planner.timing:
        sc = sc.model_copy(update={"planner": sc.planner.model_copy(update={"timing": timing})})
    if mode == "closed" and sc.planner.timing == "motion":
        raise WareroverError("motion timing (--timing motion / planner.timing: motion) times "
                             "the one plan of the open loop; --mode closed compares two "
                             "closed-loop episodes in ticks: use --mode open, or --timing "
                             "unit")
    return sc


# ----------------------------------------------------------------------------- one seed

def _bar(show: bool):
    """A rich progress bar on stderr (or a do-nothing stand-in), and its update callback."""
    if not show:
        import contextlib

        return contextlib.nullcontext(), None
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    bar = Progress(TextColumn("{task.description}"), BarColumn(),
                   TextColumn("{task.fields[info]}"), TimeElapsedColumn(),
                   console=err_console, transient=True)
    tasks: dict[str, Any] = {}

    def update(phase: str, done: int, total: int) -> None:
        if phase not in tasks:
            tasks[phase] = bar.add_task(phase, total=total or None, info="")
        info = f"tick {done}" + (f" (plan {total})" if total else "")
        bar.update(tasks[phase], completed=done, total=total or None, info=info)

    return bar, update


def _one(sc, mode: str, out: Path | None, json_out: bool, agvs: list[int] | None,
         pictures: bool, quiet: bool, video: Path | None = None, ghost: bool = False) -> None:
    from ..gap.core import closed_loop_report, open_loop_gap

    default = Path("runs") / f"{sc.name}-seed{sc.seed}-gap"
    _check_out(out or default)
    check_agv_ids(agvs or (), sc.fleet.size, str(sc.source or sc.name))
    show = not quiet and not json_out and err_console.is_terminal
    bar, update = _bar(show)
    with bar:
        if mode == "closed":
            report, result = closed_loop_report(sc), None
        else:
            g = open_loop_gap(sc, progress=update)
            report, result = g.report, _result(g, sc.seed)
    _print_repairs(report)
    if video is not None and mode == "open":
        _video(g, video, f"{sc.name} seed {sc.seed}", show, ghost)
    written = _write_one(out or default, report, result, agvs, pictures)
    if json_out:
        print(json.dumps(_finite({k: v for k, v in report.items()
                                  if k not in ("grid", "physics")}), indent=2, sort_keys=True))
        return
    console = Console()
    if mode == "closed":
        _closed_table(console, sc, report)
    else:
        _open_table(console, f"open-loop gap: {sc.name}  seed {sc.seed}  "
                             f"{sc.scheduler.name} + {sc.planner.name}", report)
    console.print(f"wrote {written}", markup=False)


def _video_check(video: Path) -> None:
    """Refuse a bad --video before any work is done."""
    from ..inputs import check_output_file

    if video.suffix.lower() != ".mp4":
        raise WareroverError(f"--video: {video}: expected a .mp4 file")
    check_output_file(video, "--video")
    try:
        import av  # noqa: F401
        import cv2  # noqa: F401
    except ImportError as err:
        raise WareroverError(f"--video needs opencv-python-headless and av ({err}): "
                             "pip install 'warerover-phys[render]'") from None


def _video(g, video: Path, title: str, show: bool, ghost_on: bool = False) -> None:
    """Render the physics execution of an open-loop gap to ``video``: the bodies as
    recorded, coloured by what they do, the path ahead of each from its progress in the
    plan, and with ``ghost_on`` each AGV's planned pose (the executed plan's ticks x
    tick_s) as a ghost."""
    from ..render import Style, ghost_poses, recording_with_ghosts, render_video

    run = g.run
    plan = run.plan
    if run.trajectory is None:
        raise WareroverError("--video: the executor kept no trajectory")
    ghost = ghost_poses({i: list(p.states) for i, p in plan.paths.items()},
                        [t.footprint for t in plan.types], plan.layout.cols,
                        float(plan.layout.cell_m), plan.tick_s)
    planned = [{"agv": i, "tick": p.start_tick, "states": [list(s) for s in p.states]}
               for i, p in plan.paths.items()]
    switches = tuple(e for e in run.events if e.get("event") == "reorder")
    rec = recording_with_ghosts(dict(run.trajectory), ghost, planned=planned,
                                switches=switches)
    style = Style(size=(1280, 720), ghosts=ghost_on, switches=bool(switches),
                  title=title + (": ghost = plan" if ghost_on else ""))
    bar, update = _bar(show)
    with bar:
        info = render_video(rec, video, style=style, progress=None if update is None else
                            lambda k, n: update("video", k, 0))
    err_console.print(f"wrote {video}: {info['frames']} frames at {info['fps']:g} fps, "
                      f"{info['speed']:g}x, {info['codec']}", markup=False, highlight=False)


def _print_repairs(report: dict) -> None:
    """One line on stderr per rotation repaired (see :func:`.gap_plan.repair_rotations`)."""
    for r in report.get("cycle_repairs_detail", []):
        err_console.print(f"repaired a rotation at timestep {r['timestep']} (agents "
                          f"{r['agents']}, {r['moves']} detour moves)", highlight=False)
    if report.get("cycle_repairs"):
        err_console.print(f"planned figures are the plan as given; the repair added "
                          f"{report['cycle_repair_added_ticks']} planned ticks over the fleet "
                          "(repaired_* figures, lost_rotation_repair_s)", highlight=False)


def _result(g, seed: int) -> dict:
    """An open-loop gap as the per-seed result of :func:`.gap_stats.seed_gap`."""
    from ..gap.stats import _flat, wait_map

    plan = g.run.plan
    fp = [t.footprint for t in plan.types]
    return {"seed": seed, "report": _flat(g.report), "agents": g.agents, "actions": g.actions,
            "footprints": fp,
            "wait_map": wait_map(g.actions, fp, plan.layout.rows, plan.layout.cols),
            "grid": plan.layout.grid, **_schedule_data(g)}


def _schedule_data(g) -> dict:
    """``{"schedule": ...}`` (``schedule.json``) for a motion-timed gap, else nothing."""
    if getattr(g, "schedule", None) is None:
        return {}
    plan = g.run.plan
    return {"schedule": g.schedule.to_json(plan.layout.cols, plan.source)}


def _write_one(out: Path, report: dict, result: dict | None, agvs: list[int] | None,
               pictures: bool) -> Path:
    """``gap.json`` (+ ``agents.csv``, ``actions.csv`` and the pictures in open loop) into
    the folder ``out`` as one set, or the report alone to ``out`` if it ends in .json."""
    text = json.dumps(_finite(report), indent=2, sort_keys=True, default=float) + "\n"
    if out.suffix == ".json":
        from ..util.atomic import write_text

        out.parent.mkdir(parents=True, exist_ok=True)
        write_text(out, text)
        return out
    from ..gap.stats import _csv
    from ..util.atomic import write_set

    writers: dict[str, Callable[[Path], Any]] = {
        "gap.json": lambda p: p.write_text(text, encoding="utf-8")}
    if result is not None:
        agents = [{k: v for k, v in a.items() if k != "top_blockers"}
                  | {"top_blockers": json.dumps(a["top_blockers"])} for a in result["agents"]]
        writers["agents.csv"] = lambda p: p.write_text(_csv(agents), encoding="utf-8")
        writers["actions.csv"] = lambda p: p.write_text(_csv(result["actions"]),
                                                        encoding="utf-8")
        if result.get("schedule") is not None:
            sched_text = json.dumps(_finite(result["schedule"]), indent=1) + "\n"
            writers["schedule.json"] = lambda p: p.write_text(sched_text, encoding="utf-8")
        if pictures:
            from ..gap.plots import available
            from ..gap.plots import writers as picture_writers

            if available():
                writers.update(picture_writers([result], agvs))
            else:
                from ..gap.stats import _no_pictures

                _no_pictures()
    write_set(out, writers, meta={"mode": report.get("mode")})
    return out


def _finite(obj: Any) -> Any:
    from ..gap.stats import _finite as fin

    return fin(obj)


# ----------------------------------------------------------------------------- tables

PART_LABELS = {
    "dependency": "waiting on a dependency", "accel_decel": "acceleration / deceleration",
    "turning": "turning", "control": "control latency (decide, settle)",
    "injected": "injected delays", "failures": "failures / corridors",
    "rotation_repair": "rotation repair (planned ticks added)",
    "freeze_recovery": "recovery from freezes", "dwell_overrun": "dwell overrun",
    "reorder_gain": "switched edges (reorder gain)",
    "faster_than_plan": "faster than the plan (gain)",
    "plan_waits_skipped": "plan waits skipped (gain)"}


def _open_table(console: Console, title: str, r: dict) -> None:
    from ..gap.open_loop import PARTS

    motion = r.get("timing") == "motion"
    t = Table(title=f"{title}  planned: {r.get('timing', 'unit')} timing", show_header=True)
    for col, just in (("figure", "left"), ("planned", "right"), ("executed", "right"),
                      ("executed / planned", "right")):
        t.add_column(col, justify=just)
    t.add_row(escape("makespan (s) [makespan_ratio]"), _f(r["planned_makespan_s"], ".1f"),
              _f(r["executed_makespan_s"], ".2f"), _f(r["makespan_ratio"]))
    if motion:
        t.add_row(escape("  unit timing [makespan_ratio_unit]"),
                  _f(r.get("planned_makespan_s_unit"), ".1f"), "", _f(r.get("makespan_ratio_unit")))
    t.add_row(escape("sum of costs (s) [sum_of_costs_ratio]"),
              _f(r["planned_sum_of_costs_s"], ".1f"), _f(r["executed_sum_of_costs_s"], ".2f"),
              _f(r["sum_of_costs_ratio"]))
    if motion:
        t.add_row(escape("  unit timing [sum_of_costs_ratio_unit]"),
                  _f(r.get("planned_sum_of_costs_s_unit"), ".1f"), "",
                  _f(r.get("sum_of_costs_ratio_unit")))
    if "orders_makespan_ratio" in r:
        t.add_row(escape("all orders done (s) [orders_makespan_ratio]"),
                  _f(r["planned_orders_makespan_s"], ".1f"),
                  _f(r["executed_orders_makespan_s"], ".2f"), _f(r["orders_makespan_ratio"]))
        t.add_row(escape("throughput [tp_ratio]"), "", "", _f(r.get("tp_ratio")))
        t.add_row(escape("order latency [latency_ratio]"), "", "", _f(r.get("latency_ratio")))
    if r.get("cycle_repairs"):
        t.add_row(escape(f"makespan after {r['cycle_repairs']} rotation repair(s) (s) "
                         "[repaired_makespan_s]"), _f(r["repaired_makespan_s"], ".1f"), "", "")
    console.print(t)
    c = Table(title=f"lost time (executed - planned finish), {r['agents']} AGVs"
                    + (f", against the unit plan (motion timing: {_f(r['lost_s_fleet_total'], '.2f')}"
                       " s in all)" if motion else ""), show_header=True)
    for col in ("cause", "fleet total (s)", "per AGV mean (s)"):
        c.add_column(col, justify="left" if col == "cause" else "right")
    unit = "_unit" if motion else ""
    c.add_row(escape(f"total [lost_s{unit}]"), _f(r[f"lost_s_fleet_total{unit}"], ".2f"),
              _f(r[f"lost_s_per_agv_mean{unit}"], ".2f"))
    for p in PARTS:
        c.add_row(escape(f"  {PART_LABELS[p]} [lost_{p}_s]"),
                  _f(r[f"lost_{p}_s_fleet_total"], ".2f"),
                  _f(r[f"lost_{p}_s_per_agv_mean"], ".2f"))
    console.print(c)
    console.print(f"actions late: {r['actions_late']} of {r['actions']}; contacts AGV-AGV "
                  f"{r.get('agv_contacts')}, AGV-static {r.get('static_contacts')}; min "
                  f"clearance {_f(r.get('min_clearance_m'))} m; limit violations "
                  f"{r.get('limit_violations')}; deadlocks "
                  f"{r.get('deadlocks')}; real-time factor {_f(r.get('real_time_factor'), '.1f')}",
                  markup=False)


def _closed_table(console: Console, sc, report: dict) -> None:
    g, p = report["grid"], report["physics"]
    table = Table(title=f"closed-loop gap: {sc.name}  seed {sc.seed}  {sc.scheduler.name} + "
                        f"{sc.planner.name}", show_header=True)
    for col, just in (("figure", "left"), ("grid", "right"), ("physics", "right"),
                      ("physics / grid", "right")):
        table.add_column(col, justify=just)
    table.add_row(escape("makespan (ticks) [makespan_ratio]"), str(g["ticks"]), str(p["ticks"]),
                  _f(report["makespan_ratio"]))
    table.add_row(escape("throughput (orders/tick) [tp_ratio]"), _f(g["throughput"]),
                  _f(p["throughput"]), _f(report["tp_ratio"]))
    table.add_row(escape("order latency mean (ticks) [latency_ratio]"),
                  _f(g["order_latency_mean_ticks"], ".1f"),
                  _f(p["order_latency_mean_ticks"], ".1f"), _f(report["latency_ratio"]))
    table.add_row("success rate", _f(g["success_rate"]), _f(p["success_rate"]), "")
    table.add_row(escape("replans [replans = physics - grid]"), str(g["replans"]),
                  str(p["replans"]), str(report["replans"]))
    for label, key in (("delay: dependency waits, fleet total (s)", "delay_dependency_wait_s"),
                       ("delay: kinematic lag incl. turns, fleet total (s)",
                        "delay_kinematic_s"),
                       ("  of which turns, fleet total (s)", "delay_turns_s"),
                       ("delay: injected, fleet total (s)", "delay_injected_s"),
                       ("AGV-AGV contacts", "agv_contacts"),
                       ("AGV-static contacts", "static_contacts"),
                       ("min clearance, edge to edge (m)", "min_clearance_m"),
                       ("limit violations", "limit_violations"),
                       ("deadlocks", "deadlocks"),
                       ("real-time factor", "real_time_factor")):
        v = p.get(key)
        table.add_row(escape(f"{label} [{key}]"), "", _f(v, ".2f"), "")
    console.print(table)


# ----------------------------------------------------------------------------- many seeds

HEADLINE = {
    "open": ("makespan_ratio", "sum_of_costs_ratio", "orders_makespan_ratio", "tp_ratio",
             "latency_ratio", "lost_s_per_agv_mean", "lost_dependency_s_per_agv_mean",
             "lost_accel_decel_s_per_agv_mean", "lost_turning_s_per_agv_mean",
             "lost_faster_than_plan_s_per_agv_mean", "agv_contacts", "deadlocks"),
    "closed": ("makespan_ratio", "tp_ratio", "latency_ratio", "replans", "deadlocks",
               "agv_contacts", "delay_dependency_wait_s_fleet_total",
               "delay_kinematic_s_fleet_total"),
}


def _many(sc, seeds: list[int], mode: str, workers: int | None, out: Path | None,
          json_out: bool, agvs: list[int] | None, pictures: bool, quiet: bool) -> None:
    from ..gap.stats import run_seeds, summarise, write_outputs

    if workers is None:
        workers = min(2, os.cpu_count() or 1)
    if workers < 1:
        raise WareroverError(f"--workers must be >= 1 (got {workers})")
    if out is not None and out.suffix == ".json":
        raise WareroverError(f"{out}: --seeds writes a folder (summary.json, agents.csv, ...)"
                             ", not one .json file")
    header_mode = MODE_LABEL[mode]
    _check_out(out or Path("runs") / f"{sc.name}-seeds-{header_mode}-gap")
    check_agv_ids(agvs or (), sc.fleet.size, str(sc.source or sc.name))
    show = not quiet and not json_out and err_console.is_terminal
    if show:
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        with Progress(TextColumn(f"gap ({MODE_LABEL[mode]}) {sc.name}"), BarColumn(),
                      MofNCompleteColumn(), TextColumn("seeds"), TimeElapsedColumn(),
                      TimeRemainingColumn(), console=err_console, transient=True) as bar:
            task = bar.add_task("seeds", total=len(seeds))
            results, failed = run_seeds(sc, seeds, mode, workers,
                                        lambda s, r, e: bar.advance(task))
    else:
        results, failed = run_seeds(sc, seeds, mode, workers)
    for s, e in failed:
        err_console.print(f"seed {s} failed: {e}", markup=False, highlight=False)
    if not results:
        raise WareroverError(f"every seed failed ({len(failed)})")
    header = {"mode": MODE_LABEL[mode], "timing": sc.planner.timing if mode == "open" else "unit",
              "scenario": sc.name, "scheduler": sc.scheduler.name,
              "planner": sc.planner.name, "source": sc.source}
    folder = out or Path("runs") / f"{sc.name}-seeds-{header['mode']}-gap"
    write_outputs(folder, header=header, results=results, failed=failed, pictures=pictures,
                  picture_agvs=agvs)
    stats = summarise(results)
    if json_out:
        print(json.dumps(_finite({**header, "seeds": [r["seed"] for r in results],
                                  "failed": [s for s, _ in failed], "statistics": stats}),
                         indent=2, sort_keys=True))
        return
    t = Table(title=f"{header['mode']} gap: {sc.name}  {sc.scheduler.name} + {sc.planner.name}"
                    f"  {len(results)} seeds  planned: {header['timing']} timing",
              show_header=True)
    for col in ("figure", "mean", "95% CI of the mean", "median", "p95", "max"):
        t.add_column(col, justify="left" if col == "figure" else "right")
    extra = ("makespan_ratio_unit", "orders_makespan_ratio_unit") \
        if header["timing"] == "motion" else ()
    for k in HEADLINE[mode] + extra:
        s = stats.get(k)
        if not s or not s["n"]:
            continue
        t.add_row(escape(k), _f(s["mean"]), f"{_f(s['ci95_low'])} .. {_f(s['ci95_high'])}",
                  _f(s["median"]), _f(s["p95"]), _f(s["max"]))
    console = Console()
    console.print(t)
    console.print(f"wrote {folder} (summary.json: every figure)", markup=False)


# ----------------------------------------------------------------------------- a plan file

def _plan_gap(floor: Path, plan: Path, fmt: str | None, yx: bool, fleet: Path | None,
              delays: str | None, tick_s: float, dt_s: float, seed: int, out: Path | None,
              json_out: bool, agvs: list[int] | None, pictures: bool, quiet: bool,
              timing: str = "unit", video: Path | None = None, ghost: bool = False,
              reorder: str = "none", max_ticks: int | None = None) -> None:
    from ..gap.core import plan_gap

    if not (math.isfinite(tick_s) and tick_s > 0):
        raise WareroverError(f"--tick-s must be a positive number (got {tick_s})")
    if not (math.isfinite(dt_s) and 0 < dt_s <= tick_s):
        raise WareroverError(f"--dt-s must be in (0, tick_s] (got {dt_s})")
    _check_out(out or Path("runs") / f"gap-{plan.stem}")
    show = not quiet and not json_out and err_console.is_terminal
    bar, update = _bar(show)
    with bar:
        g = plan_gap(floor, plan, fleet=fleet, fmt=fmt, xy=not yx, delays=delays,
                     tick_s=tick_s, dt_s=dt_s, seed=seed, timing=timing, agvs=agvs or (),
                     progress=update, reorder=reorder, max_ticks=max_ticks)
    warn_incomplete(g.report["completed"], g.report["physics"]["ticks_run"],
                    "--max-ticks" if max_ticks else "10x the plan's makespan + 200")
    _print_repairs(g.report)
    if video is not None:
        _video(g, video, f"plan {plan.name}", show, ghost)
    written = _write_one(out or Path("runs") / f"gap-{plan.stem}", g.report,
                         _result(g, seed), agvs, pictures)
    if json_out:
        print(json.dumps(_finite({k: v for k, v in g.report.items()
                                  if k not in ("grid", "physics")}), indent=2, sort_keys=True))
        return
    console = Console()
    _open_table(console, f"open-loop gap: plan {plan.name} on {floor.name}  "
                         f"{g.report['agents']} agents", g.report)
    console.print(f"wrote {written}", markup=False)
