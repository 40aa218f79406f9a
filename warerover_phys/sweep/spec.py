"""Sweep files: which scenarios, which grid of overrides, how many seeds.

A sweep file is YAML with a closed schema (unknown keys are errors)::

    name: table1
    scenarios:                      # label -> scenario file (relative to this file)
      Ho: ../layouts/paper_homogeneous.yaml
      FT: {file: ../layouts/paper_fault.yaml, set: {max_ticks: 1500}}
    grid:                           # every combination of these override values
      scheduler.name: [ta, rd]
      planner.name: [astar, cbs, "my_pkg.planners:GreedyPlanner"]
      orders.pattern: [oneshot, burst]
    set: {executor.name: grid}      # the same overrides for every episode
    exclude:                        # combinations to leave out (all given items must match)
      - {scenario: FT, scheduler.name: rd}
    repetitions: 100                # seeds seed_start .. seed_start + 99
    seed_start: 0                   # (or: seeds: [1, 5, 9])

An *episode* is one (scenario label, overrides, seed); its key is
``[label, sorted [path, value] pairs, seed]`` as compact JSON.

>>> import textwrap, tempfile, pathlib
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> _ = (d / "s.yaml").write_text(textwrap.dedent('''
...     scenarios: {Ho: %s}
...     grid: {planner.name: [astar, cbs]}
...     repetitions: 2
... ''' % pathlib.Path("layouts/paper_homogeneous.yaml").resolve()))
>>> spec = load_sweep(d / "s.yaml")
>>> [(e.label, e.overrides, e.seed) for e in expand(spec)][:3]
[('Ho', (('planner.name', 'astar'),), 0), ('Ho', (('planner.name', 'cbs'),), 0), ('Ho', (('planner.name', 'astar'),), 1)]
"""

from __future__ import annotations

import itertools
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from ..config import Scenario, _from_validation_error, load_scenario, read_yaml
from ..errors import ScenarioError
from ..registry import check_plugins

__all__ = ["SweepSpec", "ScenarioEntry", "Episode", "SweepError", "load_sweep", "expand",
           "episode_key", "compile_scenarios", "narrow", "read_spec_file"]

M = TypeVar("M", bound=BaseModel)

MAX_EPISODES = 1_000_000
"""Most episodes one sweep may hold (scenarios x grid combinations x seeds)."""
PosInt = Annotated[int, Field(ge=1, le=MAX_EPISODES, strict=True)]
NonNegInt = Annotated[int, Field(ge=0, le=2**62, strict=True)]

DIMENSIONS = {"scheduler.name": "scheduler", "scheduler": "scheduler",
              "planner.name": "planner", "planner": "planner",
              "orders.pattern": "pattern"}
"""Override paths that the report turns into its own columns (the rest form a variant)."""


class SweepError(ScenarioError):
    """A bad sweep file: ``FILE: FIELD: MESSAGE (got VALUE)`` on one line."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _check_path(key: str) -> str:
    parts = key.split(".")
    if not key or any(not p for p in parts):
        raise ValueError(f"override path {key!r} has an empty part")
    if parts[0] == "seed":
        raise ValueError("set seeds with 'repetitions' / 'seed_start' or 'seeds', not as an "
                         "override")
    return key


class ScenarioEntry(_Model):
    """One scenario of the sweep: its file and overrides that apply to it only."""

    file: str
    set: dict[str, Any] = Field(default_factory=dict)

    @field_validator("set")
    @classmethod
    def _paths(cls, value: dict[str, Any]) -> dict[str, Any]:
        for key in value:
            _check_path(key)
        return value


class SweepSpec(_Model):
    name: str = "sweep"
    scenarios: dict[str, ScenarioEntry] = Field(min_length=1)
    """Label (used in keys and tables, e.g. ``Ho``) -> scenario file or entry."""
    grid: dict[str, list[Any]] = Field(default_factory=dict)
    """Override path -> values; the sweep runs every combination."""
    set: dict[str, Any] = Field(default_factory=dict)
    """Overrides applied to every episode."""
    exclude: list[dict[str, Any]] = Field(default_factory=list)
    """Combinations left out: a mapping of ``scenario`` and/or grid paths to values."""
    repetitions: PosInt | None = None
    seed_start: NonNegInt = 0
    seeds: list[NonNegInt] | None = None
    source: str | None = Field(default=None, exclude=True)

    @field_validator("scenarios", mode="before")
    @classmethod
    def _shorthand(cls, value: Any) -> Any:
        if isinstance(value, dict):
            return {k: {"file": v} if isinstance(v, str) else v for k, v in value.items()}
        return value

    @field_validator("grid")
    @classmethod
    def _grid(cls, value: dict[str, list[Any]]) -> dict[str, list[Any]]:
        for key, values in value.items():
            _check_path(key)
            if not values:
                raise ValueError(f"grid.{key} lists no values")
            seen = [json.dumps(v, sort_keys=True) for v in values]
            if len(set(seen)) != len(seen):
                raise ValueError(f"grid.{key} lists a value twice")
        return value

    @field_validator("set")
    @classmethod
    def _set(cls, value: dict[str, Any]) -> dict[str, Any]:
        for key in value:
            _check_path(key)
        return value

    @model_validator(mode="after")
    def _consistent(self) -> SweepSpec:
        if (self.repetitions is None) == (self.seeds is None):
            raise ValueError("give exactly one of repetitions (with seed_start) or seeds")
        if self.seeds is not None and len(set(self.seeds)) != len(self.seeds):
            raise ValueError("seeds lists a seed twice")
        combos = len(self.scenarios)
        for values in self.grid.values():
            combos *= len(values)
        seeds = len(self.seeds) if self.seeds is not None else self.repetitions or 0
        if combos * seeds > MAX_EPISODES:
            raise ValueError(f"the sweep would hold {combos * seeds:,} episodes (at most "
                             f"{MAX_EPISODES:,}: fewer grid values or repetitions)")
        both = sorted(set(self.grid) & set(self.set))
        if both:
            raise ValueError(f"{both[0]!r} is both in grid and in set")
        for i, rule in enumerate(self.exclude):
            for key, val in rule.items():
                if key == "scenario":
                    if val not in self.scenarios:
                        raise ValueError(f"exclude[{i}].scenario {val!r} is not one of "
                                         f"{sorted(self.scenarios)}")
                elif key not in self.grid:
                    raise ValueError(f"exclude[{i}]: {key!r} is neither 'scenario' nor a "
                                     f"grid path ({', '.join(self.grid) or 'grid is empty'})")
                elif val not in self.grid[key]:
                    raise ValueError(f"exclude[{i}].{key}: {val!r} is not one of the grid's "
                                     f"values {self.grid[key]}")
        return self

    @property
    def seed_list(self) -> list[int]:
        if self.seeds is not None:
            return list(self.seeds)
        assert self.repetitions is not None
        return list(range(self.seed_start, self.seed_start + self.repetitions))

    @property
    def base_dir(self) -> Path:
        return Path(self.source).parent if self.source else Path.cwd()

    def scenario_path(self, label: str) -> Path:
        return (self.base_dir / self.scenarios[label].file).resolve()

    def plugin_paths(self) -> tuple[str, ...]:
        """Where plugin modules are looked for besides ``sys.path``: the sweep file's folder
        and the working directory."""
        return tuple(dict.fromkeys([str(self.base_dir.resolve()), str(Path.cwd().resolve())]))


@dataclass(frozen=True)
class Episode:
    """One run to do: scenario ``label`` with ``overrides`` and ``seed``."""

    label: str
    overrides: tuple[tuple[str, Any], ...]
    """Every override of this episode (set, the scenario's set, the grid), sorted by path."""
    seed: int
    variant: tuple[tuple[str, Any], ...] = ()
    """The grid overrides that are not scheduler / planner / order pattern."""

    @property
    def key(self) -> str:
        return episode_key(self.label, self.overrides, self.seed)

    @property
    def combo(self) -> tuple[str, str]:
        """(label, overrides as JSON): hashable even when a value is a mapping or a list."""
        return self.label, json.dumps(self.overrides, sort_keys=True, default=str)


def episode_key(label: str, overrides: Any, seed: int) -> str:
    """The results key of an episode: compact JSON of ``[label, sorted overrides, seed]``."""
    items = sorted((list(kv) for kv in (overrides.items() if isinstance(overrides, dict)
                                         else overrides)), key=lambda kv: kv[0])
    return json.dumps([label, items, seed], sort_keys=True, separators=(",", ":"))


def load_sweep(path: str | Path) -> SweepSpec:
    """Read and validate a sweep file; a :class:`SweepError` names the file, field and value."""
    return read_spec_file(path, "sweep", SweepSpec, SweepError)


def read_spec_file(path: str | Path, kind: str, model: type[M], error: type[ScenarioError],
                   ) -> M:
    """Read the YAML file ``path`` (a ``kind`` file: sweep, study) and validate it as
    ``model`` with its ``source``; an ``error`` names the file, field and value."""
    path = Path(path)
    try:
        data = read_yaml(path, kind)
    except ScenarioError as err:
        raise error(err.message, file=err.file, field=err.field, value=err.value) from None
    try:
        return model.model_validate({**data, "source": str(path)})
    except ValidationError as err:
        e = _from_validation_error(err, str(path))
        raise error(e.message, file=e.file, field=e.field, value=e.value) from None


def narrow(spec: SweepSpec, *, repetitions: int | None = None,
           only: list[tuple[str, Any]] | None = None) -> SweepSpec:
    """A smaller sweep: the first ``repetitions`` seeds, and for each ``(path, value)`` of
    ``only`` just that grid value (``scenario`` picks one scenario label). Episodes keep
    their keys, so the full sweep later runs only what the smaller one left out."""
    update: dict[str, Any] = {}
    if repetitions is not None:
        if repetitions < 1:
            raise SweepError("must be at least 1", file=spec.source, field="--repetitions",
                             value=repetitions)
        update["seeds"] = spec.seed_list[:repetitions]
        update["repetitions"] = None
    grid = dict(spec.grid)
    scenarios = dict(spec.scenarios)
    for path, value in only or []:
        if path == "scenario":
            if value not in scenarios:
                raise SweepError(f"no scenario labelled so (choose from {sorted(scenarios)})",
                                 file=spec.source, field="--only scenario", value=value)
            scenarios = {value: scenarios[value]}
            continue
        if path not in grid:
            raise SweepError(f"not a grid path of the sweep ({', '.join(grid) or 'no grid'})",
                             file=spec.source, field="--only", value=path)
        match = [v for v in grid[path] if v == value or str(v) == str(value)]
        if not match:
            raise SweepError(f"not one of the grid's values {grid[path]}", file=spec.source,
                             field=f"--only {path}", value=value)
        grid[path] = match[:1]
    update.update(grid=grid, scenarios=scenarios)
    data = {**spec.model_dump(), **update, "source": spec.source}
    data["exclude"] = [rule for rule in spec.exclude
                       if all(k == "scenario" and v in scenarios or
                              k != "scenario" and v in grid[k] for k, v in rule.items())]
    return SweepSpec.model_validate(data)


def _excluded(spec: SweepSpec, label: str, combo: dict[str, Any]) -> bool:
    for rule in spec.exclude:
        if all((label == v) if k == "scenario" else (combo.get(k) == v)
               for k, v in rule.items()):
            return True
    return False


def expand(spec: SweepSpec) -> list[Episode]:
    """Every episode of the sweep, seed by seed (a partial run covers every combination
    with its first seeds), then scenario, then grid combination in file order."""
    keys = list(spec.grid)
    combos = [dict(zip(keys, values, strict=True))
              for values in itertools.product(*(spec.grid[k] for k in keys))]
    runs = []
    for label, entry in spec.scenarios.items():
        for combo in combos:
            if _excluded(spec, label, combo):
                continue
            merged = {**spec.set, **entry.set, **combo}
            overrides = tuple(sorted(merged.items()))
            variant = tuple((k, v) for k, v in combo.items() if k not in DIMENSIONS)
            runs.append((label, overrides, variant))
    return [Episode(label, overrides, seed, variant)
            for seed in spec.seed_list for label, overrides, variant in runs]


def compile_scenarios(spec: SweepSpec, episodes: list[Episode]) -> dict[tuple, Scenario]:
    """Load and validate the scenario of every distinct (label, overrides) once, import
    every plugin class, and build one world per distinct layout and fleet (reachability).

    Raises :class:`SweepError` naming the sweep file, the scenario label and overrides.
    """
    from ..world import World

    for extra in reversed(spec.plugin_paths()):
        if extra not in sys.path:
            sys.path.insert(0, extra)
    out: dict[tuple, Scenario] = {}
    built: set[str] = set()
    for ep in episodes:
        if ep.combo in out:
            continue
        label, overrides = ep.label, ep.overrides
        where = f"scenarios.{label}" + (
            " with " + ", ".join(f"{k}={v}" for k, v in overrides) if overrides else "")
        path = spec.scenario_path(label)
        try:
            sc = load_scenario(path, list(overrides))
            check_plugins(sc)
            world_key = json.dumps([str(path), sc.layout.model_dump(mode="json"),
                                    sc.fleet.model_dump(mode="json")], sort_keys=True)
            if world_key not in built:
                World.build(sc)
                built.add(world_key)
        except ScenarioError as err:
            raise _blame(spec, label, overrides, err, where, path) from None
        out[ep.combo] = sc
    return out


def _blame(spec: SweepSpec, label: str, overrides: tuple[tuple[str, Any], ...],
           err: ScenarioError, where: str, path: Path) -> SweepError:
    """Name the sweep field an error comes from when it is one of the overrides."""
    field = (err.field or "").replace("[", ".").replace("]", "")
    for key, value in overrides:
        norm = key if key not in ("scheduler", "planner", "executor") else f"{key}.name"
        if field and field in (key, norm):
            origin = ("grid" if key in spec.grid else "set" if key in spec.set
                      else f"scenarios.{label}.set")
            return SweepError(f"{err.message} (scenario {label}: {err.file or path})",
                              file=spec.source, field=f"{origin}.{key}", value=value)
    return SweepError(f"{where}: {err.with_file(str(path))}", file=spec.source)
