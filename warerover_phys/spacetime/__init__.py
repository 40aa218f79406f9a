"""Continuous-time validation: every agent's motion between two timed poses becomes its
swept body volume in space-time ``(x, y, t)``, and python-fcl finds any two volumes of
different agents that meet (see docs/spacetime.md).

- :mod:`.motion`: the input, :class:`TimedPlan` (timed poses per agent, linear in between),
  and converters from unit-time plans, timed cell schedules and ``trajectories.npz``;
- :mod:`.volumes`: the convex hulls in ``(x, y, t)``, built with numpy (exact for straight
  moves, conservative for turns);
- :mod:`.check`: broad phase, filters, fcl narrow phase, :func:`validate_spacetime`.
"""

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

__all__ = ["AgentMotion", "TimedPlan", "SpacetimeInputError", "SpacetimeConflict",
           "SpacetimeResult", "Volumes", "build_volumes", "from_plan", "from_schedule",
           "from_trajectory", "load_trajectory_file", "validate_spacetime",
           "DEFAULT_TOLERANCE_M", "DEFAULT_MAX_TURN_RAD"]
