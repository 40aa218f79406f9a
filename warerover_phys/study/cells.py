"""The cells of a study and the tasks that run them.

A one-shot *cell* is (instance, agent count, scen, planner, robot, mismatch, delays, seed).
Cells that can share a plan form one :class:`PlanTask`: the plan depends on the instance,
the planner and the seed, and for rotation-aware planners on the turn ticks of the
planner's robot model, never on the executing side (true robot, mismatch, delays). A task
solves (or reads) its plan once, validates it, repairs its rotations, then executes it once
per cell; its plan is kept under ``DIR/plans/`` so that a resumed study does not solve it
again. A lifelong cell is one closed-loop episode (:class:`LifelongTask`).

Keys are compact JSON of the cell's labels, each label with a hash of what it stands for
(:func:`~.spec.content_hash`).
"""

from __future__ import annotations

import itertools
import json
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import AgvTypeSpec, DelaySpec
from .spec import Execution, Mismatch, PlannerEntry, StudyError, StudySpec, content_hash

__all__ = ["Cell", "PlanTask", "LifelongTask", "expand", "tasks_for", "lifelong_tasks",
           "check_lifelong", "lifelong_scenario", "resolve_solvers", "cell_id"]


@dataclass(frozen=True)
class Cell:
    """One executed row of a one-shot instance."""

    key: str
    instance: str
    n: int
    scen: str
    """The scenario file's stem."""
    scen_index: int
    """1-based position in the instance's ``scens``."""
    planner: str
    robot: str
    mismatch: str
    delays: str
    seed: int


@dataclass(frozen=True)
class PlanTask:
    """One plan and the cells that execute it (picklable; everything a worker needs)."""

    plan_id: str
    map_path: str
    scen_path: str
    n: int
    seed: int
    planner: str
    """The first planner label of the task (the plan's name)."""
    entry: PlannerEntry
    """How the plan is made (the planners of the task differ at most in ``timing``)."""
    entries: dict[str, PlannerEntry]
    """Every planner label of the task's cells."""
    planner_model: AgvTypeSpec
    """The robot model the planner assumes (rotation-aware planners: its turn ticks)."""
    cells: tuple[Cell, ...]
    robots: dict[str, AgvTypeSpec]
    mismatch: dict[str, Mismatch]
    delays: dict[str, DelaySpec]
    execution: Execution
    out_dir: str
    solvers: dict[str, str] = field(default_factory=dict)
    """Solver name -> binary path (resolved by :func:`resolve_solvers`)."""
    deadline: float | None = None
    """The run's deadline (``time.time()``): past it the task starts no plan and no cell,
    and a cell it cuts short gets no row (a resumed study runs them)."""

    @property
    def keys(self) -> list[str]:
        return [c.key for c in self.cells]


@dataclass(frozen=True)
class LifelongTask:
    """One closed-loop episode: a scenario file with overrides and a seed."""

    key: str
    scenario: str
    file: str
    planner: str
    overrides: tuple[tuple[str, Any], ...]
    variant: tuple[tuple[str, Any], ...]
    seed: int
    out_dir: str

    @property
    def keys(self) -> list[str]:
        return [self.key]


GUARDS = ("cell_timeout_s", "plan_grace_s")
"""Execution settings that only guard the wall clock: a cell's key leaves them out."""


def _key(*parts: Any) -> str:
    return json.dumps(list(parts), sort_keys=True, separators=(",", ":"), default=str)


def cell_id(key: str) -> str:
    """A file-name-safe id of a key (its content hash, 12 hex digits)."""
    import hashlib

    return hashlib.sha256(key.encode()).hexdigest()[:12]


def _labelled(label: str, value: Any) -> str:
    return f"{label}#{content_hash(value)}"


def expand(spec: StudySpec) -> list[Cell]:
    """Every one-shot cell of the study, in file order (seed outermost), less the
    excluded ones."""
    out = []
    ex = spec.execution.model_dump(mode="json", exclude=set(GUARDS))
    for seed in spec.seeds:
        for inst in spec.instances:
            for n, (j, scen) in itertools.product(inst.agents, enumerate(inst.scens, 1)):
                stem = Path(scen).stem
                for planner, robot, mismatch, delays in itertools.product(
                        spec.planners, spec.robots, spec.mismatch, spec.delays):
                    combo = {"instance": inst.name, "agents": n, "scen": j, "planners": planner,
                             "robots": robot, "mismatch": mismatch, "delays": delays,
                             "seed": seed}
                    if spec.excluded(combo):
                        continue
                    key = _key("oneshot", _labelled(inst.name, inst.map), n, stem,
                               _labelled(planner, spec.planners[planner].model_dump(mode="json")),
                               _labelled(robot, spec.robots[robot].model_dump(mode="json")),
                               _labelled(mismatch, spec.mismatch[mismatch].model_dump()),
                               _labelled(delays, spec.delays[delays].model_dump(mode="json")),
                               seed, content_hash(ex))
                    out.append(Cell(key, inst.name, n, stem, j, planner, robot, mismatch,
                                    delays, seed))
    return out


def _plan_key(spec: StudySpec, inst_map: str, scen: str, cell: Cell) -> tuple:
    """What a cell's plan depends on: the instance, the seed, how the plan is made (the
    planner's settings but ``timing``, which only reads the plan) and, for rotation-aware
    planners, the turn ticks of the planner's robot model."""
    entry = spec.planners[cell.planner]
    model: Any = None
    if entry.rotations:
        from ..planning.rotation import agent_turn_ticks

        model = agent_turn_ticks(spec.robots[cell.robot], spec.execution.tick_s)
    how = entry.model_dump(mode="json", exclude={"timing"})
    return (inst_map, scen, cell.n, cell.seed, json.dumps(how, sort_keys=True),
            json.dumps(model))


def tasks_for(spec: StudySpec, cells: list[Cell], out_dir: str | Path,
              solvers: dict[str, str]) -> list[PlanTask]:
    """Group ``cells`` into plan tasks, in the order of their first cell."""
    insts = {i.name: i for i in spec.instances}
    groups: dict[tuple, list[Cell]] = {}
    for c in cells:
        inst = insts[c.instance]
        scen = str(spec.path(inst.scens[c.scen_index - 1]).resolve())
        groups.setdefault(_plan_key(spec, str(spec.path(inst.map).resolve()), scen, c),
                          []).append(c)
    tasks = []
    for key, group in groups.items():
        map_path, scen_path, n, seed = key[:4]
        planner = group[0].planner
        entries = {c.planner: spec.planners[c.planner] for c in group}
        entry = entries[planner]
        if entry.plans is not None:  # the workers do not know the study file's folder
            entry = entry.model_copy(update={"plans": str(spec.path(entry.plans).resolve())})
        pid = content_hash(list(key))
        tasks.append(PlanTask(
            plan_id=f"{Path(scen_path).stem}-{n}-{planner}-s{seed}-{pid}".replace("/", "_"),
            map_path=map_path, scen_path=scen_path, n=n, seed=seed, planner=planner,
            entry=entry, entries=entries, planner_model=spec.robots[group[0].robot],
            cells=tuple(group),
            robots=dict(spec.robots), mismatch=dict(spec.mismatch), delays=dict(spec.delays),
            execution=spec.execution, out_dir=str(out_dir),
            solvers={k: v for k, v in solvers.items() if k in entry.solver_names()}))
    return tasks


def lifelong_tasks(spec: StudySpec, out_dir: str | Path) -> list[LifelongTask]:
    """Every lifelong cell of the study (seed outermost)."""
    life = spec.lifelong
    if life is None:
        return []
    keys = list(life.grid)
    combos = [dict(zip(keys, v, strict=True))
              for v in itertools.product(*(life.grid[k] for k in keys))]
    out = []
    for seed in life.seeds:
        for label, file in life.scenarios.items():
            path = str(spec.path(file).resolve())
            for planner, sets in life.planners.items():
                for combo in combos:
                    merged = {**life.set, **sets, **combo}
                    overrides = tuple(sorted(merged.items()))
                    key = _key("lifelong", _labelled(label, file),
                               _labelled(planner, sets), sorted(combo.items()),
                               content_hash(sorted(life.set.items())), seed)
                    out.append(LifelongTask(key, label, path, planner, overrides,
                                            tuple(combo.items()), seed, str(out_dir)))
    return out


def lifelong_scenario(file: str, overrides: tuple[tuple[str, Any], ...] | list, seed: int
                      ) -> Any:
    """The scenario of a lifelong cell: a scenario YAML, or a League of Robot Runners
    problem (``*.json``: its map, agents and task stream, lifelong PIBT on the league's
    rotation model, 1,000 timesteps unless ``max_ticks`` is overridden), with
    ``overrides`` (``--set`` pairs: ``planner.invoke``, ``planner.latency``, ...)."""
    if Path(file).suffix.lower() == ".json":
        from ..problems.robotrunners import problem_scenario, read_problem

        return problem_scenario(read_problem(file), ticks=1000, seed=seed,
                                overrides=list(overrides))
    from ..config import load_scenario

    return load_scenario(file, list(overrides))


def check_lifelong(spec: StudySpec, tasks: list[LifelongTask]) -> None:
    """Load every distinct (scenario, overrides) of ``tasks`` once: a bad override path or
    value is a :class:`StudyError` naming the study file before anything runs."""
    from ..errors import ScenarioError

    seen: set[str] = set()
    for t in tasks:
        key = json.dumps([t.file, t.overrides], sort_keys=True, default=str)
        if key in seen:
            continue
        seen.add(key)
        try:
            lifelong_scenario(t.file, t.overrides, t.seed)
        except ScenarioError as err:
            raise StudyError(f"lifelong cell {t.scenario} x {t.planner}: {err}",
                             file=spec.source, field="lifelong") from None


def resolve_solvers(spec: StudySpec, given: dict[str, str] | None = None) -> dict[str, str]:
    """The binary of every solver a planner's command names: ``given`` (``--solver
    NAME=PATH``), else the solver's ``env`` variable, else its ``path``. Raises
    :class:`StudyError` naming the solver, where it was looked for and how to build it."""
    given = dict(given or {})
    unknown = sorted(set(given) - set(spec.solvers))
    if unknown:
        raise StudyError(f"--solver {unknown[0]}: the study names no such solver (it has "
                         f"{sorted(spec.solvers) or 'none'})", file=spec.source)
    used = {name for p in spec.planners.values() for name in p.solver_names()}
    out = {}
    for name in sorted(used):
        entry = spec.solvers[name]
        tried = []
        if name in given:
            cand, where = given[name], f"--solver {name}={given[name]}"
        elif entry.env and os.environ.get(entry.env):
            cand, where = os.environ[entry.env], f"${entry.env}={os.environ[entry.env]}"
        elif entry.path:
            cand, where = str(spec.path(entry.path)), f"solvers.{name}.path"
        else:
            cand, where = None, ""
        if cand is not None:
            found = shutil.which(cand) if os.sep not in cand else cand
            if found and os.path.isfile(found) and os.access(found, os.X_OK):
                out[name] = str(Path(found).resolve())
                continue
            tried.append(f"{where} is not an executable file")
        hints = [f"--solver {name}=PATH"] + ([f"${entry.env}"] if entry.env else []) + \
            [f"solvers.{name}.path"]
        build = f"; build it: {entry.build}" if entry.build else ""
        raise StudyError(f"solver {name!r} not found ({'; '.join(tried) or 'no path given'}); "
                         f"give it by {', '.join(hints)}{build}", file=spec.source,
                         field=f"solvers.{name}")
    return out
