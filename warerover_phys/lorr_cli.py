"""``warerover lorr``: a League of Robot Runners problem, run lifelong (see :mod:`.lorr`)."""

from __future__ import annotations

import json
import resource
import sys
from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register"]

PLANNERS = ("pibt",)
"""Planners ``lorr`` runs today (lifelong, one step per timestep)."""


def lorr(problem: Annotated[Path, typer.Argument(
             metavar="PROBLEM.json", help="Robot Runners problem JSON (2023 or 2024+).")],
         ticks: Annotated[int, typer.Option(help="Timesteps to run.")] = 1000,
         planner: Annotated[str, typer.Option(help="Planner: pibt.")] = "pibt",
         executor: Annotated[str, typer.Option(help="Executor: grid.")] = "grid",
         rotations: Annotated[bool, typer.Option(
             "--rotations/--no-rotations",
             help="The league's rotation model (forward, turn, wait) or free moves.")] = True,
         rotation_rule: Annotated[str, typer.Option(
             help="With rotations: 'actions' (PIBT ranks forward / turn / wait by the "
                  "cost-to-go of the cell and heading each leads to) or 'turn-first' (PIBT on "
                  "cells, then robots whose cell is not ahead turn instead).")] = "actions",
         seed: Annotated[int, typer.Option(help="Seed of PIBT's tie-breaking.")] = 0,
         out: Annotated[Path | None, typer.Option(
             help="Output folder: output.json (Robot Runners output) and metrics.json; "
                  "the actions are streamed to disk while the run goes.")] = None,
         dist_budget_mb: Annotated[float, typer.Option(
             help="MiB the cached distance tables (one per goal cell, shared by all robots) "
                  "may hold; least recently used go first.")] = 1024.0,
         prefetch_tables: Annotated[bool, typer.Option(
             "--prefetch-tables",
             help="Compute the tables of the tasks' errand cells before the first timestep, "
                  "until the budget is full (set-up time instead of timestep time).")
                           ] = False,
         json_out: Annotated[bool, typer.Option(
             "--json", help="Print the figures as JSON.")] = False,
         quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")
                          ] = False,
         ) -> None:
    """Run a Robot Runners problem lifelong; write the output JSON that PlanViz replays."""
    from .console import err_console, fail_os
    from .console import fail as _fail
    from .errors import WareroverError
    from .inputs import check_output_dir, check_seed
    from .lorr import RULES, read_problem, run_lifelong, write_output_json

    try:
        if not 1 <= ticks <= 10_000_000:
            raise WareroverError(f"--ticks: expected 1 to 10000000 (got {ticks})")
        check_seed(seed)
        if planner not in PLANNERS:
            raise WareroverError(f"--planner: lorr runs {', '.join(PLANNERS)} (got "
                                 f"{planner!r}); the other planners plan whole paths, not "
                                 "one lifelong step")
        if executor != "grid":
            raise WareroverError(f"--executor: lorr runs on the grid executor only (got "
                                 f"{executor!r}); to see a run on bodies, execute its output "
                                 "with `warerover execute MAP --plan output.json`")
        if rotation_rule not in RULES:
            raise WareroverError(f"--rotation-rule: expected one of {', '.join(RULES)} (got "
                                 f"{rotation_rule!r})")
        if not dist_budget_mb > 0:
            raise WareroverError(f"--dist-budget-mb: expected a positive number (got "
                                 f"{dist_budget_mb})")
        if out is not None:
            check_output_dir(out)
        prob = read_problem(problem)
        trace = None
        if out is not None:
            import tempfile

            out.absolute().parent.mkdir(parents=True, exist_ok=True)
            trace = tempfile.TemporaryDirectory(prefix="lorr-trace-",
                                                dir=out.absolute().parent)
        kw = {"dist_budget_mb": dist_budget_mb, "prefetch": prefetch_tables,
              "trace_dir": None if trace is None else trace.name}
        show = not quiet and not json_out and err_console.is_terminal
        if show:
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

            with Progress(TextColumn("lorr"), BarColumn(), TextColumn("tick {task.completed:.0f}"
                          " / {task.total:.0f}"), TimeElapsedColumn(), console=err_console,
                          transient=True) as bar:
                task = bar.add_task("lorr", total=ticks)
                result = run_lifelong(prob, ticks, rotations=rotations, seed=seed,
                                      rule=rotation_rule, **kw,
                                      progress=lambda t, n: bar.update(task, completed=t))
        else:
            result = run_lifelong(prob, ticks, rotations=rotations, seed=seed,
                                  rule=rotation_rule, **kw)
        figures = result.summary()
        figures["planner"] = planner
        written = {}

        def finish_figures() -> dict:
            rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
            figures["peak_rss_mb"] = rss / 1024 if sys.platform != "darwin" else rss / 2**20
            return figures

        if out is not None and trace is not None:
            import time

            from .atomic import write_set

            t0 = time.perf_counter()

            def metrics(p: Path) -> None:  # written after output.json: its time and memory
                figures["output_s"] = time.perf_counter() - t0
                p.write_text(json.dumps(finish_figures(), indent=2) + "\n")

            try:
                written = write_set(out, {
                    "output.json": lambda p: write_output_json(result, p),
                    "metrics.json": metrics,
                }, meta={"problem": str(problem)})
            finally:
                trace.cleanup()
        else:
            finish_figures()
    except WareroverError as err:
        _fail(err)
    except OSError as err:
        fail_os(err)
    if json_out:
        typer.echo(json.dumps(figures, indent=2, default=float))
    else:
        typer.echo(f"{problem.name}: {figures['agents']} robots, {figures['ticks']} timesteps"
                   f"{'' if rotations else ' (no rotations)'}: {figures['tasks_finished']} "
                   f"tasks finished; {figures['ms_per_tick_mean']:.2f} ms per timestep (p99 "
                   f"{figures['ms_per_tick_p99']:.2f}), setup {figures['setup_s']:.2f} s, "
                   f"peak memory {figures['peak_rss_mb']:.0f} MB")
    for f in written.values():  # with --json, stdout holds the JSON document alone
        typer.echo(f"wrote {f}", err=json_out)


def register(app: typer.Typer) -> None:
    app.command(name="lorr")(lorr)
