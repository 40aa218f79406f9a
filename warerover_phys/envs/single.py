"""Gymnasium single-agent view: agent 0 acts; the other agents are part of the world.

The others follow the shipped learned policy behind its PIBT shield (``others="learned"``,
the default) or stand still (``others="wait"``); their choices are made first, then agent
0's action replaces its own, and the step rules of :mod:`warerover_phys.envs.core` apply
(a conflicting move of agent 0 is cancelled). Reward, termination (agent 0 on its goal,
one-shot) and truncation are agent 0's. With ``executor="physics"`` (or another executor)
the moves are carried out by it (see :mod:`warerover_phys.envs.core`); while agent 0 is
``info["in_transit"]`` (or, with rotations, ``info["turning"]``) its actions are treated
as wait. :func:`register` adds it to Gymnasium's registry as
``warerover/MAPF-v0`` (``gymnasium.make("warerover/MAPF-v0", scenario="layouts/...yaml")``
or ``instance=`` an :class:`~warerover_phys.envs.core.Instance`, a scenario or a MovingAI
``.map`` path, as :meth:`Instance.coerce <warerover_phys.envs.core.Instance.coerce>`
takes); importing changes no registry. With rotations (``rotations=True`` or a scenario's
``planner.rotations``) the others' moves become rotation actions (a turn first where a move
is not straight ahead; see :func:`~warerover_phys.envs.core.rotation_actions`).

>>> from warerover_phys.envs import MAPFGymEnv, Instance
>>> import numpy as np
>>> env = MAPFGymEnv(Instance(np.zeros((6, 6), dtype=bool)), num_agents=4)
>>> obs, info = env.reset(seed=0)
>>> obs.shape
(4, 11, 11)
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .deps import require

require("gymnasium")

import gymnasium as gym  # noqa: E402
from gymnasium import spaces  # noqa: E402

from .core import EnvConfig, GridMAPF, Instance, LearnedDriver, render_ansi, render_rgb  # noqa: E402

if TYPE_CHECKING:
    from ..config import Scenario

__all__ = ["MAPFGymEnv", "register"]


class MAPFGymEnv(gym.Env):
    metadata = {"render_modes": ["ansi", "rgb_array"], "render_fps": 4}

    def __init__(self, instance: Instance | Scenario | str | Path | None = None,
                 render_mode: str | None = None, others: str = "learned", *,
                 scenario: Scenario | str | Path | None = None, **config) -> None:
        if (instance is None) == (scenario is None):
            raise TypeError("give the grid as instance= (an Instance, a scenario or a .map "
                            "path) or as scenario= (a scenario YAML path), one of them")
        instance = Instance.coerce(instance if instance is not None else scenario)
        if others not in ("learned", "wait"):
            raise ValueError(f"others must be 'learned' or 'wait' (got {others!r})")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} "
                             f"(got {render_mode!r})")
        self.core = GridMAPF(instance, EnvConfig(**config))
        self.render_mode = render_mode
        self.others = others
        self.observation_space = spaces.Box(-1.0, 1.0, self.core.obs_shape, dtype=np.float32)
        self.action_space = spaces.Discrete(self.core.num_actions)
        self._driver: LearnedDriver | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        obs = self.core.reset(self.np_random)
        if self.others == "learned":
            self._driver = LearnedDriver(self.core, seed=int(self.np_random.integers(2**31)))
            self._driver.reset()
        return obs[0], {"on_goal": bool(self.core.on_goal()[0]), "in_transit": False,
                        "turning": False}

    def step(self, action):
        if self._driver is not None:
            actions = self._driver.actions()
        else:
            actions = np.zeros(self.core.num_agents, dtype=np.int64)
        actions[0] = int(action)
        obs, rewards, blocked, _, truncated = self.core.step(actions)
        on = bool(self.core.on_goal()[0])
        terminated = on and not self.core.config.lifelong
        return (obs[0], float(rewards[0]), terminated, bool(truncated and not terminated),
                {"on_goal": on, "blocked": bool(blocked[0]),
                 "in_transit": bool(self.core.in_transit()[0]),
                 "turning": bool(self.core.turning()[0])})

    def render(self):
        if self.render_mode == "ansi":
            return render_ansi(self.core)
        if self.render_mode == "rgb_array":
            return render_rgb(self.core)
        return None


def register() -> None:
    """Register ``warerover/MAPF-v0`` with Gymnasium (once; later calls do nothing)."""
    if "warerover/MAPF-v0" not in gym.registry:
        gym.register("warerover/MAPF-v0", entry_point=MAPFGymEnv)
