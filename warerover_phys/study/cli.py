"""``warerover study SPEC.yaml --out DIR`` and ``warerover study report DIR``, registered on
the main typer app by :func:`register` (called at the end of ``warerover_phys/cli.py``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register", "study"]


def _solvers(texts: list[str] | None) -> dict[str, str]:
    from ..errors import WareroverError

    out = {}
    for text in texts or []:
        name, eq, path = text.partition("=")
        if not eq or not name.strip() or not path.strip():
            raise WareroverError(f"--solver: expected NAME=PATH, e.g. lacam3=/opt/lacam3/main "
                                 f"(got {text!r})")
        out[name.strip()] = path.strip()
    return out


def study(target: Annotated[str, typer.Argument(
              metavar="SPEC.yaml|report", help="A study file to run, or `report`.")],
          folder: Annotated[Path | None, typer.Argument(
              metavar="[DIR]", help="With `report`: the study's --out folder.")] = None,
          out: Annotated[Path | None, typer.Option(
              help="Results folder (results.jsonl, results.parquet, results.csv, plans/); "
                   "running again resumes.")] = None,
          workers: Annotated[int | None, typer.Option(
              help="Local worker processes (default: CPU count).")] = None,
          ray: Annotated[str | None, typer.Option(
              "--ray", metavar="ADDRESS|auto|local",
              help="Run on Ray (needs the ray extra: pip install 'warerover-phys\\[ray]').")] = None,
          solver: Annotated[list[str] | None, typer.Option(
              "--solver", metavar="NAME=PATH",
              help="The binary of a solver the study's commands name, e.g. "
                   "lacam3=/work/lacam3-build/main (wins over the study file and its env "
                   "variable; repeatable).")] = None,
          max_minutes: Annotated[float | None, typer.Option(
              "--max-minutes", metavar="M",
              help="Stop after M minutes of wall clock: no plan or cell starts later, a cell "
                   "cut short gets no row; running again finishes the rest.")] = None,
          retry_failed: Annotated[bool, typer.Option(
              "--retry-failed", help="Run the cells recorded as failed again (their plans "
                                     "are solved again).")] = False,
          pictures: Annotated[bool, typer.Option(
              "--pictures/--no-pictures", help="report: draw the PNG pictures.")] = True,
          json_out: Annotated[bool, typer.Option(
              "--json", help="Print one JSON document (the run's summary, or the report's "
                             "tables) and nothing else on stdout.")] = False,
          quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress.")] = False,
          ) -> None:
    """Planners x MAPF instances x robot models, each plan executed on physics: one row per
    cell in OUT/results.parquet and OUT/results.csv (resumable). `warerover study report
    DIR` writes DIR/report.md with tables, rank correlations and pictures."""
    from ..errors import WareroverError
    from ..util.console import fail as _fail

    try:
        if target == "report":
            if folder is None:
                raise WareroverError("study report: give the study's folder: warerover study "
                                     "report DIR")
            _report(folder, pictures, json_out)
            return
        if folder is not None:
            raise WareroverError(f"study: unexpected argument {str(folder)!r} (the results "
                                 "folder is --out DIR)")
        if out is None:
            raise WareroverError("study: --out DIR is required (where the results go)")
        if workers is not None and workers < 1:
            raise WareroverError(f"--workers: must be at least 1 (got {workers})")
        if max_minutes is not None and not max_minutes > 0:
            raise WareroverError(f"--max-minutes: must be above 0 (got {max_minutes})")
        _run(Path(target), out, workers, ray, _solvers(solver), retry_failed, json_out, quiet,
             None if max_minutes is None else 60 * max_minutes)
    except WareroverError as err:
        _fail(err)
    except OSError as err:
        _fail(WareroverError(f"{getattr(err, 'filename', '') or ''}: {err.strerror or err}"))


def _run(spec_file: Path, out: Path, workers: int | None, ray: str | None,
         solvers: dict[str, str], retry_failed: bool, json_out: bool, quiet: bool,
         max_wall_s: float | None = None) -> None:
    import os

    from ..cli.sweep import _Progress
    from ..util.console import err_console
    from .runner import run_study
    from .spec import load_study

    progress = _Progress(err_console, quiet or json_out, name="study", noun="cells")
    spec = load_study(spec_file)
    n = workers or os.cpu_count() or 1
    where = f"Ray ({ray})" if ray is not None else f"{n} local worker process(es)"
    try:
        summary = run_study(spec, out, workers=n, ray_address=ray, retry_failed=retry_failed,
                            solvers=solvers, on_start=lambda s, k: progress.start(s, k, where),
                            on_row=progress.row, max_wall_s=max_wall_s)
    except KeyboardInterrupt:
        progress.stop()
        err_console.print(f"interrupted: {progress.done} cell(s) of this run recorded in {out}; "
                          "run the same command again to resume", markup=False,
                          highlight=False, soft_wrap=True)
        raise typer.Exit(130) from None
    finally:
        progress.stop()
    if json_out:
        typer.echo(json.dumps({"cells": summary.total, "done_before": summary.done_before,
                               "ran": summary.ran, "failed": summary.failed,
                               "failed_total": summary.failed_total, "left": summary.left,
                               "wall_s": round(summary.wall_s, 3),
                               "results": str(summary.out_dir / "results.parquet")}))
        return
    failed = (f", {summary.failed} without a result in this run" if summary.failed else "")
    if summary.left:
        typer.echo(f"stopped at --max-minutes: {summary.ran} cells run in {summary.wall_s:.1f} s"
                   f"{failed}; {summary.left} of {summary.total} cells left without a row in "
                   f"{summary.out_dir}: run the same command again to finish them")
        return
    typer.echo(f"done: {summary.total} cells in {summary.out_dir} — {summary.ran} run now in "
               f"{summary.wall_s:.1f} s{failed}. Next: warerover study report {out}")


def _report(folder: Path, pictures: bool, json_out: bool) -> None:
    from ..util.console import err_console
    from .report import write_study_report

    result = write_study_report(folder, pictures=pictures)
    if json_out:
        typer.echo(_json(result))
        return
    typer.echo(result["markdown"])
    for note in result["notes"]:
        err_console.print(f"note: {note}", markup=False, highlight=False, soft_wrap=True)
    typer.echo("wrote " + ", ".join(str(p) for p in result["files"].values()))


def _json(result: dict) -> str:
    import math

    def clean(v):
        if isinstance(v, float) and not math.isfinite(v):
            return None
        if isinstance(v, dict):
            return {str(k): clean(x) for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [clean(x) for x in v]
        if isinstance(v, Path):
            return str(v)
        return v

    return json.dumps(clean({"files": result["files"], "notes": result["notes"],
                             "tables": result["tables"]}))


def register(app: typer.Typer) -> None:
    """Add ``study`` to the ``warerover`` app."""
    app.command("study")(study)
