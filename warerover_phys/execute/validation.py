"""A plan against the floor and the fleet, vectorised over timesteps (:func:`validate_plan`)."""

from __future__ import annotations

import numpy as np

from ..layout import CellType, Layout
from ..plans.model import Plan
from .floor import PlanError


def _dense(plan: Plan) -> np.ndarray:
    """Cells as an array (T, N, 2), every path padded with its last cell."""
    horizon = plan.makespan + 1
    out = np.empty((horizon, plan.num_agents, 2), dtype=np.int64)
    for i, path in enumerate(plan.paths):
        arr = np.asarray(path, dtype=np.int64).reshape(-1, 2)
        out[:len(arr), i] = arr
        out[len(arr):, i] = arr[-1]
    return out


def validate_plan(plan: Plan, layout: Layout, sizes: list[int], *, source: str | None = None,
                  ) -> None:
    """Raise :class:`PlanError` for the first problem of ``plan`` on ``layout`` with AGVs
    of footprints ``sizes``: more agents than free cells, a map of another size, a cell off
    the map or on an obstacle, a jump of more than one cell, two agents on one cell (any
    footprint cell), or two agents passing through each other."""
    rows, cols = layout.rows, layout.cols
    n = plan.num_agents
    blocked = np.asarray(layout.grid) == CellType.OBSTACLE
    if plan.rows is not None and plan.cols is not None and (plan.rows, plan.cols) != (rows, cols):
        raise PlanError(f"plan is for a {plan.rows} x {plan.cols} map, the floor is "
                        f"{rows} x {cols}", file=source)
    free = int((~blocked).sum())
    if n > free:
        raise PlanError(f"{n} agents but the floor has only {free} free cells", file=source)
    if len(sizes) != n:
        raise PlanError(f"the fleet has {len(sizes)} AGVs, the plan {n} agents", file=source)
    pos = _dense(plan)
    k = np.asarray(sizes, dtype=np.int64)
    # Footprint cells: offsets (di, dj) for di, dj < k of each agent.
    kmax = int(k.max()) if n else 1
    for di in range(kmax):
        for dj in range(kmax):
            use = (di < k) & (dj < k)
            r, c = pos[:, use, 0] + di, pos[:, use, 1] + dj
            ids = np.flatnonzero(use)
            off = (r < 0) | (r >= rows) | (c < 0) | (c >= cols)
            if off.any():
                t, a = np.argwhere(off)[0]
                raise PlanError(f"cell {(int(r[t, a]), int(c[t, a]))} is off the {rows} x "
                                f"{cols} map", file=source, agent=int(ids[a]), timestep=int(t))
            hit = blocked[r, c]
            if hit.any():
                t, a = np.argwhere(hit)[0]
                raise PlanError(f"cell {(int(r[t, a]), int(c[t, a]))} is an obstacle",
                                file=source, agent=int(ids[a]), timestep=int(t))
    if len(pos) > 1:
        step = np.abs(np.diff(pos, axis=0)).sum(axis=2)
        jump = step > 1
        if jump.any():
            t, a = np.argwhere(jump)[0]
            raise PlanError(f"jumps from {tuple(map(int, pos[t, a]))} to "
                            f"{tuple(map(int, pos[t + 1, a]))} (more than one cell)",
                            file=source, agent=int(a), timestep=int(t + 1))
    _check_conflicts(pos, k, cols, source)


def _occupancy(pos: np.ndarray, k: np.ndarray, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Flat cells (T, M) covered by every agent's footprint, and the agent of each column."""
    cells, owners = [], []
    for di in range(int(k.max())):
        for dj in range(int(k.max())):
            use = np.flatnonzero((di < k) & (dj < k))
            cells.append((pos[:, use, 0] + di) * cols + pos[:, use, 1] + dj)
            owners.append(use)
    return np.concatenate(cells, axis=1), np.concatenate(owners)


def _check_conflicts(pos: np.ndarray, k: np.ndarray, cols: int, source: str | None) -> None:
    occ, owner = _occupancy(pos, k, cols)
    horizon = len(occ)
    order = np.argsort(occ, axis=1, kind="stable")
    srt = np.take_along_axis(occ, order, axis=1)
    dup = srt[:, 1:] == srt[:, :-1]
    if dup.any():
        t, j = np.argwhere(dup)[0]
        a, b = sorted((int(owner[order[t, j]]), int(owner[order[t, j + 1]])))
        cell = divmod(int(srt[t, j]), cols)
        raise PlanError(f"vertex conflict with agent {b} at cell {cell}", file=source, agent=a,
                        timestep=int(t))
    if horizon < 2:
        return
    # Swaps: agent a goes u -> v while agent b goes v -> u (anchor cells; for bigger
    # footprints a swap also overlaps at one of the two timesteps, caught above).
    anchors = pos[..., 0] * cols + pos[..., 1]
    src, dst = anchors[:-1], anchors[1:]
    moved = src != dst
    for t in np.flatnonzero(moved.any(axis=1)):
        m = np.flatnonzero(moved[t])
        fwd = {(int(src[t, a]), int(dst[t, a])): int(a) for a in m}
        for (u, v), a in fwd.items():
            b = fwd.get((v, u))
            if b is not None and a < b:
                raise PlanError(f"swap conflict with agent {b} between cells "
                                f"{divmod(u, cols)} and {divmod(v, cols)}", file=source,
                                agent=a, timestep=int(t + 1))
