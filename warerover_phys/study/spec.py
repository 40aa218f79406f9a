"""Study files: planners x instances x robot models, executed on physics.

A study file is YAML with a closed schema (unknown keys are errors; paths are relative to the
file)::

    name: tradeoffs
    instances:                       # one-shot MAPF instances: map x scens x agent counts
      - map: ../data/warehouse-10-20-10-2-1.map
        scens: [../data/warehouse-10-20-10-2-1-random-1.scen, ...]
        agents: [100, 200, 400, 700]
    planners:                        # label -> how its plans are made
      lacam: {solver: lacam, time_limit_s: 10}
      lacam-refine: {solver: lacam, refine: true, time_limit_s: 10}
      pibt-rot: {solver: pibt, rotations: true, time_limit_s: 20}
      lacam+motion: {solver: lacam, timing: motion}
      lacam3: {command: "{lacam3} -m {map} -i {scen} -N {n} -o {out} -t {time}"}
      given: {plans: ../my-plans, pattern: "{scen}-{n}.txt"}
    solvers:                         # binaries named in command templates
      lacam3: {path: /opt/lacam3/main, env: WAREROVER_LACAM3, build: "cmake ..."}
    robots:                          # the robots' model (AgvTypeSpec fields)
      standard: {max_speed_mps: 1.0, max_accel_mps2: 1.0, max_turn_rate_radps: 1.6}
    mismatch:                        # true robot = model x factors; the planner assumes the model
      exact: {}
      slow-turns: {turn_rate: 0.8}
    delays: {none: {}}               # label -> DelaySpec (model, prob, min/max ticks ...)
    seeds: [0]
    execution: {dt_s: 0.1, tick_s: 1.0}
    exclude:                         # combinations left out (all given items must match)
      - {agents: [400, 700], robots: [fast]}
    lifelong:                        # lifelong cells: scenario x planner x overrides
      scenarios: {Ho: ../layouts/paper_homogeneous.yaml, rr: ../rr/warehouse_small_50.json}
      planners: {astar: {planner.name: astar}}   # a *.json: a Robot Runners problem
      grid: {planner.invoke: [every_tick, "periodic:5"], planner.latency: [none, measured]}

A *cell* is one (instance, agent count, scen, planner, robot, mismatch, delays, seed) or one
lifelong (scenario, planner, overrides, seed). Its key names every label with a short hash
of what the label stands for, so editing a planner's settings without renaming it does not
reuse the old rows.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import os
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from ..config import AgvTypeSpec, DelaySpec
from ..errors import ScenarioError
from ..sweep.spec import read_spec_file

__all__ = ["StudySpec", "StudyError", "PlannerEntry", "SolverEntry", "Mismatch", "Execution",
           "InstanceEntry", "LifelongEntry", "load_study", "content_hash", "DIMENSIONS",
           "PLACEHOLDERS"]

PosInt = Annotated[int, Field(ge=1, strict=True)]
PosFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
MAX_CELLS = 1_000_000
DIMENSIONS = ("instance", "agents", "scen", "planners", "robots", "mismatch", "delays", "seed")
"""What an ``exclude`` rule may name."""
PLACEHOLDERS = ("map", "scen", "n", "out", "time", "seed")
"""The placeholders of a command template besides the solvers' names."""


class StudyError(ScenarioError):
    """A bad study file: ``FILE: FIELD: MESSAGE (got VALUE)`` on one line."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def content_hash(value: Any) -> str:
    """Six hex digits of the JSON of ``value`` (keys sorted): a label's content in a key."""
    text = json.dumps(value, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:6]


class InstanceEntry(_Model):
    """A MovingAI map, its scenario files and the agent counts to take from each."""

    map: str
    scens: list[str] = Field(min_length=1)
    agents: list[PosInt] = Field(min_length=1)
    label: str | None = None
    """Name in tables (default: the map's file stem)."""

    @property
    def name(self) -> str:
        return self.label or Path(self.map).stem


class PlannerEntry(_Model):
    """How a planner's plans are made: a built-in one-shot ``solver``, an external
    ``command`` template, or a folder of ready ``plans``."""

    solver: Literal["lacam", "pibt", "astar"] | None = None
    refine: bool = False
    """``lacam``: lower the first solution's sum of costs by LNS until the time limit."""
    guide: bool = True
    rotations: bool = False
    """Plan turns in place (differential drive): the planner's robot model gives each turn's
    ticks; the planner then steps tick by tick (``pibt``, ``lacam``) or plans each AGV's
    turning path (``astar``, prioritized)."""
    timing: Literal["unit", "motion"] = "unit"
    """``motion``: the planned side (sum of costs, makespan) is the plan's motion-model
    schedule for the planner's robot model (seconds); ``unit``: ticks x ``tick_s``."""
    time_limit_s: PosFloat = 10.0
    command: str | None = None
    """A command line with placeholders ``{map} {scen} {n} {out} {time} {seed}`` and the
    ``solvers``' names (``{lacam3}``); run without a shell; the plan it writes to ``{out}``
    is read by :func:`warerover_phys.plans.read_plan`."""
    plans: str | None = None
    """A folder of plan files, one per instance, named by ``pattern``."""
    pattern: str = "{scen}-{n}.txt"
    """Plan file names in ``plans``: ``{map}`` (map stem), ``{scen}`` (scen stem), ``{n}``,
    ``{seed}``."""
    format: str | None = None
    """The plan format of ``command``'s output or the ``plans`` files (default: detected)."""

    @model_validator(mode="after")
    def _one_kind(self) -> PlannerEntry:
        given = [k for k in ("solver", "command", "plans") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of solver (built-in), command (external) or "
                             f"plans (a folder); got {given or 'none'}")
        if self.rotations and self.solver is None:
            raise ValueError("rotations: only the built-in solvers plan rotations")
        if self.refine and self.solver != "lacam":
            raise ValueError("refine: only with solver: lacam")
        if self.format is not None:
            from ..plans import FORMATS

            if self.format not in FORMATS:
                raise ValueError(f"format {self.format!r} is not one of {sorted(FORMATS)}")
        return self

    @property
    def kind(self) -> str:
        return "builtin" if self.solver else "command" if self.command else "plans"

    def solver_names(self) -> list[str]:
        """The ``{name}`` placeholders of ``command`` that are not the fixed ones."""
        import string

        if self.command is None:
            return []
        names = [f for _, f, _, _ in string.Formatter().parse(self.command) if f]
        return [f for f in dict.fromkeys(names) if f not in PLACEHOLDERS]


class SolverEntry(_Model):
    """An external solver binary: where it is and how to build it."""

    path: str | None = None
    """The binary (absolute, or relative to the study file)."""
    env: str | None = None
    """An environment variable that, when set, names the binary (it wins over ``path``)."""
    build: str | None = None
    """How to build it (shown when the binary is missing)."""


class Mismatch(_Model):
    """The robots' true model as factors of the model the planner assumes."""

    speed: PosFloat = 1.0
    accel: PosFloat = 1.0
    turn_rate: PosFloat = 1.0

    def apply(self, spec: AgvTypeSpec) -> AgvTypeSpec:
        return spec.model_copy(update={
            "max_speed_mps": spec.max_speed_mps * self.speed,
            "max_accel_mps2": spec.max_accel_mps2 * self.accel,
            "max_turn_rate_radps": spec.max_turn_rate_radps * self.turn_rate})


class Execution(_Model):
    """How every plan is executed (the physics executor, open loop)."""

    tick_s: PosFloat = 1.0
    dt_s: PosFloat = 0.1
    trajectory_hz: PosFloat = 2.0
    keep_trajectories: bool = False
    """Write each cell's ``trajectories.npz`` under ``DIR/cells/``."""
    max_ticks_factor: PosFloat = 10.0
    """A cell stops after ``factor x plan makespan + 200`` ticks (recorded as incomplete)."""
    options: dict[str, Any] = Field(default_factory=dict)
    """Other executor fields (``no_slip``, ``comm_latency_s``, ``adg`` ...)."""
    cell_timeout_s: PosFloat | None = 300.0
    """Wall-clock guard of one cell's execution (and motion schedule): past it the cell
    is a row with status ``timeout`` (None: no guard). Not part of a cell's identity."""
    plan_grace_s: PosFloat | None = 60.0
    """Wall-clock guard of obtaining and repairing a plan: ``2 x time_limit_s +
    plan_grace_s`` seconds, then the task's cells are rows with status ``timeout`` (None:
    no guard). Not part of a cell's identity."""

    @model_validator(mode="after")
    def _steps(self) -> Execution:
        if self.dt_s > self.tick_s:
            raise ValueError(f"dt_s {self.dt_s} is longer than a tick ({self.tick_s} s)")
        if self.trajectory_hz * self.dt_s > 1 + 1e-9:
            raise ValueError(f"trajectory_hz {self.trajectory_hz} is above the physics rate "
                             f"(1 / dt_s = {1 / self.dt_s:g} Hz)")
        from ..execute import executor_spec

        try:
            executor_spec("physics", dt_s=self.dt_s, options=self.options, source="options")
        except ScenarioError as err:
            raise ValueError(f"options: {err.field}: {err.message}") from None
        return self


class LifelongEntry(_Model):
    """Lifelong cells: scenario files x planners x override grid x seeds, run by the
    closed loop (``warerover run``); reported with their throughput."""

    scenarios: dict[str, str] = Field(min_length=1)
    planners: dict[str, dict[str, Any]] = Field(min_length=1)
    """Label -> overrides (``{planner.name: lacam, planner.rotations: true}``)."""
    grid: dict[str, list[Any]] = Field(default_factory=dict)
    """Override path -> values (``--set`` paths, e.g. ``planner.invoke``)."""
    set: dict[str, Any] = Field(default_factory=dict)
    seeds: list[Annotated[int, Field(ge=0)]] = Field(default_factory=lambda: [0], min_length=1)

    @field_validator("grid")
    @classmethod
    def _grid(cls, value: dict[str, list[Any]]) -> dict[str, list[Any]]:
        for key, values in value.items():
            if not values:
                raise ValueError(f"grid.{key} lists no values")
        return value


class StudySpec(_Model):
    name: str = "study"
    instances: list[InstanceEntry] = Field(default_factory=list)
    planners: dict[str, PlannerEntry] = Field(default_factory=dict)
    solvers: dict[str, SolverEntry] = Field(default_factory=dict)
    robots: dict[str, AgvTypeSpec] = Field(default_factory=lambda: {"default": AgvTypeSpec()})
    mismatch: dict[str, Mismatch] = Field(default_factory=lambda: {"exact": Mismatch()})
    delays: dict[str, DelaySpec] = Field(default_factory=lambda: {"none": DelaySpec()})
    seeds: list[Annotated[int, Field(ge=0)]] = Field(default_factory=lambda: [0], min_length=1)
    execution: Execution = Execution()
    exclude: list[dict[str, Any]] = Field(default_factory=list)
    lifelong: LifelongEntry | None = None
    source: str | None = Field(default=None, exclude=True)

    @model_validator(mode="after")
    def _consistent(self) -> StudySpec:
        if not self.instances and self.lifelong is None:
            raise ValueError("a study needs instances (with planners) or lifelong cells")
        if self.instances and not self.planners:
            raise ValueError("planners: instances need at least one planner")
        for dim in ("robots", "mismatch", "delays"):
            if not getattr(self, dim):
                raise ValueError(f"{dim}: give at least one")
        for label, spec in self.robots.items():
            if spec.footprint != 1:
                raise ValueError(f"robots.{label}.footprint: MovingAI instances are 1x1 "
                                 f"(got {spec.footprint})")
        for label, p in self.planners.items():
            for name in p.solver_names():
                if name not in self.solvers:
                    raise ValueError(f"planners.{label}.command: {{{name}}} is neither one of "
                                     f"{', '.join('{' + x + '}' for x in PLACEHOLDERS)} nor a "
                                     f"solver of 'solvers' ({sorted(self.solvers) or 'none'})")
        for i, rule in enumerate(self.exclude):
            for key in rule:
                if key not in DIMENSIONS:
                    raise ValueError(f"exclude[{i}]: {key!r} is not one of {list(DIMENSIONS)}")
        if self.cell_count() > MAX_CELLS:
            raise ValueError(f"the study would hold more than {MAX_CELLS:,} cells")
        return self

    def cell_count(self) -> int:
        one = sum(len(i.scens) * len(i.agents) for i in self.instances) * len(self.planners) \
            * len(self.robots) * len(self.mismatch) * len(self.delays) * len(self.seeds)
        life = 0
        if self.lifelong is not None:
            life = len(self.lifelong.scenarios) * len(self.lifelong.planners) * \
                len(self.lifelong.seeds)
            for values in self.lifelong.grid.values():
                life *= len(values)
        return one + life

    @property
    def base_dir(self) -> Path:
        return Path(self.source).parent if self.source else Path.cwd()

    def path(self, text: str) -> Path:
        """A path of the study file, relative to it (``~`` and ``$VARS`` expanded)."""
        p = Path(os.path.expandvars(os.path.expanduser(text)))
        return p if p.is_absolute() else (self.base_dir / p)

    def excluded(self, combo: dict[str, Any]) -> bool:
        """Whether a combination of dimension values matches an ``exclude`` rule."""
        for rule in self.exclude:
            if all(combo.get(k) in (v if isinstance(v, list) else [v]) for k, v in rule.items()):
                return True
        return False

    def pairs(self) -> list[tuple[str, str, str]]:
        """(robot, mismatch, delays) labels in file order."""
        return list(itertools.product(self.robots, self.mismatch, self.delays))


def load_study(path: str | Path) -> StudySpec:
    """Read and validate a study file; a :class:`StudyError` names the file, field and
    value. Checks that the maps, scenario files and plan folders exist."""
    spec = read_spec_file(path, "study", StudySpec, StudyError)
    _check_files(spec)
    return spec


def _check_files(spec: StudySpec) -> None:
    src = spec.source
    for i, inst in enumerate(spec.instances):
        if not spec.path(inst.map).is_file():
            raise StudyError("map file not found", file=src, field=f"instances[{i}].map",
                             value=inst.map)
        for j, scen in enumerate(inst.scens):
            if not spec.path(scen).is_file():
                raise StudyError("scenario file not found", file=src,
                                 field=f"instances[{i}].scens[{j}]", value=scen)
    for label, p in spec.planners.items():
        if p.plans is not None and not spec.path(p.plans).is_dir():
            raise StudyError("plan folder not found", file=src,
                             field=f"planners.{label}.plans", value=p.plans)
    if spec.lifelong is not None:
        for label, f in spec.lifelong.scenarios.items():
            if not spec.path(f).is_file():
                raise StudyError("scenario file not found", file=src,
                                 field=f"lifelong.scenarios.{label}", value=f)
