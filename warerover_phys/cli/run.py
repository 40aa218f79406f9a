"""The ``warerover run`` command: one episode, its metrics table and output files."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from ..errors import ScenarioError, WareroverError
from ..util.console import fail as _fail
from ..util.console import fail_os
from .options import (
    ExecOpt,
    FpsOpt,
    OrdersOpt,
    PlanOpt,
    SchedOpt,
    SeedOpt,
    SetOpt,
    SizeOpt,
    SpeedOpt,
    _Bar,
    _check_frames,
    _check_video_out,
    _run_video,
    _scenario,
    _show_progress,
    _video_style,
)


def run(scenario: Annotated[Path, typer.Argument(help="Scenario YAML file.")],
        seed: SeedOpt = None,
        out: Annotated[Path | None, typer.Option(
            help="Output folder (default: runs/NAME-seedN).")] = None,
        json_out: Annotated[bool, typer.Option(
            "--json", help="Print metrics as JSON instead of a table.")] = False,
        set_: SetOpt = None, scheduler: SchedOpt = None, planner: PlanOpt = None,
        executor: ExecOpt = None, orders: OrdersOpt = None,
        quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
        video: Annotated[Path | None, typer.Option(
            help="Also render the episode to this MP4 (H.264).")] = None,
        fps: FpsOpt = 30.0, speed: SpeedOpt = None, size: SizeOpt = "720p",
        ) -> None:
    """Run one episode and write metrics.json, events.jsonl and paths.json (and an MP4 with
    --video)."""
    from ..inputs import check_output_dir
    from ..outputs import write_outputs
    from ..sim import Simulation

    try:
        style = _video_style(size, fps, speed, None) if video is not None else None
        if video is not None:
            _check_video_out(video)
        if out is not None:
            check_output_dir(out)
        sc = _scenario(scenario, set_, seed, scheduler, planner, executor, orders)
        out_dir = check_output_dir(out or Path("runs") / f"{sc.name}-seed{sc.seed}")
        if video is not None and speed is not None:
            _check_frames(sc.max_ticks * sc.tick_s, fps, speed)
        sim = Simulation(sc)
        show = _show_progress(quiet, json_out)
        with _Bar(show, sc.name, sc.max_ticks, "tick", extra="orders") as bar:
            result = sim.run((lambda t, done, gen: bar.update(
                t, extra=f"orders {done}/{gen}")) if show else None)
        files = write_outputs(result, out_dir, with_trajectory=video is not None)
        if video is not None:
            with _Bar(show, f"video {video.name}", 1, "frame") as bar:
                files.update(_run_video(result, files, video, style, fps, speed, sc.name,
                                        progress=bar.update if show else None))
    except ScenarioError as err:  # raised while running (plug-ins, corridors): name the file
        _fail(err.with_file(str(scenario)))
    except WareroverError as err:
        _fail(err)
    except OSError as err:
        fail_os(err)
    m = result.metrics
    if json_out:
        typer.echo(json.dumps(m, indent=2, sort_keys=True))
        return
    table = Table(title=f"{sc.name}  seed {sc.seed}  {sc.scheduler.name} + {sc.planner.name} "
                        f"on {sc.executor.name}", show_header=True)
    table.add_column("metric")
    table.add_column("value", justify="right")
    rows = [("success rate (SR)", f"{m['success_rate']:.3f}"),
            ("throughput (TP, orders/tick)", f"{m['throughput']:.3f}"),
            ("computation (CT total, s)", f"{m['ct_total_s']:.3f}"),
            ("CT per tick mean / p99 (ms)", f"{m['ct_mean_ms']:.2f} / {m['ct_p99_ms']:.2f}"),
            ("  scheduler mean (ms)", f"{m['ct_sched_mean_ms']:.2f}"),
            ("  planner mean (ms)", f"{m['ct_plan_mean_ms']:.2f}"),
            ("ticks", str(m["ticks"])),
            ("orders completed / generated", f"{m['orders_completed']} / {m['orders_generated']}"),
            ("order latency mean (ticks)", f"{m['order_latency_mean_ticks']:.1f}"),
            ("blocked moves", str(m["blocked_moves"])),
            ("collisions", str(m["collisions"])),
            ("replans / failures / detours",
             f"{m['replans']} / {m['plan_failures']} / {m['goal_busy_detours']}")]
    if sc.executor.name == "physics":
        sep = m.get("min_clearance_m")
        rows += [("AGV-AGV / static contacts", f"{m['agv_contacts']} / {m['static_contacts']}"),
                 ("min clearance (m)", "-" if sep is None else f"{sep:.3f}"),
                 ("limit violations", str(m.get("limit_violations", 0))),
                 ("deadlocks / executor replans",
                  f"{m['deadlocks']} / {m['executor_replans']}"),
                 ("real-time factor", f"{m['real_time_factor']:.1f}x")]
    for k, v in rows:
        table.add_row(k, v)
    console = Console()
    console.print(table)
    names = ", ".join(f.name for k, f in files.items() if k != "metrics")
    console.print(f"wrote {files['metrics']}, {names}", markup=False)
