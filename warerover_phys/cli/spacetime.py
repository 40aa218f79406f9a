"""``warerover check-trajectory RUN_DIR``: the space-time check of an executed run."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register"]


def check_trajectory(
        run: Annotated[Path, typer.Argument(
            metavar="RUN_DIR", help="A run folder holding trajectories.npz, or the file.")],
        tolerance_m: Annotated[float, typer.Option(
            help="Outlines may touch or overlap by this much (m).")] = 1e-3,
        margin_m: Annotated[float, typer.Option(
            help="Grow every outline by this much (m), e.g. for motion between samples.")
                            ] = 0.0,
        max_turn_rad: Annotated[float, typer.Option(
            help="Turn covered by one swept volume (rad); longer turns are split.")
                                ] = math.pi / 16,
        shelves: Annotated[bool, typer.Option(
            "--shelves/--no-shelves", help="Include carried shelves (shelf_m).")] = True,
        max_conflicts: Annotated[int, typer.Option(help="Conflicts to report at most.")] = 20,
        json_out: Annotated[bool, typer.Option("--json", help="Print JSON.")] = False,
        ) -> None:
    """Prove that no two AGVs' bodies met between recorded samples: every move between two
    samples becomes its swept volume in (x, y, t), and fcl finds any two that meet. Exit 0:
    none; 1: conflicts (listed); 2: bad input."""
    from ..errors import WareroverError
    from ..spacetime import load_trajectory_file, validate_spacetime
    from ..util.console import fail, fail_os

    try:
        for name, v in (("--tolerance-m", tolerance_m), ("--margin-m", margin_m)):
            if not (math.isfinite(v) and v >= 0):
                raise WareroverError(f"{name}: must be a finite number >= 0 (got {v})")
        if not (math.isfinite(max_turn_rad) and 0 < max_turn_rad < math.pi):
            raise WareroverError(f"--max-turn-rad: must be in (0, pi) (got {max_turn_rad})")
        if max_conflicts < 1:
            raise WareroverError(f"--max-conflicts: must be at least 1 (got {max_conflicts})")
        plan = load_trajectory_file(run, shelves=shelves)
        res = validate_spacetime(plan, tolerance_m=tolerance_m, margin_m=margin_m,
                                 max_turn_rad=max_turn_rad, shelves=shelves,
                                 max_conflicts=max_conflicts)
    except WareroverError as err:
        fail(err)
    except OSError as err:
        fail_os(err)
    if json_out:
        typer.echo(json.dumps(res.summary(), indent=2))
    else:
        tm = res.timings_s
        typer.echo(f"{plan.source}: {res.agents} AGVs, {res.samples} samples, {res.volumes} "
                   f"swept volumes; {res.broad_pairs} box pairs, {res.fcl_pairs} to fcl, "
                   f"{res.colliding_pairs} colliding; {tm['total']:.3f} s")
        typer.echo(f"tolerance {tolerance_m:g} m, margin {margin_m:g} m, turns bounded within "
                   f"{res.max_rotation_bound_m * 1000:.2f} mm")
        for c in res.conflicts:
            typer.echo(str(c))
        more = " (more not listed)" if res.truncated else ""
        typer.echo("ok: no two bodies met" if res.ok else
                   f"{len(res.conflicts)} conflict(s){more}")
    if not res.ok:
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    app.command("check-trajectory")(check_trajectory)
