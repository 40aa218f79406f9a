"""The grid MAPF world behind the environments: numpy arrays indexed by agent slot.

:class:`GridMAPF` holds positions, goals and distance tables of ``N`` agents on an obstacle
grid and steps them all at once (no dicts, no spaces: the PettingZoo and Gymnasium classes
wrap it). It draws nothing itself: every random choice comes from the generator passed to
:meth:`GridMAPF.reset`.

Rules of one step (all agents at once, the ideal grid executor's semantics):

- actions ``0`` wait, ``1`` up, ``2`` down, ``3`` left, ``4`` right (row, col);
- a move off the grid or onto an obstacle is cancelled (the agent waits);
- conflicting moves are cancelled, repeatedly until none is left: several agents entering
  one cell (all of them wait; an agent that waits keeps its cell), two agents swapping cells
  (both wait). Following (entering a cell its agent leaves in the same step) and rotations
  are allowed, as in the MAPF definition the validator checks.

Rewards (per agent per step, defaults of :class:`EnvConfig`): ``+goal_reward`` (1.0) for
stepping onto its goal, ``-goal_reward`` for stepping off it (so waiting on and off the goal
earns nothing), ``step_penalty`` (-0.01) for ending the step off its goal, and
``blocked_penalty`` (-0.05) when its move was cancelled.

Episodes: one-shot (default) ends (``terminated``) when every agent stands on its goal;
lifelong (``lifelong=True``) gives an agent a new random goal the step it arrives and never
terminates. Both are truncated after ``max_steps`` steps.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..planning.graph import UNREACHABLE, MotionGraph
from ..planning.oneshot import grid_graph
from ..planning.policy import ACTIONS, NUM_ACTIONS, NUM_CHANNELS, ObsGrid, observe

__all__ = ["EnvConfig", "GridMAPF", "Instance"]


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

    def __post_init__(self) -> None:
        if self.num_agents < 1:
            raise ValueError(f"num_agents must be >= 1 (got {self.num_agents})")
        if not 1 <= self.fov_radius <= 32:
            raise ValueError(f"fov_radius must be in 1..32 (got {self.fov_radius})")
        if self.max_steps < 1:
            raise ValueError(f"max_steps must be >= 1 (got {self.max_steps})")


@dataclass(frozen=True, eq=False)
class Instance:
    """An obstacle grid and, optionally, fixed starts and goals ((row, col) per agent)."""

    obstacles: np.ndarray
    starts: tuple[tuple[int, int], ...] | None = None
    goals: tuple[tuple[int, int], ...] | None = None
    name: str = "grid"

    @classmethod
    def from_movingai(cls, map_file: str | Path, scen_file: str | Path | None = None,
                      num_agents: int | None = None) -> Instance:
        """A MovingAI map; with a ``.scen`` file, its first ``num_agents`` starts/goals."""
        from ..movingai import read_map, read_scen

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
    def from_scenario(cls, path: str | Path) -> Instance:
        """The layout of a scenario YAML (unloaded AGVs: only obstacles block them)."""
        from ..config import load_scenario
        from ..layout import build_layout

        sc = load_scenario(path)
        layout = build_layout(sc.layout, fleet_size=sc.fleet.size, file=str(path),
                              name=sc.name)
        return cls(layout.obstacles.copy(), name=sc.name)


class GridMAPF:
    """``N`` agents on a grid, stepped together (see the module doc)."""

    def __init__(self, instance: Instance, config: EnvConfig = EnvConfig()) -> None:
        self.instance = instance
        self.config = config
        obstacles = np.asarray(instance.obstacles, dtype=bool)
        self.graph: MotionGraph = grid_graph(obstacles)
        self.rows, self.cols = obstacles.shape
        self.free = ~obstacles
        self.obs_grid = ObsGrid(obstacles, config.fov_radius)
        n = config.num_agents
        if instance.starts is not None:
            if len(instance.starts) != n or instance.goals is None or len(instance.goals) != n:
                raise ValueError(f"instance {instance.name!r} fixes "
                                 f"{len(instance.starts)} agents, config asks for {n}")
        # The largest connected part of the free cells: where random starts/goals are drawn.
        free_nodes = np.flatnonzero(self.free.ravel())
        if len(free_nodes) == 0:
            raise ValueError(f"instance {instance.name!r} has no free cell")
        best = None
        seen = np.zeros(self.rows * self.cols, dtype=bool)
        for v in free_nodes:
            if seen[v]:
                continue
            part = self.graph.dist_to(self.graph.cell(int(v))) < UNREACHABLE
            seen |= part
            if best is None or part.sum() > best.sum():
                best = part
            if best.sum() * 2 > len(free_nodes):
                break
        self.sample_nodes = np.flatnonzero(best)
        if instance.starts is None and len(self.sample_nodes) < n:
            raise ValueError(f"{n} agents do not fit the {len(self.sample_nodes)} connected "
                             f"free cells of {instance.name!r}")
        self.pos = np.zeros(n, dtype=np.int64)
        self.goal = np.zeros(n, dtype=np.int64)
        self.dist = np.full((n, self.rows * self.cols + 1), UNREACHABLE, dtype=np.int32)
        """Per agent, distance to its goal from every node; last column: off the grid."""
        self.t = 0
        self._rng: np.random.Generator | None = None

    @property
    def num_agents(self) -> int:
        return self.config.num_agents

    @property
    def obs_shape(self) -> tuple[int, int, int]:
        w = 2 * self.config.fov_radius + 1
        return (NUM_CHANNELS, w, w)

    # ------------------------------------------------------------------------ episode

    def reset(self, rng: np.random.Generator) -> np.ndarray:
        """Start an episode (starts and goals drawn from ``rng`` unless fixed); returns the
        observations ``(N, 4, W, W)``."""
        self._rng = rng
        n = self.num_agents
        inst = self.instance
        if inst.starts is not None:
            self.pos[:] = [r * self.cols + c for r, c in inst.starts]
            self.goal[:] = [r * self.cols + c for r, c in inst.goals]
        else:
            self.pos[:] = rng.choice(self.sample_nodes, size=n, replace=False)
            self.goal[:] = rng.choice(self.sample_nodes, size=n, replace=False)
        for i in range(n):
            self.dist[i, :-1] = self.graph.dist_to(self.graph.cell(int(self.goal[i])))
        if (self.dist[np.arange(n), self.pos] >= UNREACHABLE).any():
            raise ValueError(f"instance {inst.name!r}: a goal cannot be reached from its start")
        self.t = 0
        return self.observe()

    def observe(self) -> np.ndarray:
        return observe(self.obs_grid, self.pos, self.goal, self.dist)

    def on_goal(self) -> np.ndarray:
        return self.pos == self.goal

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool, bool]:
        """Apply one action per agent: ``(obs, rewards, blocked, terminated, truncated)``."""
        cfg = self.config
        actions = np.asarray(actions, dtype=np.int64)
        if actions.shape != (self.num_agents,) or actions.min(initial=0) < 0 \
                or actions.max(initial=0) >= NUM_ACTIONS:
            raise ValueError(f"expected {self.num_agents} actions in 0..{NUM_ACTIONS - 1}, "
                             f"got {actions!r}")
        was_on = self.on_goal()
        target = self._resolve(actions)
        blocked = (actions != 0) & (target == self.pos)
        self.pos = target
        self.t += 1
        now_on = self.on_goal()
        rewards = (cfg.goal_reward * (now_on & ~was_on) - cfg.goal_reward * (was_on & ~now_on)
                   + cfg.step_penalty * ~now_on + cfg.blocked_penalty * blocked)
        if cfg.lifelong and now_on.any():
            self._new_goals(np.flatnonzero(now_on))
        terminated = (not cfg.lifelong) and bool(self.on_goal().all())
        truncated = not terminated and self.t >= cfg.max_steps
        return self.observe(), rewards.astype(np.float32), blocked, terminated, truncated

    def _new_goals(self, agents: np.ndarray) -> None:
        for i in agents:
            g = int(self.pos[i])
            while g == self.pos[i]:
                g = int(self._rng.choice(self.sample_nodes))
            self.goal[i] = g
            self.dist[i, :-1] = self.graph.dist_to(self.graph.cell(g))

    def _resolve(self, actions: np.ndarray) -> np.ndarray:
        """Next positions: moves off the grid, onto obstacles or into conflicts cancelled."""
        r, c = np.divmod(self.pos, self.cols)
        nr, nc = r + ACTIONS[actions, 0], c + ACTIONS[actions, 1]
        inside = (nr >= 0) & (nr < self.rows) & (nc >= 0) & (nc < self.cols)
        ok = inside & self.free[np.clip(nr, 0, self.rows - 1), np.clip(nc, 0, self.cols - 1)]
        target = np.where(ok, nr * self.cols + nc, self.pos)
        owner = np.full(self.rows * self.cols, -1, dtype=np.int64)
        idx = np.arange(len(target))
        owner[self.pos] = idx
        while True:
            moving = target != self.pos
            count = np.bincount(target, minlength=self.rows * self.cols)
            bad = moving & (count[target] > 1)
            j = owner[target]
            bad |= moving & (j >= 0) & (target[np.maximum(j, 0)] == self.pos)
            if not bad.any():
                return target
            target = np.where(bad, self.pos, target)

    def paths(self) -> list[tuple[int, int]]:
        """Current (row, col) of every agent."""
        return [divmod(int(v), self.cols) for v in self.pos]


class LearnedDriver:
    """The learned planner's policy and shield choosing every agent's action in a
    :class:`GridMAPF` (the same :class:`~warerover_phys.planning.learned.LearnedController`
    as :func:`~warerover_phys.planning.learned.learned_oneshot`, so a one-shot episode
    driven by it moves exactly as that planner does with the same ``seed``)."""

    def __init__(self, core: GridMAPF, policy=None, seed: int = 0) -> None:
        from ..planning.learned import LearnedController, load_policy

        self.core = core
        self.controller = LearnedController(policy or load_policy(), core.graph, seed=seed)

    def reset(self) -> None:
        self.controller.reset(self.core.pos.tolist(), self.core.goal.tolist())

    def actions(self) -> np.ndarray:
        """One action per agent for the core's current state (call once per step)."""
        from ..planning.policy import actions_from_moves

        ctrl, core = self.controller, self.core
        for i in np.flatnonzero(np.asarray(ctrl.goals) != core.goal):
            ctrl.set_goal(int(i), int(core.goal[i]))
        config = core.pos.tolist()
        return actions_from_moves(config, ctrl.step(config), core.cols)


def render_ansi(core: GridMAPF) -> str:
    """Text frame: ``@`` obstacle, ``.`` free, ``A`` agent, ``*`` agent on its goal,
    ``g`` a goal."""
    grid = np.where(core.free, ".", "@").astype("<U1")
    gr, gc = np.divmod(core.goal, core.cols)
    grid[gr, gc] = "g"
    pr, pc = np.divmod(core.pos, core.cols)
    grid[pr, pc] = np.where(core.on_goal(), "*", "A")
    return "\n".join("".join(row) for row in grid)


def render_rgb(core: GridMAPF, cell_px: int = 8) -> np.ndarray:
    """RGB frame ``(rows * cell_px, cols * cell_px, 3)`` uint8: obstacles black, agents
    blue (green on their goal), goals light red."""
    img = np.full((core.rows, core.cols, 3), 255, dtype=np.uint8)
    img[~core.free] = (0, 0, 0)
    gr, gc = np.divmod(core.goal, core.cols)
    img[gr, gc] = (255, 170, 170)
    pr, pc = np.divmod(core.pos, core.cols)
    img[pr, pc] = np.where(core.on_goal()[:, None], [40, 170, 40], [40, 80, 220])
    return np.repeat(np.repeat(img, cell_px, axis=0), cell_px, axis=1)
