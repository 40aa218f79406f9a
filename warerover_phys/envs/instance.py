"""What a :class:`~warerover_phys.envs.core.GridMAPF` is built from: the problem
(:class:`Instance`: a floor, starts and goals) and the settings (:class:`EnvConfig`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..config import AgvTypeSpec, ExecutorSpec, Scenario


TICK_S = 1.0
"""Seconds of simulated time per environment step on a real executor."""
ALIGN_RAD = 0.01
"""Rotations on a real executor: a turn is over once the body faces its new heading within
this (radians; the physics executor ends its turns exactly on the heading)."""


def default_agv() -> AgvTypeSpec:
    """The AGV of every agent on a real executor unless ``EnvConfig.agv_type`` says: 1x1,
    0.7 m body, 1 m/s, differential drive (a quarter turn in 0.63 s)."""
    from ..config import AgvTypeSpec

    return AgvTypeSpec(body_m=(0.7, 0.7), max_speed_mps=1.0)


@dataclass(frozen=True)
class EnvConfig:
    """Settings of an environment (immutable; ``ValueError`` on bad values)."""

    num_agents: int = 8
    fov_radius: int = 5
    """Observation window radius, cells (the window is ``2r+1`` cells a side)."""
    max_steps: int = 256
    """Steps (ticks) before the episode is truncated."""
    lifelong: bool = False
    goal_reward: float = 1.0
    step_penalty: float = -0.01
    blocked_penalty: float = -0.05
    executor: str | ExecutorSpec = "grid"
    """Who carries out the moves: ``"grid"`` (the step rules, applied directly), or an
    executor of the registry (``"physics"``, an entry point, ``package.module:ClassName``),
    by name or as an :class:`~warerover_phys.config.ExecutorSpec` (see the module doc)."""
    agv_type: AgvTypeSpec | None = None
    """Every agent's AGV on a real executor (default: 1x1, 0.7 m body, 1 m/s, diff drive)."""
    rotations: bool = False
    """Headings and wait / forward / turn left / turn right actions (see the module doc);
    also on when the instance asks (``Instance.rotations``)."""

    def __post_init__(self) -> None:
        if self.num_agents < 1:
            raise ValueError(f"num_agents must be >= 1 (got {self.num_agents})")
        if not 1 <= self.fov_radius <= 32:
            raise ValueError(f"fov_radius must be in 1..32 (got {self.fov_radius})")
        if self.max_steps < 1:
            raise ValueError(f"max_steps must be >= 1 (got {self.max_steps})")
        if isinstance(self.executor, str):
            if not self.executor:
                raise ValueError("executor must be a name (got '')")
        else:
            from ..config import ExecutorSpec

            if not isinstance(self.executor, ExecutorSpec):
                raise ValueError(f"executor must be a name or an ExecutorSpec (got "
                                 f"{self.executor!r})")
        if self.agv_type is not None:
            from ..config import AgvTypeSpec

            if not isinstance(self.agv_type, AgvTypeSpec) or self.agv_type.footprint != 1:
                raise ValueError(f"agv_type must be an AgvTypeSpec of footprint 1 (got "
                                 f"{self.agv_type!r})")
        if self.rotations and self.agv_type is not None and self.agv_type.drive != "diff":
            raise ValueError(f"rotations: the AGV must have a differential drive (got drive "
                             f"{self.agv_type.drive!r})")

    @property
    def executor_spec(self) -> ExecutorSpec | None:
        """The executor to build, or None for the step rules alone (``"grid"``)."""
        from ..config import ExecutorSpec

        spec = self.executor
        if isinstance(spec, str):
            return None if spec == "grid" else ExecutorSpec(name=spec)
        return None if spec.name == "grid" else spec


@dataclass(frozen=True, eq=False)
class Instance:
    """An obstacle grid and, optionally, fixed starts and goals ((row, col) per agent)."""

    obstacles: np.ndarray
    starts: tuple[tuple[int, int], ...] | None = None
    goals: tuple[tuple[int, int], ...] | None = None
    name: str = "grid"
    rotations: bool = False
    """The instance asks for headings and turn actions (a scenario's ``planner.rotations``)."""

    @classmethod
    def from_movingai(cls, map_file: str | Path, scen_file: str | Path | None = None,
                      num_agents: int | None = None) -> Instance:
        """A MovingAI map; with a ``.scen`` file, its first ``num_agents`` starts/goals."""
        from ..problems.movingai import read_map, read_scen

        m = read_map(map_file)
        if scen_file is None:
            return cls(m.obstacles, name=m.name)
        agents = read_scen(scen_file)
        if num_agents is not None:
            if num_agents > len(agents):
                raise ValueError(f"{scen_file} has {len(agents)} agents, asked for "
                                 f"{num_agents}")
            agents = agents[:num_agents]
        return cls(m.obstacles, tuple(a.start for a in agents), tuple(a.goal for a in agents),
                   m.name)

    @classmethod
    def from_scenario(cls, path: str | Path | Scenario) -> Instance:
        """The layout of a scenario YAML (or a loaded :class:`~warerover_phys.config.Scenario`,
        or a shipped scenario's name); unloaded AGVs: only obstacles block them."""
        from ..config import Scenario, load_scenario
        from ..layout import build_layout

        sc = path if isinstance(path, Scenario) else load_scenario(path)
        layout = build_layout(sc.layout, fleet_size=sc.fleet.size, file=sc.source,
                              name=sc.name)
        return cls(layout.obstacles.copy(), name=sc.name, rotations=sc.planner.rotations)

    @classmethod
    def coerce(cls, source: Instance | Scenario | str | Path) -> Instance:
        """An :class:`Instance` from what the environments take, as ``loop_env`` does: an
        Instance (as it is), a loaded Scenario, a MovingAI ``.map`` path, or a scenario
        YAML path (or a shipped scenario's name)."""
        if isinstance(source, Instance):
            return source
        if isinstance(source, str | Path):
            if Path(source).suffix.lower() == ".map":
                return cls.from_movingai(source)
            return cls.from_scenario(source)
        from ..config import Scenario

        if isinstance(source, Scenario):
            return cls.from_scenario(source)
        raise TypeError(f"expected an Instance, a Scenario, a scenario YAML path or a "
                        f"MovingAI .map path (got {type(source).__name__})")
