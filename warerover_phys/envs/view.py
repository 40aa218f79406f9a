"""Text and RGB frames of a :class:`~warerover_phys.envs.core.GridMAPF`."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .state import EnvState


def render_ansi(core: EnvState) -> str:
    """Text frame: ``@`` obstacle, ``.`` free, ``A`` agent, ``*`` agent on its goal,
    ``g`` a goal."""
    grid = np.where(core.free, ".", "@").astype("<U1")
    gr, gc = np.divmod(core.goal, core.cols)
    grid[gr, gc] = "g"
    pr, pc = np.divmod(core.pos, core.cols)
    grid[pr, pc] = np.where(core.on_goal(), "*", "A")
    return "\n".join("".join(row) for row in grid)


def render_rgb(core: EnvState, cell_px: int = 8) -> np.ndarray:
    """RGB frame ``(rows * cell_px, cols * cell_px, 3)`` uint8: obstacles black, agents
    blue (green on their goal), goals light red."""
    img = np.full((core.rows, core.cols, 3), 255, dtype=np.uint8)
    img[~core.free] = (0, 0, 0)
    gr, gc = np.divmod(core.goal, core.cols)
    img[gr, gc] = (255, 170, 170)
    pr, pc = np.divmod(core.pos, core.cols)
    img[pr, pc] = np.where(core.on_goal()[:, None], [40, 170, 40], [40, 80, 220])
    return np.repeat(np.repeat(img, cell_px, axis=0), cell_px, axis=1)
