"""Body poses of AGVs that follow grid states (no drawing library needed): used by the
renderer's grid recordings and by ``execute`` on the grid executor."""

from __future__ import annotations

import numpy as np

__all__ = ["states_poses"]


def _centres(nodes: np.ndarray, k: int, cols: int, cell_m: float) -> np.ndarray:
    """Body centres (metres) of a ``k x k`` AGV anchored at flat ``nodes``."""
    r, c = np.divmod(np.asarray(nodes, dtype=np.int64), cols)
    return np.stack([(c + k / 2) * cell_m, (r + k / 2) * cell_m], axis=-1)


def states_poses(actual: dict[int, list], footprint: np.ndarray, cols: int,
                 cell_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Body centres (T, N, 2) and headings (T, N) of per-tick grid states (a state between
    two cells is half-way; a heading is the direction of the last move that ended there or
    earlier, and before its first move an AGV faces that move)."""
    n = len(footprint)
    ticks = max(len(v) for v in actual.values())
    pos = np.zeros((ticks, n, 2))
    for aid, states in actual.items():
        arr = np.asarray(states, dtype=np.int64)
        arr = np.vstack([arr, np.repeat(arr[-1:], ticks - len(arr), axis=0)])
        k = int(footprint[aid])
        pos[:, aid] = 0.5 * (_centres(arr[:, 0], k, cols, cell_m)
                             + _centres(arr[:, 1], k, cols, cell_m))
    step = np.diff(pos, axis=0)
    moving = np.abs(step).sum(axis=2) > 1e-9
    ang = np.arctan2(step[..., 1], step[..., 0])
    last = np.where(moving.any(axis=0), ang[moving.argmax(axis=0), np.arange(n)], 0.0) \
        if ticks > 1 else np.zeros(n)
    heading = np.zeros((ticks, n))
    heading[0] = last
    for t in range(1, ticks):
        last = np.where(moving[t - 1], ang[t - 1], last)
        heading[t] = last
    return pos, heading
