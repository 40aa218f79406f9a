"""What the ``warerover`` commands share: option types, loading a scenario with overrides,
the progress bar, video checks and rendering."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from ..errors import WareroverError
from ..util.console import err_console
from ..util.media import check_media_path

SetOpt = Annotated[list[str] | None, typer.Option(
    "--set", help="Override any scenario field: --set orders.pattern=burst (repeatable).")]
SeedOpt = Annotated[int | None, typer.Option(help="Episode seed (overrides the file's).")]
ReorderOpt = Annotated[str | None, typer.Option(
    help="Physics: reorder the dependency graph under delays: none | greedy | milp "
         "(executor.reorder).")]
MaxTicksOpt = Annotated[int | None, typer.Option(
    "--max-ticks", help="Stop the execution after this many ticks (default: 10x the plan's "
                        "makespan + 100 for execute, + 200 for gap --plan).")]
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


def check_max_ticks(max_ticks: int | None) -> None:
    """``--max-ticks``: a whole number of ticks from 1 to ``MAX_TICKS``, or not given."""
    from ..config.types import MAX_TICKS

    if max_ticks is not None and not 1 <= max_ticks <= MAX_TICKS:
        raise WareroverError(f"--max-ticks must be from 1 to {MAX_TICKS:,} (got {max_ticks})")


def warn_incomplete(completed: bool, ticks: int, limit: str) -> None:
    """On stderr: an open-loop run stopped at its tick limit (``limit``, in words)
    before every AGV finished its plan; its figures for those AGVs are missing."""
    if not completed:
        err_console.print(f"warning: the execution stopped at its tick limit ({ticks} ticks: "
                          f"{limit}) before every AGV finished its plan; figures that need "
                          "an AGV's finish are missing (NaN or null) for those that did not "
                          "(--max-ticks sets the limit)", highlight=False, markup=False)


def _show_progress(quiet: bool, json_out: bool = False) -> bool:
    return not quiet and not json_out and err_console.is_terminal


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
