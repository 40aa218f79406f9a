"""PettingZoo parallel environment: one agent (``agv_0`` ... ``agv_{N-1}``) per AGV.

Every agent observes its ``(4, 2r+1, 2r+1)`` window (see
:mod:`warerover_phys.planning.learned.policy`) and picks one of five actions (wait, up, down, left,
right; with rotations, ``rotations=True`` or a scenario's ``planner.rotations``: a fifth
channel for the heading and four actions, wait, forward, turn left, turn right); rules and
rewards are those of :mod:`warerover_phys.envs.core`. Agents stay in the
episode until it ends: a one-shot episode terminates for everybody when all stand on their
goals; any episode is truncated after ``max_steps``. ``infos[agent]`` holds ``on_goal``,
``blocked`` (it asked to move and did not leave its cell) and ``in_transit`` (on a real
executor, ``executor="physics"``: it is still moving between two cells, and its action is
treated as wait until it stands) and ``turning`` (rotations on a real executor: its body is
still turning to its new heading; its action is treated as wait until it faces it). Seeding as in Gymnasium: ``reset(seed=s)`` seeds the
episode generator, later resets without a seed continue it.

>>> from warerover_phys.envs import parallel_env, Instance
>>> import numpy as np
>>> env = parallel_env(Instance(np.zeros((5, 5), dtype=bool)), num_agents=3)
>>> obs, infos = env.reset(seed=1)
>>> sorted(obs)
['agv_0', 'agv_1', 'agv_2']
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .deps import require

require("pettingzoo")

from gymnasium import spaces  # noqa: E402
from gymnasium.utils import seeding  # noqa: E402
from pettingzoo import ParallelEnv  # noqa: E402

from .core import EnvConfig, GridMAPF, Instance, render_ansi, render_rgb  # noqa: E402

if TYPE_CHECKING:
    from ..config import Scenario

__all__ = ["MAPFParallelEnv", "parallel_env"]


class MAPFParallelEnv(ParallelEnv):
    metadata = {"name": "warerover_mapf_v0", "render_modes": ["ansi", "rgb_array"],
                "is_parallelizable": True}

    def __init__(self, instance: Instance | Scenario | str | Path,
                 config: EnvConfig | None = None, render_mode: str | None = None) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} "
                             f"(got {render_mode!r})")
        self.core = GridMAPF(Instance.coerce(instance), config or EnvConfig())
        self.render_mode = render_mode
        self.possible_agents = [f"agv_{i}" for i in range(self.core.config.num_agents)]
        self.agents: list[str] = []
        self._np_random: np.random.Generator | None = None
        self._obs_space = spaces.Box(-1.0, 1.0, self.core.obs_shape, dtype=np.float32)
        self._act_space = spaces.Discrete(self.core.num_actions)

    def observation_space(self, agent: str) -> spaces.Box:  # one object for all agents
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Discrete:
        return self._act_space

    def _infos(self, blocked: np.ndarray | None = None) -> dict[str, dict]:
        on, moving, turning = self.core.on_goal(), self.core.in_transit(), self.core.turning()
        return {a: {"on_goal": bool(on[i]),
                    "blocked": bool(blocked[i]) if blocked is not None else False,
                    "in_transit": bool(moving[i]), "turning": bool(turning[i])}
                for i, a in enumerate(self.possible_agents)}

    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None or self._np_random is None:
            self._np_random, _ = seeding.np_random(seed)
        obs = self.core.reset(self._np_random)
        self.agents = list(self.possible_agents)
        return dict(zip(self.agents, obs, strict=True)), self._infos()

    def step(self, actions: dict[str, int]):
        if not self.agents:
            raise RuntimeError("step() after the episode ended: call reset()")
        arr = np.array([int(actions.get(a, 0)) for a in self.possible_agents], dtype=np.int64)
        obs, rewards, blocked, terminated, truncated = self.core.step(arr)
        names = self.possible_agents
        out = (dict(zip(names, obs, strict=True)),
               {a: float(r) for a, r in zip(names, rewards, strict=True)},
               {a: terminated for a in names}, {a: truncated for a in names},
               self._infos(blocked))
        if terminated or truncated:
            self.agents = []
        return out

    def render(self):
        if self.render_mode == "ansi":
            return render_ansi(self.core)
        if self.render_mode == "rgb_array":
            return render_rgb(self.core)
        return None

    def close(self) -> None:
        pass

    def state(self) -> np.ndarray:
        """Global state: ``(3, rows, cols)`` float32 (obstacles, cells held by agents (both
        cells of an agent in transit), goals)."""
        c = self.core
        out = np.zeros((3, c.rows, c.cols), dtype=np.float32)
        out[0] = ~c.free
        out[1].flat[c.pos] = 1.0
        out[1].flat[c.dest] = 1.0
        out[2].flat[c.goal] = 1.0
        return out


def parallel_env(instance: Instance | Scenario | str | Path, render_mode: str | None = None,
                 **config) -> MAPFParallelEnv:
    """A :class:`MAPFParallelEnv` on ``instance`` (an :class:`Instance`, a scenario, a
    scenario YAML or MovingAI ``.map`` path: :meth:`Instance.coerce`); keyword arguments
    are :class:`EnvConfig` fields."""
    return MAPFParallelEnv(instance, EnvConfig(**config), render_mode)
