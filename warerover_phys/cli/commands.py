"""The ``warerover`` command line.

``warerover run SCENARIO`` runs one episode and writes ``metrics.json``, ``events.jsonl`` and
``paths.json`` (and ``trajectories.npz`` on physics); ``warerover gap SCENARIO`` executes the
ideal grid run's plan unchanged on physics and reports the sim-to-real gap (``--mode
closed``: two closed-loop episodes); ``warerover check SCENARIO`` only loads and
checks a scenario; ``warerover render TRAJECTORY_FILE --out PATH`` re-renders a recorded run
to MP4 or PNG (``run --video PATH`` renders right after the run); ``warerover
check-trajectory RUN_DIR`` proves that no two bodies met between recorded samples. Bad input
prints one line naming the file, field and value, and exits with code 2.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from ..errors import ScenarioError, WareroverError
from ..util.console import err_console
from ..util.console import fail as _fail
from ..util.media import check_media_path
from .solve import mark_entered, run_solve  # `solve`'s body and its fast path

__all__ = ["app", "main"]

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="warerover-phys: closed-loop robotic warehouse simulator.")

SetOpt = Annotated[list[str] | None, typer.Option(
    "--set", help="Override any scenario field: --set orders.pattern=burst (repeatable).")]
SeedOpt = Annotated[int | None, typer.Option(help="Episode seed (overrides the file's).")]
ReorderOpt = Annotated[str | None, typer.Option(
    help="Physics: reorder the dependency graph under delays: none | greedy | milp "
         "(executor.reorder).")]
SchedOpt = Annotated[str | None, typer.Option(help="Scheduler: ta | rd.")]
PlanOpt = Annotated[str | None, typer.Option(help="Planner: astar | cbs | pibt | lacam | learned | plug-in.")]
ExecOpt = Annotated[str | None, typer.Option(help="Executor: grid | physics | plug-in.")]
OrdersOpt = Annotated[str | None, typer.Option(
    help="Order pattern: oneshot | constant | wave | hotspot | burst.")]
FpsOpt = Annotated[float, typer.Option(help="Video frames per second.")]
SpeedOpt = Annotated[float | None, typer.Option(
    help="Playback speed, simulated s per video s (default: real time, or faster to keep "
         "the video under a minute).")]
SizeOpt = Annotated[str, typer.Option(help="Frame size: 720p | 1080p | WxH.")]


def _overrides(sets: list[str] | None, seed: int | None, scheduler: str | None,
               planner: str | None, executor: str | None, orders: str | None,
               ) -> list[tuple[str, Any]]:
    from ..config import parse_override
    from ..inputs import check_seed

    if seed is not None:
        check_seed(seed)
    out = [parse_override(s) for s in sets or []]
    named = {"seed": seed, "scheduler.name": scheduler, "planner.name": planner,
             "executor.name": executor, "orders.pattern": orders}
    out += [(k, v) for k, v in named.items() if v is not None]
    return out


def _scenario(path: Path, sets: list[str] | None, seed: int | None, scheduler: str | None,
              planner: str | None, executor: str | None, orders: str | None):
    """Load ``path`` with the command line's overrides (errors name the file)."""
    from ..config import load_scenario

    try:
        overrides = _overrides(sets, seed, scheduler, planner, executor, orders)
    except WareroverError as err:
        raise (err.with_file(str(path)) if hasattr(err, "with_file") else err) from None
    from ..registry import check_plugins

    scenario = load_scenario(path, overrides)
    check_plugins(scenario)
    return scenario


def _load(scenario: Path, overrides: list[tuple[str, Any]]):
    from ..config import load_scenario
    from ..registry import check_plugins
    from ..world import World

    sc = load_scenario(scenario, overrides)
    world = World.build(sc)
    check_plugins(sc)
    return sc, world


class _Bar:
    """A rich progress bar on stderr for long work, or nothing: not with ``--json`` or
    ``--quiet``, nor when stderr is not a terminal (as ``execute`` does). ``update`` is the
    callback to hand to the work: ``update(done, total, **fields)``."""

    def __init__(self, show: bool, label: str, total: float, unit: str,
                 extra: str = "") -> None:
        self.show, self.label, self.total, self.unit, self.extra = show, label, total, unit, extra
        self._bar = None
        self._task = None

    def __enter__(self) -> _Bar:
        if self.show:
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

            columns = [TextColumn("{task.description}"), BarColumn(),
                       TextColumn(f"{self.unit} {{task.completed:.0f}}/{{task.total:.0f}}")]
            if self.extra:
                columns.append(TextColumn("{task.fields[extra]}"))
            self._bar = Progress(*columns, TimeElapsedColumn(), console=err_console,
                                 transient=True)
            self._bar.__enter__()
            self._task = self._bar.add_task(self.label, total=self.total, extra="")
        return self

    def update(self, done: float, total: float | None = None, extra: str = "") -> None:
        if self._bar is not None:
            self._bar.update(self._task, completed=done, extra=extra,
                             **({"total": total} if total is not None else {}))

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.__exit__(*exc)


def _show_progress(quiet: bool, json_out: bool = False) -> bool:
    return not quiet and not json_out and err_console.is_terminal


@app.command()
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
        _fail(WareroverError(f"{getattr(err, 'filename', '') or ''}: {err.strerror or err}"))
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


def _check_video_out(video: Path, option: str = "--video", still: bool = False) -> None:
    """Refuse a video (or, ``still``, image) output path before any work: its extension, a
    folder in its place, a place no file can be written."""
    from ..inputs import check_output_file

    check_media_path(video, option, still=still)
    check_output_file(video, option)


def _check_frames(longest_s: float, fps: float, speed: float) -> None:
    """Refuse, before the run, a video of an episode of up to ``longest_s`` simulated seconds
    that could need more frames than a video may have."""
    from ..render.video import MAX_FRAMES, frame_count

    n = frame_count(longest_s, fps, speed)
    if n > MAX_FRAMES:
        raise WareroverError(f"--speed: the episode may last {longest_s:g} s: at {speed:g}x "
                             f"and {fps:g} fps that is up to {n:,} frames (at most "
                             f"{MAX_FRAMES:,}): raise --speed or lower --fps")


def _video_style(size: str, fps: float, speed: float | None, viewport: str | None,
                 paths: bool = True):
    """Check the video options before any work is done; the render ``Style``."""
    try:
        from ..render import Style, parse_size
    except ImportError as err:
        raise WareroverError(f"rendering needs opencv-python-headless and av ({err}): "
                             "pip install 'warerover-phys[render]'") from None
    if not fps > 0 or fps > 240:
        raise WareroverError(f"--fps: must be in (0, 240] (got {fps})")
    if speed is not None and not 0 < speed < float("inf"):
        raise WareroverError(f"--speed: must be positive and finite (got {speed})")
    view = None
    if viewport is not None:
        parts = viewport.split(",")
        if len(parts) != 4 or not all(p.strip().isdigit() for p in parts):
            raise WareroverError(f"--viewport: expected row0,col0,row1,col1 (got {viewport!r})")
        view = tuple(int(p) for p in parts)
    try:
        return Style(size=parse_size(size), viewport=view, show_paths=paths)
    except ValueError as err:
        raise WareroverError(f"--size/--viewport: {err}") from None


def _run_video(result, files: dict, video: Path, style, fps: float, speed: float | None,
               title: str, progress=None) -> dict[str, Path]:
    """Render a finished episode to ``video``; a grid episode also gets a
    ``trajectories.npz`` so that ``warerover render`` can redo it."""
    from dataclasses import replace

    from ..outputs import write_trajectory
    from ..render import grid_trajectory, recording_from_episode, render_video

    out = {}
    if "trajectory" not in files:
        out["trajectory"] = files["metrics"].with_name("trajectories.npz")
        write_trajectory(grid_trajectory(result), out["trajectory"])
    try:
        render_video(recording_from_episode(result), video, fps=fps, speed=speed,
                     style=replace(style, title=title), progress=progress)
    except ValueError as err:
        raise WareroverError(f"--video: {err}") from None
    out["video"] = video
    return out


@app.command()
def render(trajectory: Annotated[Path, typer.Argument(
               metavar="TRAJECTORY_FILE",
               help="trajectories.npz of a run (or its folder); events.jsonl and paths.json "
                    "beside it add order counts and planned paths.")],
           out: Annotated[Path, typer.Option(help="Output MP4 (PNG with --png or --heat).")],
           png: Annotated[float | None, typer.Option(
               help="Write the frame at this tick as a PNG instead of a video.")] = None,
           heat: Annotated[str | None, typer.Option(
               help="Write a PNG of the whole run instead: wait (seconds waited per cell) "
                    "or traffic (passes per cell).")] = None,
           fps: FpsOpt = 30.0, speed: SpeedOpt = None, size: SizeOpt = "720p",
           viewport: Annotated[str | None, typer.Option(
               help="Show only cells row0,col0,row1,col1 (inclusive).")] = None,
           paths: Annotated[bool, typer.Option(help="Draw the path ahead of each AGV.")] = True,
           ghost: Annotated[bool, typer.Option(
               "--ghost/--no-ghost", help="Draw each AGV's planned pose (where its plan "
                                          "puts it at this time) as a ghost.")] = False,
           workers: Annotated[int, typer.Option(
               help="Processes drawing and encoding runs of frames, joined into one H.264 "
                    "file without re-encoding.")] = 1,
           preset: Annotated[str, typer.Option(
               help="libx264 speed preset (ultrafast .. veryslow).")] = "superfast",
           quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress.")] = False,
           ) -> None:
    """Re-render a recorded run to MP4 (or one frame, or a heat map, to PNG) without
    re-simulating."""
    show = _show_progress(quiet)
    try:
        from dataclasses import replace

        style = replace(_video_style(size, fps, speed, viewport, paths), ghosts=ghost)
        _render_checks(out, png, heat, workers, preset)
        from ..render import load_trajectory

        if show:
            err_console.print(f"reading {escape(str(trajectory))} ...", highlight=False)
        rec = load_trajectory(trajectory)
        rows, cols = rec.grid.shape
        if style.viewport is not None and (style.viewport[0] >= rows or
                                           style.viewport[1] >= cols):
            raise WareroverError(f"--viewport: {viewport} starts outside the {rows}x{cols} "
                                 "layout")
        if png is not None or heat is not None:
            _render_still(rec, out, png, heat, style)
            typer.echo(f"wrote {out}")
            return
        info = _render_movie(rec, out, style, fps, speed, workers, preset, show)
    except WareroverError as err:
        _fail(err)
    except ValueError as err:
        _fail(WareroverError(str(err)))
    except OSError as err:
        _fail(WareroverError(f"{getattr(err, 'filename', '') or ''}: {err.strerror or err}"))
    typer.echo(f"wrote {out}: {info['frames']} frames at {info['fps']:g} fps, "
               f"{info['speed']:g}x, {info['codec']}, {info['render_fps']:.1f} frames/s "
               f"rendered with {info['workers']} worker{'s' * (info['workers'] > 1)}")


def _render_checks(out: Path, png: float | None, heat: str | None, workers: int,
                   preset: str) -> None:
    """Refuse bad ``render`` options before the recording is read."""
    from ..render.heat import HEAT_KINDS

    if png is not None and heat is not None:
        raise WareroverError("--png and --heat: give one (both write a PNG)")
    if heat is not None and heat not in HEAT_KINDS:
        raise WareroverError(f"--heat: expected one of {', '.join(HEAT_KINDS)} (got {heat!r})")
    if not 1 <= workers <= 64:
        raise WareroverError(f"--workers: must be 1..64 (got {workers})")
    presets = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow",
               "slower", "veryslow")
    if preset not in presets:
        raise WareroverError(f"--preset: expected one of {', '.join(presets)} (got {preset!r})")
    _check_video_out(out, "--out", still=png is not None or heat is not None)


def _render_still(rec, out: Path, png: float | None, heat: str | None, style) -> None:
    """``render --png TICK`` or ``render --heat KIND``: one PNG."""
    from ..render import write_png

    if heat is not None:
        import cv2

        from ..render.heat import draw_heat
        from ..util.atomic import replacing

        img = draw_heat(rec, heat, style)
        with replacing(out) as tmp:
            if not cv2.imwrite(str(tmp), img):
                raise OSError(f"{out}: cannot write the image")
        return
    if not 0 <= png <= rec.end_s / rec.tick_s + 1e-9:
        raise WareroverError(f"--png: tick {png:g} is outside the recording (0..{rec.ticks})")
    write_png(rec, out, png, style)


def _render_movie(rec, out: Path, style, fps: float, speed: float | None, workers: int,
                  preset: str, show: bool) -> dict:
    """``render`` to MP4 with a progress bar giving frames per second and the time left."""
    import time

    from ..render import FrameRate, render_video

    rate = FrameRate()
    t0 = time.perf_counter()
    with _Bar(show, f"render {out.name}", 1, "frame", extra="fps") as bar:
        info = render_video(rec, out, fps=fps, speed=speed, style=style, workers=workers,
                            preset=preset, progress=(lambda k, n: bar.update(
                                k, n, extra=rate(k, n))) if show else None)
    info["render_fps"] = info["frames"] / max(time.perf_counter() - t0, 1e-9)
    return info


@app.command()
def gap(scenario: Annotated[Path, typer.Argument(
            help="Scenario YAML file (with --plan: the floor, a MovingAI .map, a layout or a "
                 "scenario YAML).")],
        mode: Annotated[str, typer.Option(
            help="open: the ideal (grid) run's plan executed unchanged on physics; closed: "
                 "two closed-loop episodes, one per executor.")] = "open",
        seed: SeedOpt = None,
        seeds: Annotated[str | None, typer.Option(
            help="Many seeds, run in parallel: 0..99, 3,5,8 or 0..4,10.")] = None,
        workers: Annotated[int | None, typer.Option(
            help="Worker processes for --seeds (default: 2, at most the CPUs).")] = None,
        out: Annotated[Path | None, typer.Option(
            help="Output folder (default: runs/NAME-seedN-gap or runs/NAME-seeds-gap); a "
                 "path ending in .json writes only the report there (one seed).")] = None,
        json_out: Annotated[bool, typer.Option("--json", help="Print JSON.")] = False,
        plan: Annotated[Path | None, typer.Option(
            "--plan", help="Execute this MAPF plan file (any format of `warerover execute`) "
                           "instead of a grid run; SCENARIO is then the floor.")] = None,
        fmt: Annotated[str | None, typer.Option(
            "--format", help="Force the plan format (as `warerover execute`).")] = None,
        yx: Annotated[bool, typer.Option(
            "--yx/--xy", help="Timed points: (row,col,t) instead of (x,y,t).")] = False,
        fleet: Annotated[Path | None, typer.Option(
            help="--plan: AGV types (YAML, as `warerover execute`).")] = None,
        delays: Annotated[str | None, typer.Option(
            help="--plan: random delays MODEL:PROB[:MIN:MAX] ticks.")] = None,
        tick_s: Annotated[float, typer.Option(help="--plan: seconds per plan timestep.")
                          ] = 1.0,
        dt_s: Annotated[float, typer.Option(help="--plan: physics step (seconds).")] = 0.02,
        agvs: Annotated[str | None, typer.Option(
            help="AGVs drawn in time_space.png, e.g. 0,3,5 (default: the three that lose "
                 "the most time).")] = None,
        pictures: Annotated[bool, typer.Option(
            "--pictures/--no-pictures", help="Write the PNG pictures (open loop).")] = True,
        quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
        timing: Annotated[str | None, typer.Option(
            help="Planned time of the plan: unit (one move per tick) or motion (the motion-"
                 "model schedule over the dependency graph; open loop only). Overrides "
                 "planner.timing.")] = None,
        video: Annotated[Path | None, typer.Option(
            help="Open loop, one seed or --plan: render the physics execution to this MP4 "
                 "(H.264, 720p): AGVs coloured by what they do, paths ahead.")] = None,
        ghost: Annotated[bool, typer.Option(
            "--ghost/--no-ghost", help="--video: also draw each AGV's planned pose (the "
                                       "plan's timing) as a ghost.")] = False,
        reorder: ReorderOpt = None,
        set_: SetOpt = None, scheduler: SchedOpt = None, planner: PlanOpt = None,
        orders: OrdersOpt = None) -> None:
    """The sim-to-real gap. Open loop (default): the plan of the ideal grid run (or --plan
    FILE) executed unchanged on physics, compared action by action, lost time split into
    causes per AGV. --mode closed: two closed-loop episodes compared. --seeds runs many
    seeds in parallel and reports their distribution."""
    from .gap import run_gap

    run_gap(scenario=scenario, mode=mode, seed=seed, seeds=seeds, workers=workers, out=out,
            json_out=json_out, plan=plan, fmt=fmt, yx=yx, fleet=fleet, delays=delays,
            tick_s=tick_s, dt_s=dt_s, agvs=agvs, pictures=pictures, quiet=quiet, video=video,
            ghost=ghost, timing=timing, reorder=reorder,
            overrides=lambda: _scenario(scenario, [*(set_ or []), *(
                [f"executor.reorder={reorder}"] if reorder else [])], seed, scheduler,
                planner, None, orders))


@app.command()
def check(scenario: Annotated[Path, typer.Argument(help="Scenario YAML file.")],
          set_: SetOpt = None) -> None:
    """Load and check a scenario (schema, layout, reachability) without running it."""
    try:
        try:
            overrides = _overrides(set_, None, None, None, None, None)
        except WareroverError as err:
            raise (err.with_file(str(scenario)) if hasattr(err, "with_file") else err) from None
        sc, world = _load(scenario, overrides)
    except WareroverError as err:
        _fail(err)
    lay = world.layout
    from ..planning.sweep_checks import check_fleet_sweeps, static_sweep_hits

    starts: dict[str, list] = {}
    for agv in world.agvs:
        starts.setdefault(agv.type_name, []).append(world.cell(agv.node))
    problems = check_fleet_sweeps(sc.fleet.types, lay.cell_m, lay,
                                  shelf_sweeps=sc.executor.shelf_sweeps) or static_sweep_hits(
        lay, sc.fleet.types, starts)
    if problems:
        _fail(ScenarioError("turning sweeps cannot be reserved: " + "; ".join(problems),
                            file=str(scenario), field="fleet.types"))
    typer.echo(f"{scenario}: ok — {lay.rows}x{lay.cols} cells, {len(lay.shelves)} shelves, "
               f"{lay.num_skus} SKUs, {len(lay.stations)} stations, {len(lay.parking)} parking "
               f"cells, {len(world.agvs)} AGVs")


@app.command()
def solve(map_file: Annotated[Path, typer.Argument(metavar="MAP.map", help="MovingAI map.")],
          scen_file: Annotated[Path, typer.Argument(metavar="SCEN.scen",
                                                    help="MovingAI scenario.")],
          agents: Annotated[int, typer.Option(help="Use the first N agents.")] = 100,
          planner: Annotated[str, typer.Option(help="lacam | pibt | astar | learned.")] = "lacam",
          time_limit: Annotated[float, typer.Option(
              help="Seconds for the whole command, counted from the process start "
                   "(--refine uses all of it).")] = 60.0,
          seed: Annotated[int, typer.Option(help="Tie-breaking seed.")] = 0,
          json_out: Annotated[bool, typer.Option("--json", help="Print JSON.")] = False,
          out: Annotated[Path | None, typer.Option(
              help="Write the plan (t:(x,y),... per line; x = column, y = row).")] = None,
          guide: Annotated[bool, typer.Option(
              "--guide/--no-guide", help="lacam / pibt: follow guide paths that spread the "
                                         "agents (lower-cost first solutions).")] = True,
          refine: Annotated[bool, typer.Option(
              "--refine", help="After the first solution, lower its sum of costs by "
                               "large-neighbourhood search until the time limit.")] = False,
          ) -> None:
    """Solve a one-shot MovingAI instance, validate the plan and print its figures."""
    code = run_solve(map_file, scen_file, agents=agents, planner=planner,
                     time_limit=time_limit, seed=seed, json_out=json_out, out=out,
                     guide=guide, refine=refine, fail=_fail)
    if code:
        raise typer.Exit(code)


def main() -> None:
    """Console-script entry point. A bad option or value (typer's usage errors) is one line
    on stderr, exit code 2, as every other bad input; Ctrl-C is one line, exit code 130."""
    # click's exceptions, wherever this typer takes click from (newer ones vendor it)
    exceptions = sys.modules[typer.BadParameter.__module__]
    click_error = exceptions.ClickException
    help_error = getattr(exceptions, "NoArgsIsHelpError", ())

    mark_entered()
    try:
        code = typer.main.get_command(app).main(prog_name="warerover", standalone_mode=False)
    except help_error as err:  # a bare `warerover`: the help, as before
        err.show()
        sys.exit(err.exit_code)
    except click_error as err:
        ctx = getattr(err, "ctx", None)
        hint = f" (see `{ctx.command_path} --help`)" if ctx is not None else ""
        err_console.print(f"[bold red]error:[/] {escape(err.format_message())}{hint}",
                          highlight=False, soft_wrap=True)
        sys.exit(err.exit_code)
    except (KeyboardInterrupt, typer.Abort):
        err_console.print("interrupted")
        sys.exit(130)
    sys.exit(code if isinstance(code, int) else 0)


@app.command()
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
            ) -> None:
    """Execute a plan made elsewhere exactly as written (no scheduler, no replanning) on
    the physics or grid executor; write metrics, events, paths and trajectories."""
    import math

    from ..execute import (
        check_reorder,
        execute_plan,
        executed_plan,
        executor_options,
        executor_spec,
        load_fleet,
        load_floor,
        parse_delays,
        repair_cycles,
        robot_model,
        validate_plan,
        write_execution,
    )
    from ..inputs import check_output_dir, check_output_file, check_seed
    from ..plans import check_format, format_plan, read_plan, write_plan

    try:
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
        show = not quiet and not json_out and err_console.is_terminal
        if show:
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

            with Progress(TextColumn("execute"), BarColumn(),
                          TextColumn("tick {task.completed:.0f} (plan {task.total:.0f})"),
                          TimeElapsedColumn(), console=err_console, transient=True) as bar:
                task = bar.add_task("execute", total=the_plan.makespan)
                result = execute_plan(the_plan, layout, types, executor=executor, seed=seed,
                                      delays=delay_spec, tick_s=tick_s, dt_s=dt_s,
                                      repairs=repairs, given=given, options=options,
                                      progress=lambda t, h: bar.update(task, completed=t))
        else:
            result = execute_plan(the_plan, layout, types, executor=executor, seed=seed,
                                  delays=delay_spec, tick_s=tick_s, dt_s=dt_s, repairs=repairs,
                                  given=given, options=options)
        files = write_execution(result, the_plan, layout, types, out_dir, tick_s)
        if export is not None:
            write_plan(executed_plan(result, layout.cols), export, export_format)
            files["export"] = export
        if video is not None:
            from ..render import Style, load_trajectory, render_video

            try:
                render_video(load_trajectory(files["trajectory"]), video,
                             style=Style(title=f"{plan.name} on {executor}"))
            except ValueError as err:
                raise WareroverError(f"--video: {err}") from None
            files["video"] = video
    except WareroverError as err:
        _fail(err)
    except OSError as err:
        _fail(WareroverError(f"{getattr(err, 'filename', '') or ''}: {err.strerror or err}"))
    m = result.metrics
    if json_out:
        typer.echo(json.dumps(m, indent=2, sort_keys=True, default=float))
        return
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
    for f in files.values():
        typer.echo(f"wrote {f}")


# `warerover sweep` and `warerover report` live in warerover_phys/sweep/cli.py.
from .sweep import register as _register_sweep  # noqa: E402

_register_sweep(app)

# `warerover serve` and `warerover export-glb` live in warerover_phys/serve/cli.py.
from .serve import register as _register_serve  # noqa: E402

_register_serve(app)

# `warerover lorr` (League of Robot Runners problems) lives in warerover_phys/lorr_cli.py.
from .lorr import register as _register_lorr  # noqa: E402

_register_lorr(app)

# `warerover check-trajectory` (space-time validation) lives in warerover_phys/spacetime/cli.py.
from .spacetime import register as _register_spacetime  # noqa: E402

_register_spacetime(app)

# `warerover study` (planners x instances x robot models) lives in warerover_phys/study/cli.py.
from ..study.cli import register as _register_study  # noqa: E402

_register_study(app)
