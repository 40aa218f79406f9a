"""``warerover sweep`` and ``warerover report``, registered on the main typer app by
:func:`register` (called at the end of ``warerover_phys/cli.py``)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated, Any

import typer

__all__ = ["register", "sweep", "report"]


class _Progress:
    """A rich progress bar with ETA on a terminal; a line every 5% otherwise."""

    def __init__(self, console: Any, quiet: bool, name: str = "sweep",
                 noun: str = "episodes") -> None:
        self.console = console
        self.quiet = quiet
        self.name, self.noun = name, noun
        self.bar: Any = None
        self.task: Any = None
        self.failed = 0
        self.done = 0
        self.total = 0
        self.t0 = time.monotonic()
        self.every = 1

    def start(self, summary: Any, to_run: int, where: str) -> None:
        self.total = to_run
        self.every = max(1, to_run // 20)
        self.console.print(f"{self.name}: {summary.total} {self.noun}, {summary.done_before} already in "
                           f"{summary.results}, {to_run} to run on {where}", markup=False, highlight=False, soft_wrap=True)
        if self.quiet or not to_run:
            return
        if self.console.is_terminal:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TaskProgressColumn,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self.bar = Progress(TextColumn(self.noun), BarColumn(), MofNCompleteColumn(),
                                TaskProgressColumn(), TimeElapsedColumn(), TextColumn("ETA"),
                                TimeRemainingColumn(), TextColumn("failed {task.fields[failed]}"),
                                console=self.console, transient=False)
            self.task = self.bar.add_task("sweep", total=to_run, failed=0)
            self.bar.start()

    def row(self, row: dict[str, Any]) -> None:
        self.done += 1
        self.failed += row["status"] != "ok"
        if self.bar is not None:
            self.bar.update(self.task, advance=1, failed=self.failed)
        elif not self.quiet and (self.done % self.every == 0 or self.done == self.total):
            elapsed = time.monotonic() - self.t0
            eta = elapsed / self.done * (self.total - self.done)
            self.console.print(f"[{self.done}/{self.total}] {self.done / self.total:.0%}  "
                               f"elapsed {elapsed:.0f} s  ETA {eta:.0f} s  failed {self.failed}",
                               highlight=False, soft_wrap=True)

    def stop(self) -> None:
        if self.bar is not None:
            self.bar.stop()
            self.bar = None


def sweep(sweep_file: Annotated[Path, typer.Argument(metavar="SWEEP.yaml",
                                                     help="Sweep file (YAML).")],
          out: Annotated[Path, typer.Option(help="Results folder (results.jsonl, sweep.json); "
                                                 "running again resumes.")],
          workers: Annotated[int | None, typer.Option(
              help="Local worker processes (default: CPU count).")] = None,
          ray: Annotated[str | None, typer.Option(
              "--ray", metavar="ADDRESS|auto|local",
              help="Run on Ray: a cluster address, auto (the running cluster) or local "
                   "(start one here with --workers CPUs). Needs warerover-phys[ray].")] = None,
          retry_failed: Annotated[bool, typer.Option(
              "--retry-failed", help="Run the episodes recorded as failed again.")] = False,
          repetitions: Annotated[int | None, typer.Option(
              help="Run only the first N seeds (a quicker subset; keys stay the same).")] = None,
          only: Annotated[list[str] | None, typer.Option(
              "--only", metavar="PATH=VALUE",
              help="Run only this grid value, e.g. --only orders.pattern=oneshot, or "
                   "--only scenario=Ho (repeatable).")] = None,
          quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress.")] = False,
          ) -> None:
    """Run every episode of a sweep once, in parallel; resumable (results in OUT/results.jsonl)."""
    import os

    from ..config import parse_override
    from ..errors import WareroverError
    from ..inputs import check_output_dir
    from ..sweep.runner import check_ray_address, run_sweep
    from ..sweep.spec import load_sweep, narrow
    from ..util.console import err_console, fail_os
    from ..util.console import fail as _fail

    progress = _Progress(err_console, quiet)
    try:
        if workers is not None and workers < 1:
            raise WareroverError(f"--workers: must be at least 1 (got {workers})")
        check_output_dir(out)
        if ray is not None:
            check_ray_address(ray)
        spec = load_sweep(sweep_file)
        if repetitions is not None or only:
            pairs = []
            for text in only or []:
                path, value = parse_override(text, option="--only")
                pairs.append((path, value))
            spec = narrow(spec, repetitions=repetitions, only=pairs)
        n = workers or os.cpu_count() or 1
        where = f"Ray ({ray})" if ray is not None else f"{n} local worker process(es)"
        summary = run_sweep(spec, out, workers=n, ray_address=ray, retry_failed=retry_failed,
                            on_start=lambda s, k: progress.start(s, k, where),
                            on_row=progress.row)
    except KeyboardInterrupt:
        progress.stop()
        err_console.print(f"interrupted: {progress.done} episode(s) of this run recorded in "
                          f"{out}; run the same command again to resume", markup=False, highlight=False, soft_wrap=True)
        raise typer.Exit(130) from None
    except WareroverError as err:
        progress.stop()
        _fail(err)
    except OSError as err:
        progress.stop()
        fail_os(err)
    progress.stop()
    failed = (f", {summary.failed} failed in this run" if summary.failed else "") + \
        (f" ({summary.failed_total} failed rows in all; --retry-failed reruns them)"
         if summary.failed_total else "")
    typer.echo(f"done: {summary.total} episodes in {summary.results} — {summary.ran} run now "
               f"in {summary.wall_s:.1f} s{failed}. Next: warerover report {out}")


def report(out_dir: Annotated[Path, typer.Argument(metavar="DIR",
                                                   help="A sweep's --out folder.")],
           ) -> None:
    """Aggregate a sweep: SR, CT, TP with 95% CIs; writes report.md, report.csv, PNG tables.

    Rows are environment x method (scheduler + planner), pooled over order patterns and per
    pattern."""
    from ..errors import WareroverError
    from ..sweep.report import write_report
    from ..util.console import err_console, fail_os
    from ..util.console import fail as _fail

    try:
        result = write_report(out_dir)
    except WareroverError as err:
        _fail(err)
    except OSError as err:
        fail_os(err)
    typer.echo(result["markdown"])
    for note in result["notes"]:
        err_console.print(f"note: {note}", markup=False, highlight=False, soft_wrap=True)
    typer.echo("wrote " + ", ".join(str(p) for p in result["files"].values()))


def register(app: typer.Typer) -> None:
    """Add ``sweep`` and ``report`` to the ``warerover`` app."""
    app.command("sweep")(sweep)
    app.command("report")(report)
