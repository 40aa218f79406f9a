"""Gymnasium and PettingZoo environments over the project's grids (scenario layouts and
MovingAI maps), with the local observations the ``learned`` planner uses.

- :class:`~warerover_phys.envs.core.GridMAPF`: the numpy world (all agents per call);
- :func:`parallel_env`: a PettingZoo ``ParallelEnv``, one agent per AGV;
- :class:`MAPFGymEnv` (registered as ``warerover/MAPF-v0``): the Gymnasium single-agent
  view (agent 0 acts; the others follow the learned policy, or wait);
- :class:`~warerover_phys.envs.loop.WarehouseLoopEnv` (:func:`loop_env`): a scenario's whole
  closed loop (orders, scheduler, tasks, faults, grid or physics executor) as a PettingZoo
  ``ParallelEnv``, the agents in the planner's place; :class:`PlannerDriver` lets a step
  planner (``learned``, ``pibt``) choose the actions (the episode of ``warerover run``).

Gymnasium and PettingZoo are optional (``pip install warerover-phys[envs]``); they are
imported when a class that needs them is first used.

>>> from warerover_phys.envs import EnvConfig, GridMAPF, Instance
>>> import numpy as np
>>> core = GridMAPF(Instance(np.zeros((4, 4), dtype=bool)), EnvConfig(num_agents=2))
>>> core.reset(np.random.default_rng(0)).shape
(2, 4, 11, 11)
"""

from __future__ import annotations

from .core import EnvConfig, GridMAPF, Instance, LearnedDriver

__all__ = ["EnvConfig", "GridMAPF", "Instance", "LearnedDriver", "parallel_env",
           "MAPFParallelEnv", "MAPFGymEnv", "WarehouseLoopEnv", "loop_env", "PlannerDriver"]


def __getattr__(name: str):
    if name in ("MAPFParallelEnv", "parallel_env"):
        from . import parallel
        return getattr(parallel, name)
    if name in ("WarehouseLoopEnv", "loop_env", "PlannerDriver"):
        from . import loop
        return getattr(loop, name)
    if name == "MAPFGymEnv":
        from .single import MAPFGymEnv
        return MAPFGymEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
