"""What the environments' helpers read of a grid MAPF world (:class:`EnvState`): the
frames (:mod:`.view`) and the learned driver (:mod:`.actions`) take any object with these
fields, :class:`~warerover_phys.envs.core.GridMAPF` among them, so that they need not
import the core that imports them."""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

__all__ = ["EnvState"]


class EnvState(Protocol):
    """The read-only fields of a grid MAPF world that the frames and drivers use."""

    rows: int
    cols: int
    free: np.ndarray
    pos: np.ndarray
    goal: np.ndarray
    heading: np.ndarray
    rotations: bool
    graph: Any

    def on_goal(self) -> np.ndarray: ...
