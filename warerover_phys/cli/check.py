"""The ``warerover check`` command: load and check a scenario without running it."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import ScenarioError, WareroverError
from ..util.console import fail as _fail
from .options import SetOpt, _load, _overrides


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
