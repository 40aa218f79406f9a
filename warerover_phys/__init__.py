"""warerover-phys: a closed-loop robotic warehouse simulator.

Order streams, schedulers, MAPF planners and executors run tick by tick on one world.

>>> from warerover_phys import load_scenario, run_episode
>>> result = run_episode(load_scenario("layouts/paper_homogeneous.yaml"), seed=1)
>>> result.metrics["collisions"]
0
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .errors import LayoutError, ScenarioError, WareroverError

if TYPE_CHECKING:
    from .config import Scenario, load_scenario, scenario_from_dict
    from .outputs import write_outputs
    from .sim import EpisodeResult, Simulation, run_episode

_LAZY = {"Scenario": "config", "load_scenario": "config", "scenario_from_dict": "config",
         "write_outputs": "outputs", "EpisodeResult": "sim", "Simulation": "sim",
         "run_episode": "sim"}


def __getattr__(name: str):
    """The simulator's entry points, imported on first use (the command line starts fast:
    ``warerover solve`` never loads the closed loop)."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'warerover_phys' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value

__all__ = ["Scenario", "load_scenario", "scenario_from_dict", "run_episode", "Simulation",
           "EpisodeResult", "write_outputs", "WareroverError", "ScenarioError", "LayoutError"]

__version__ = "0.1.0"
