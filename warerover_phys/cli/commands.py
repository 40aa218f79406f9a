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

import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from ..util.console import err_console
from ..util.console import fail as _fail
from .check import (  # noqa: F401
    check,
)
from .execute import (  # noqa: F401
    execute,
)
from .options import (  # noqa: F401
    ExecOpt,
    FpsOpt,
    MaxTicksOpt,
    OrdersOpt,
    PlanOpt,
    ReorderOpt,
    SchedOpt,
    SeedOpt,
    SetOpt,
    SizeOpt,
    SpeedOpt,
    _Bar,
    _check_frames,
    _check_video_out,
    _load,
    _overrides,
    _run_video,
    _scenario,
    _show_progress,
    _video_style,
)
from .render import (  # noqa: F401
    _render_checks,
    _render_movie,
    _render_still,
    render,
)
from .run import (  # noqa: F401
    run,
)
from .solve import mark_entered, run_solve  # `solve`'s body and its fast path

__all__ = ["app", "main"]

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="warerover-phys: closed-loop robotic warehouse simulator.")


# The commands, in the order `warerover --help` lists them; each lives in its own module.
app.command()(run)
app.command()(render)


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
        max_ticks: MaxTicksOpt = None,
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
            ghost=ghost, timing=timing, reorder=reorder, max_ticks=max_ticks,
            overrides=lambda: _scenario(scenario, [*(set_ or []), *(
                [f"executor.reorder={reorder}"] if reorder else [])], seed, scheduler,
                planner, None, orders))


app.command()(check)


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


app.command()(execute)

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
