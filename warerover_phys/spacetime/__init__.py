"""Continuous-time validation: every agent's motion between two timed poses becomes its
swept body volume in space-time ``(x, y, t)``, and python-fcl finds any two volumes of
different agents that meet (see docs/spacetime.md).

- :mod:`.motion`: the input, :class:`TimedPlan` (timed poses per agent, linear in between),
  and converters from unit-time plans, timed cell schedules and ``trajectories.npz``;
- :mod:`.volumes`: the convex hulls in ``(x, y, t)``, built with numpy (exact for straight
  moves, conservative for turns);
- :mod:`.check`: broad phase, filters, fcl narrow phase, :func:`validate_spacetime`.

The names below load their submodule on first use, so that ``warerover``'s command line
(which registers ``check-trajectory`` from :mod:`.cli`) starts without numpy or fcl.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__all__ = ["AgentMotion", "TimedPlan", "SpacetimeInputError", "SpacetimeConflict",
           "SpacetimeResult", "Volumes", "build_volumes", "from_plan", "from_schedule",
           "from_trajectory", "load_trajectory_file", "validate_spacetime",
           "DEFAULT_TOLERANCE_M", "DEFAULT_MAX_TURN_RAD"]

_WHERE = {"AgentMotion": "motion", "TimedPlan": "motion", "SpacetimeInputError": "motion",
          "from_plan": "motion", "from_schedule": "motion", "from_trajectory": "motion",
          "load_trajectory_file": "motion", "Volumes": "volumes", "build_volumes": "volumes",
          "SpacetimeConflict": "check", "SpacetimeResult": "check",
          "validate_spacetime": "check", "DEFAULT_TOLERANCE_M": "check",
          "DEFAULT_MAX_TURN_RAD": "check"}

if TYPE_CHECKING:
    from .check import (
        DEFAULT_MAX_TURN_RAD,
        DEFAULT_TOLERANCE_M,
        SpacetimeConflict,
        SpacetimeResult,
        validate_spacetime,
    )
    from .motion import (
        AgentMotion,
        SpacetimeInputError,
        TimedPlan,
        from_plan,
        from_schedule,
        from_trajectory,
        load_trajectory_file,
    )
    from .volumes import Volumes, build_volumes


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
