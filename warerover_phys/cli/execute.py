"""The ``warerover execute`` command: another solver's MAPF plan on a floor, executed and
measured."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from ..errors import WareroverError
from ..util.console import err_console, fail_os
from ..util.console import fail as _fail
from .options import MaxTicksOpt, ReorderOpt, _check_video_out, check_max_ticks, warn_incomplete


def execute(floor: Annotated[Path, typer.Argument(
                help="Floor: a MovingAI .map, a layout YAML or a scenario YAML.")],
            plan: Annotated[Path, typer.Option(
                "--plan", help="Plan file: lacam / MAPF visualizer, MAPF-LNS2 / EECBS "
                               "(Agent i:(r,c)->...), timed points, Robot Runners JSON or "
                               "paths.json (format detected from the content).")],
            fmt: Annotated[str | None, typer.Option(
                "--format", help="Force the plan format: lacam | lns | timed | robotrunners | "
                                 "paths_json.")] = None,
            yx: Annotated[bool, typer.Option(
                "--yx/--xy", help="Timed points: (row,col,t) instead of (x,y,t).")] = False,
            fleet: Annotated[Path | None, typer.Option(
                help="AGV types (YAML); default 1x1, 0.7 m bodies, 1 m/s.")] = None,
            executor: Annotated[str, typer.Option(
                help="Executor: physics | grid | an entry point | package.module:Class.")
                                ] = "physics",
            seed: Annotated[int, typer.Option(help="Seed of the random delays.")] = 0,
            delays: Annotated[str | None, typer.Option(
                help="Random delays MODEL:PROB[:MIN:MAX] ticks, e.g. bernoulli:0.05:1:10.")
                              ] = None,
            strict: Annotated[bool, typer.Option(
                help="Refuse a plan with rotations (dependency cycles) instead of "
                     "repairing them.")] = False,
            tick_s: Annotated[float, typer.Option(help="Seconds per plan timestep.")] = 1.0,
            dt_s: Annotated[float, typer.Option(help="Physics step (seconds).")] = 0.02,
            out: Annotated[Path | None, typer.Option(
                help="Output folder (default: runs/execute-PLAN).")] = None,
            video: Annotated[Path | None, typer.Option(
                help="Also render the execution to this MP4 (H.264).")] = None,
            json_out: Annotated[bool, typer.Option(
                "--json", help="Print metrics as JSON instead of a table.")] = False,
            export: Annotated[Path | None, typer.Option(
                help="Write the executed paths to this file.")] = None,
            export_format: Annotated[str, typer.Option(
                help="Format of --export (as --format).")] = "lacam",
            quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")
                             ] = False,
            sets: Annotated[list[str] | None, typer.Option(
                "--set", help="Another executor option FIELD=VALUE (repeatable; YAML "
                              "values), as in a scenario's executor section: "
                              "no_slip=true, payload=true, comm_latency_s=0.2, "
                              "shelf_contacts=true, park=false, adg=false ...; "
                              "robot=diffdrive: no_slip and wheel limits, as a "
                              "scenario's robot: diffdrive")] = None,
            reorder: ReorderOpt = None,
            max_ticks: MaxTicksOpt = None,
            ) -> None:
    """Execute a plan made elsewhere exactly as written (no scheduler, no replanning) on
    the physics or grid executor; write metrics, events, paths and trajectories."""
    try:
        check_max_ticks(max_ticks)
        job = _prepare(floor, plan, fmt=fmt, yx=yx, fleet=fleet, executor=executor, seed=seed,
                       delays=delays, strict=strict, tick_s=tick_s, dt_s=dt_s, out=out,
                       video=video, export=export, export_format=export_format, sets=sets,
                       reorder=reorder)
        result = _execute(job, executor=executor, seed=seed, tick_s=tick_s, dt_s=dt_s,
                          show=not quiet and not json_out and err_console.is_terminal,
                          max_ticks=max_ticks)
        files = _write(job, result, plan=plan, executor=executor, tick_s=tick_s, video=video,
                       export=export, export_format=export_format)
    except WareroverError as err:
        _fail(err)
    except OSError as err:
        fail_os(err)
    m = result.metrics
    warn_incomplete(m["completed"], m["ticks"], "--max-ticks" if max_ticks else
                    "10x the plan's makespan + 100")
    if json_out:
        typer.echo(json.dumps(m, indent=2, sort_keys=True, default=float))
        return
    _print_metrics(m, plan, floor, executor)
    for f in files.values():
        typer.echo(f"wrote {f}")


@dataclass
class _Job:
    """What ``execute`` runs: the checked inputs, the plan (rotations repaired) and its floor."""

    out_dir: Path
    delay_spec: Any
    options: dict
    layout: Any
    types: list
    the_plan: Any
    given: Any
    repairs: list


def _prepare(floor: Path, plan: Path, *, fmt, yx, fleet, executor, seed, delays, strict,
             tick_s, dt_s, out, video, export, export_format, sets, reorder) -> _Job:
    """Check every option, read the floor, the fleet and the plan, validate the plan and
    repair its rotations (each repair printed), in that order."""
    import math

    from ..execute import (
        check_reorder,
        executor_options,
        executor_spec,
        load_fleet,
        load_floor,
        parse_delays,
        repair_cycles,
        robot_model,
        validate_plan,
    )
    from ..inputs import check_output_dir, check_output_file, check_seed
    from ..plans import check_format, format_plan, read_plan

    if not (math.isfinite(tick_s) and tick_s > 0):
        raise WareroverError(f"--tick-s must be a positive number (got {tick_s})")
    if not (math.isfinite(dt_s) and 0 < dt_s <= tick_s):
        raise WareroverError(f"--dt-s must be in (0, tick_s] (got {dt_s})")
    check_seed(seed)
    out_dir = check_output_dir(out or Path("runs") / f"execute-{plan.stem}")
    if video is not None:
        _check_video_out(video)
    if export is not None:
        check_output_file(export, "--export")
        check_format(export_format, "--export-format")
    delay_spec = parse_delays(delays)
    options = executor_options(sets)
    if reorder is not None:
        options["reorder"] = check_reorder(reorder)
    mode = options.get("reorder", "none")
    if mode != "none" and (executor != "physics" or options.get("adg") is False):
        raise WareroverError(f"--reorder {mode} switches edges of the dependency graph: it "
                             f"needs --executor physics with executor.adg=true (got "
                             f"--executor {executor}"
                             + (", executor.adg=false)" if executor == "physics" else ")"))
    robot = {k: options.pop(k) for k in ("robot",) if k in options}
    executor_spec(executor, dt_s=dt_s, delays=delay_spec, options=options)  # check early
    layout, types_by_name, kinds = load_floor(floor)
    the_plan = read_plan(plan, fmt, xy=not yx)
    types = load_fleet(fleet, the_plan.num_agents, types_by_name, kinds)
    options, types = robot_model({**options, **robot}, types)
    sizes = [t.footprint for t in types]
    validate_plan(the_plan, layout, sizes, source=str(plan))
    if export is not None:  # can the export format hold this plan? (before the work)
        format_plan(the_plan, export_format)
    given = the_plan
    the_plan, repairs = repair_cycles(the_plan, layout, sizes, strict=strict,
                                      source=str(plan))
    if repairs:
        validate_plan(the_plan, layout, sizes, source=str(plan))
        for r in repairs:
            err_console.print(f"repaired a rotation at timestep {r.timestep}: cells "
                              f"{[list(c) for c in r.cells]} by a detour of {r.moves} "
                              f"single moves (agents {list(r.agents)})", highlight=False)
    return _Job(out_dir, delay_spec, options, layout, types, the_plan, given, repairs)


def _execute(job: _Job, *, executor: str, seed: int, tick_s: float, dt_s: float, show: bool,
             max_ticks: int | None = None):
    """The plan on the executor, with a progress bar on a terminal (``show``)."""
    from ..execute import execute_plan

    if show:
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        with Progress(TextColumn("execute"), BarColumn(),
                      TextColumn("tick {task.completed:.0f} (plan {task.total:.0f})"),
                      TimeElapsedColumn(), console=err_console, transient=True) as bar:
            task = bar.add_task("execute", total=job.the_plan.makespan)
            return execute_plan(job.the_plan, job.layout, job.types, executor=executor,
                                seed=seed, delays=job.delay_spec, tick_s=tick_s, dt_s=dt_s,
                                repairs=job.repairs, given=job.given, options=job.options,
                                max_ticks=max_ticks,
                                progress=lambda t, h: bar.update(task, completed=t))
    return execute_plan(job.the_plan, job.layout, job.types, executor=executor, seed=seed,
                        delays=job.delay_spec, tick_s=tick_s, dt_s=dt_s, repairs=job.repairs,
                        given=job.given, options=job.options, max_ticks=max_ticks)


def _write(job: _Job, result, *, plan: Path, executor: str, tick_s: float,
           video: Path | None, export: Path | None, export_format: str) -> dict:
    """The output folder, ``--export`` and ``--video``: the files written, by kind."""
    from ..execute import executed_plan, write_execution
    from ..plans import write_plan

    files = write_execution(result, job.the_plan, job.layout, job.types, job.out_dir, tick_s)
    if export is not None:
        write_plan(executed_plan(result, job.layout.cols), export, export_format)
        files["export"] = export
    if video is not None:
        from ..render import Style, load_trajectory, render_video

        try:
            render_video(load_trajectory(files["trajectory"]), video,
                         style=Style(title=f"{plan.name} on {executor}"))
        except ValueError as err:
            raise WareroverError(f"--video: {err}") from None
        files["video"] = video
    return files


def _print_metrics(m: dict, plan: Path, floor: Path, executor: str) -> None:
    table = Table(title=f"{plan.name} on {floor.name}: {m['agents']} agents, {executor}")
    table.add_column("metric")
    table.add_column("planned", justify="right")
    table.add_column("executed", justify="right")
    table.add_row("makespan (ticks)", str(m["planned_makespan_ticks"]),
                  str(m["executed_makespan_ticks"]))
    table.add_row("sum of costs (ticks)", str(m["planned_sum_of_costs_ticks"]),
                  str(m["executed_sum_of_costs_ticks"]))
    table.add_row("ratio executed / planned", "",
                  f"{m['makespan_ratio']:.3f} / {m['sum_of_costs_ratio']:.3f}")
    for key in ("agv_contacts", "static_contacts", "min_clearance_m", "limit_violations",
                "deadlocks",
                "cycle_repairs", "real_time_factor"):
        if key in m:
            v = m[key]
            table.add_row(key, "", f"{v:.3f}" if isinstance(v, float) else str(v))
    Console().print(table)
