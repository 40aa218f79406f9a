"""Actions of agents with headings (:func:`rotation_actions`) and the learned planner
choosing every agent's action (:class:`LearnedDriver`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .state import EnvState


HEADING_STEP = np.array([[0, 1], [1, 0], [0, -1], [-1, 0]], dtype=np.int64)
"""(d_row, d_col) of each heading: east, south, west, north."""
HEADING_MOVE = np.array([4, 2, 3, 1], dtype=np.int64)
"""The move action (right, down, left, up) of each heading."""
MOVE_HEADING = np.array([-1, 3, 1, 2, 0], dtype=np.int64)
"""The heading of each move action (-1: wait)."""
TURN = np.array([0, 0, -1, 1], dtype=np.int64)
"""Heading change of each rotation action: wait, forward, turn left, turn right."""
NUM_ROT_ACTIONS = 4


def rotation_actions(moves: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Rotation actions that follow move actions: forward where the move is along the
    heading, else a turn towards it (left or right; right for a half turn), wait for wait."""
    moves = np.asarray(moves, dtype=np.int64)
    want = MOVE_HEADING[moves]
    diff = (want - heading) % 4
    out = np.where(diff == 0, 1, np.where(diff == 3, 2, 3))
    return np.where(moves == 0, 0, out)


class LearnedDriver:
    """The learned planner's policy and shield choosing every agent's action in a
    :class:`GridMAPF` (the same :class:`~warerover_phys.planning.learned.planner.LearnedController`
    as :func:`~warerover_phys.planning.learned.planner.learned_oneshot`, so a one-shot episode
    driven by it moves exactly as that planner does with the same ``seed``)."""

    def __init__(self, core: EnvState, policy=None, seed: int = 0) -> None:
        from ..planning.learned.planner import LearnedController, load_policy

        self.core = core
        self.controller = LearnedController(policy or load_policy(), core.graph, seed=seed)

    def reset(self) -> None:
        self.controller.reset(self.core.pos.tolist(), self.core.goal.tolist())

    def actions(self) -> np.ndarray:
        """One action per agent for the core's current state (call once per step); with
        rotations, the move's rotation action (a turn first where the move is not straight
        ahead: the policy is asked again next step)."""
        from ..planning.learned.policy import actions_from_moves

        ctrl, core = self.controller, self.core
        for i in np.flatnonzero(np.asarray(ctrl.goals) != core.goal):
            ctrl.set_goal(int(i), int(core.goal[i]))
        config = core.pos.tolist()
        moves = actions_from_moves(config, ctrl.step(config), core.cols)
        return rotation_actions(moves, core.heading) if core.rotations else moves
