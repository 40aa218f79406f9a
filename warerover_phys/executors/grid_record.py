"""What each AGV of a grid execution was doing at each tick, for its recording.

The grid executor keeps nothing but where each AGV stands; its recording is built after the
run from the executed states and the committed plans (:func:`grid_execution`), with the
fields the physics executor records per sample (:mod:`.recording`: ``exec_state``,
``blocker``, ``plan_tick``). Each AGV's progress in its plan is followed as the executor
follows it: a tick on which the AGV reaches its plan's next state advances it; a tick on
which it does not (its next cells were held) leaves it where it was, *waiting* on the AGV
that holds the cell (its blocker). A new committed plan starts at its own first state.

Numpy over the fleet, one pass per tick (a Python step per committed plan only).

>>> import numpy as np
>>> # A 1 x 3 corridor: AGV 0 goes 0 -> 1 -> 2; AGV 1 stands on 2 for a tick, then leaves.
>>> actual = np.array([[[0, 0], [1, 1], [1, 1], [2, 2]],
...                    [[2, 2], [2, 2], [5, 5], [5, 5]]]).transpose(1, 0, 2)
>>> plans = [(0, 0, [(0, 0), (1, 1), (2, 2)]), (1, 0, [(2, 2), (2, 2), (5, 5)])]
>>> out = grid_execution(actual, plans, np.array([1, 1]), cols=3)
>>> out["exec_state"][:, 0].tolist(), out["blocker"][:, 0].tolist()
([1, 3, 1, 6], [-1, 1, -1, -1])
>>> out["plan_tick"][:, 0].tolist()
[1, 1, 2, 2]
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from .recording import DRIVING, FAILED, FINISHED, STANDING, WAITING

__all__ = ["grid_execution", "state_array"]

FAILED_TASK_STATE = 7
"""``world.AgvState.FAILED``."""


def _occupant(anchor: np.ndarray, k: np.ndarray, cols: int, cells: int) -> np.ndarray:
    """Cell -> the AGV whose footprint (``k x k`` from its anchor) covers it (-1: none)."""
    occ = np.full(cells + 1, -1, dtype=np.int64)
    ids = np.arange(len(anchor))
    for size in np.unique(k).tolist():
        sel = k == size
        for dr in range(size):
            for dc in range(size):
                c = anchor[sel] + dr * cols + dc
                occ[np.clip(c, 0, cells)] = ids[sel]
    occ[cells] = -1
    return occ


def state_array(actual: dict[int, list], n: int, ticks: int) -> np.ndarray:
    """(ticks, n, 2) executed ``(from, to)`` states of ``actual`` (AGV -> states per tick;
    a short list held at its last state)."""
    out = np.zeros((ticks, n, 2), dtype=np.int64)
    for i in range(n):
        states = np.asarray(actual.get(i) or [(0, 0)], dtype=np.int64).reshape(-1, 2)[:ticks]
        out[:len(states), i] = states
        out[len(states):, i] = states[-1]
    return out


def grid_execution(actual: np.ndarray, plans: Iterable[tuple[int, int, Sequence]],
                   footprint: np.ndarray, cols: int, rows: int | None = None,
                   task_state: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """``exec_state``, ``blocker`` and ``plan_tick`` (T, N) of a grid execution.

    ``actual`` (T, N, 2): each AGV's executed state per tick (``(from, to)`` anchor nodes,
    ``row * cols + col``); ``plans``: committed plans ``(agv, start tick, states)`` (states
    as ``(from, to)`` pairs, state ``j`` planned at tick ``start + j``), in commit order;
    ``task_state`` (T, N): ``world.AgvState`` codes (7 = failed), None: never failed."""
    actual = np.asarray(actual, dtype=np.int64)
    ticks, n = actual.shape[:2]
    k = np.asarray(footprint, dtype=np.int64)
    rows = rows if rows is not None else int(actual.max(initial=0)) // cols + int(k.max(initial=1))
    cells = rows * cols
    by_tick: dict[int, list[tuple[int, np.ndarray]]] = {}
    for agv, start, states in plans:
        arr = np.asarray(states, dtype=np.int64).reshape(-1, 2)
        if len(arr) and 0 <= agv < n:
            by_tick.setdefault(int(start), []).append((int(agv), arr))
    width = max((len(a) for group in by_tick.values() for _, a in group), default=1)
    plan = np.zeros((n, width, 2), dtype=np.int64)
    length = np.zeros(n, dtype=np.int64)       # 0: no plan yet
    last_move = np.zeros(n, dtype=np.int64)    # index of the first state of the final run
    start = np.zeros(n, dtype=np.int64)
    p = np.zeros(n, dtype=np.int64)            # index of the plan state reached
    rows_n = np.arange(n)
    out = {"exec_state": np.full((ticks, n), STANDING, dtype=np.int8),
           "blocker": np.full((ticks, n), -1, dtype=np.int32),
           "plan_tick": np.full((ticks, n), -1, dtype=np.int32)}
    for t in range(ticks):
        for agv, arr in by_tick.get(t, ()):
            plan[agv, :len(arr)] = arr
            plan[agv, len(arr):] = arr[-1]
            length[agv], start[agv], p[agv] = len(arr), t, 0
            differs = np.flatnonzero((arr != arr[-1]).any(axis=1))
            last_move[agv] = differs[-1] + 1 if len(differs) else 0
        now = actual[t]
        nxt = actual[t + 1] if t + 1 < ticks else now
        has = length > 0
        want = plan[rows_n, np.minimum(p + 1, np.maximum(length - 1, 0))]
        moving = (now[:, 0] != now[:, 1]) | (nxt != now).any(axis=1)
        at_end = has & (p >= last_move)
        reached = has & (nxt == want).all(axis=1) & (p + 1 < length) & ~at_end
        stuck = has & ~moving & ~at_end & (want != now).any(axis=1)
        state = np.where(moving, DRIVING, np.where(stuck, WAITING,
                                                   np.where(at_end | ~has, FINISHED, STANDING)))
        if task_state is not None:
            state = np.where(np.asarray(task_state[t]) == FAILED_TASK_STATE, FAILED, state)
        out["exec_state"][t] = state
        waiting = np.flatnonzero(state == WAITING)
        if len(waiting):
            occ = _occupant(now[:, 0], k, cols, cells)
            # the first cell of the wanted anchor's footprint held by another AGV
            found = np.full(len(waiting), -1, dtype=np.int64)
            dst = want[waiting, 1]
            for dr in range(int(k[waiting].max())):
                for dc in range(int(k[waiting].max())):
                    inside = (dr < k[waiting]) & (dc < k[waiting])
                    c = np.where(inside, dst + dr * cols + dc, cells)
                    who = occ[np.clip(c, 0, cells)]
                    take = (found < 0) & (who >= 0) & (who != waiting)
                    found[take] = who[take]
            out["blocker"][t, waiting] = found
        p = p + reached
        out["plan_tick"][t] = np.where(has, start + p, -1)
    return out
