"""warerover-phys: a closed-loop robotic warehouse simulator.

Order streams, schedulers, MAPF planners and executors run tick by tick on one world.

>>> from warerover_phys import load_scenario, run_episode
>>> result = run_episode(load_scenario("layouts/paper_homogeneous.yaml"), seed=1)
>>> result.metrics["collisions"]
0
"""

from __future__ import annotations

from .config import Scenario, load_scenario, scenario_from_dict
from .errors import LayoutError, ScenarioError, WareroverError
from .outputs import write_outputs
from .sim import EpisodeResult, Simulation, run_episode

__all__ = ["Scenario", "load_scenario", "scenario_from_dict", "run_episode", "Simulation",
           "EpisodeResult", "write_outputs", "WareroverError", "ScenarioError", "LayoutError"]

__version__ = "0.1.0"
