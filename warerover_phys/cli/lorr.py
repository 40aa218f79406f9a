"""``warerover lorr``: a League of Robot Runners problem run in the one loop (see
:mod:`.problems.robotrunners`)."""

from __future__ import annotations

import json
import resource
import sys
from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register"]


def lorr(problem: Annotated[Path, typer.Argument(
             metavar="PROBLEM.json", help="Robot Runners problem JSON (2023 or 2024+).")],
         ticks: Annotated[int, typer.Option(help="Timesteps to run.")] = 1000,
         planner: Annotated[str, typer.Option(
             help="Planner (lifelong PIBT by default; any planner of the loop).")] = "pibt",
         executor: Annotated[str, typer.Option(
             help="Executor: grid (ideal moves) | physics (bodies) | plug-in.")] = "grid",
         rotations: Annotated[bool, typer.Option(
             "--rotations/--no-rotations",
             help="The league's rotation model (forward, turn, wait) or free moves.")] = True,
         rotation_rule: Annotated[str, typer.Option(
             help="With rotations: 'actions' (PIBT ranks forward / turn / wait by the "
                  "cost-to-go of the cell and heading each leads to) or 'turn-first' (PIBT on "
                  "cells, then robots whose cell is not ahead turn instead).")] = "actions",
         seed: Annotated[int, typer.Option(help="Episode seed (PIBT's tie-breaking, delays, "
                                                "faults).")] = 0,
         out: Annotated[Path | None, typer.Option(
             help="Output folder: output.json (Robot Runners output), metrics.json, "
                  "events.jsonl, paths.json (and trajectories.npz on physics).")] = None,
         set_: Annotated[list[str] | None, typer.Option(
             "--set", help="Override any field of the problem's scenario: --set "
                           "executor.dt_s=0.05 (repeatable).")] = None,
         dist_budget_mb: Annotated[float, typer.Option(
             help="MiB the cached distance tables (one per goal cell, shared by all robots) "
                  "may hold; least recently used go first.")] = 1024.0,
         json_out: Annotated[bool, typer.Option(
             "--json", help="Print the figures as one JSON document.")] = False,
         quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")
                          ] = False,
         ) -> None:
    """Run a Robot Runners problem in the loop; write the output JSON that PlanViz replays."""
    from ..config import parse_override
    from ..errors import ScenarioError, WareroverError
    from ..outputs import write_outputs
    from ..problems.robotrunners import (
        output_json,
        problem_scenario,
        read_problem,
        write_output_json,
    )
    from ..sim import Simulation
    from ..util.console import err_console, fail_os
    from ..util.console import fail as _fail

    try:
        _check_options(ticks, rotation_rule, dist_budget_mb, seed, out)
        prob = read_problem(problem)
        overrides = [parse_override(s) for s in set_ or []]
        overrides.append(("planner.dist_budget_mb", dist_budget_mb))
        sc = problem_scenario(prob, ticks=ticks, rotations=rotations, rule=rotation_rule,
                              seed=seed, planner=planner, executor=executor,
                              overrides=overrides)
        sim = Simulation(sc)
        result = _run(sim, ticks, not quiet and not json_out and err_console.is_terminal)
        doc = output_json(result, prob, rotations=rotations, executor=sim.executor)
        figures = _figures(result, prob, doc)
        written = {}
        if out is not None:
            written = write_outputs(result, out, extra={
                "output.json": lambda p: write_output_json(doc, p)})
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        figures["peak_rss_mb"] = rss / 1024 if sys.platform != "darwin" else rss / 2**20
    except ScenarioError as err:
        _fail(err if err.file else err.with_file(str(problem)))
    except WareroverError as err:
        _fail(err)
    except OSError as err:
        fail_os(err)
    if json_out:
        typer.echo(json.dumps(figures, indent=2, default=float))
    else:
        typer.echo(f"{problem.name}: {figures['agents']} robots, {figures['ticks']} timesteps"
                   f" on {executor}{'' if rotations else ' (no rotations)'}: "
                   f"{figures['tasks_finished']} tasks finished; "
                   f"{figures['ms_per_tick_mean']:.2f} ms per timestep, "
                   f"peak memory {figures['peak_rss_mb']:.0f} MB")
    for f in written.values():
        err_console.print(f"wrote {f}", markup=False, highlight=False)


def _check_options(ticks: int, rotation_rule: str, dist_budget_mb: float, seed: int,
                   out: Path | None) -> None:
    """``lorr``'s options, before anything is read: one clear error for the first bad one."""
    from ..errors import WareroverError
    from ..inputs import check_output_dir, check_seed
    from ..problems.robotrunners import RULES

    if not 1 <= ticks <= 10_000_000:
        raise WareroverError(f"--ticks: expected 1 to 10000000 (got {ticks})")
    if rotation_rule not in RULES:
        raise WareroverError(f"--rotation-rule: expected one of {', '.join(RULES)} (got "
                             f"{rotation_rule!r})")
    if not 0 < dist_budget_mb < float("inf"):
        raise WareroverError(f"--dist-budget-mb: expected a positive number (got "
                             f"{dist_budget_mb})")
    check_seed(seed)
    if out is not None:
        check_output_dir(out)


def _run(sim, ticks: int, show: bool):
    """The simulation run to its end, with a progress bar on the error console (``show``)."""
    if not show:
        return sim.run()
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from ..util.console import err_console

    with Progress(TextColumn("lorr"), BarColumn(), TextColumn(
            "tick {task.completed:.0f} / {task.total:.0f}, {task.fields[done]} tasks"),
            TimeElapsedColumn(), console=err_console, transient=True) as bar:
        task = bar.add_task("lorr", total=ticks, done=0)
        return sim.run(lambda t, done, gen: bar.update(task, completed=t, done=done))


def _figures(result, prob, doc: dict) -> dict:
    """What ``lorr`` prints: the run's size and speed, the output's task figures and the
    loop's metrics."""
    m = result.metrics
    ticks = m["ticks"]
    wall = m["wall_s"]
    return {"problem": prob.source, "agents": prob.team_size, "ticks": ticks,
            "tasks_finished": doc["numTaskFinished"], "sum_of_cost": doc["sumOfCost"],
            "makespan": doc["makespan"], "ms_per_tick_mean": 1e3 * wall / max(1, ticks),
            "agent_counter_modelled": False if prob.agent_counter != 1 else None,
            "delays_modelled": (m.get("delay_injected_s", 0) > 0) if prob.delay_config
            else None, "metrics": m}


def register(app: typer.Typer) -> None:
    app.command(name="lorr")(lorr)
