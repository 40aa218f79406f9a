"""The ``warerover render`` command: a recorded trajectory to an MP4 or a still PNG."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from ..errors import WareroverError
from ..util.console import err_console, fail_os
from ..util.console import fail as _fail
from .options import FpsOpt, SizeOpt, SpeedOpt, _Bar, _check_video_out, _show_progress, _video_style


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
        fail_os(err)
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
