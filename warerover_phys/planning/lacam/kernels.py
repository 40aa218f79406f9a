"""LaCAM's configuration generator (:func:`~.pibt.pibt_step` with forced moves and guide
paths) compiled with numba: the same next configurations.

:func:`~.lacam.lacam_nodes` asks PIBT for one configuration per high-level iteration, with
the constraints of the low-level node as forced moves and (one-shot instances) the guide
paths of :mod:`.scatter`. :func:`step` runs that step with the compiled lifelong step's push
(:func:`~warerover_phys.planning.pibt.kernels._push`: the same candidate sort, swaps and
explicit push stack), with two additions: the forced moves are placed first and checked as
the reference checks them, and a robot's guide cell goes to the front of its candidates
before its swap partner is looked for, as in the reference (the push's guide arguments). The high-level search stays in
Python (its generator draws are unchanged), so both give the same plans
(``tests/planning/test_scatter_numba.py``).

The guide paths are read from two sorted arrays: keys ``agent * cells + cell`` and the next
cell (:func:`guide_arrays`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

# the push is the lifelong step's (with guide paths); _guide_next lived here before
from ..pibt.kernels import _guide_next, _push  # noqa: F401

__all__ = ["guide_arrays", "step"]


def guide_arrays(guide: Sequence[dict[int, int]] | None, cells: int,
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Per agent the next cell of its guide path from each cell on it, as sorted keys
    ``agent * cells + cell`` and their next cells (empty without a guide)."""
    if not guide:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    sizes = [len(d) for d in guide]
    total = sum(sizes)
    keys = np.fromiter((k for d in guide for k in d), dtype=np.int64, count=total)
    vals = np.fromiter((v for d in guide for v in d.values()), dtype=np.int64, count=total)
    keys += np.repeat(np.arange(len(guide), dtype=np.int64) * cells, sizes)
    order = np.argsort(keys, kind="stable")
    return keys[order], vals[order]


@njit(cache=True)
def _step(nbr, deg, config, goal, tables, order, tie, forced_who, forced_where, gkeys, gvals,
          cols):
    n = config.shape[0]
    cells = nbr.shape[1]
    occ_now = np.full(cells, -1, dtype=np.int64)
    occ_next = np.full(cells, -1, dtype=np.int64)
    nxt = np.full(n, -1, dtype=np.int64)
    heading = np.zeros(1, dtype=np.int64)
    for i in range(n):
        occ_now[config[i]] = i
    for f in range(forced_who.shape[0]):
        i = forced_who[f]
        v = forced_where[f]
        here = config[i]
        if occ_next[v] >= 0:
            return nxt, False
        if v != here:
            near = False
            for t in range(deg[0, here]):
                if nbr[0, here, t] == v:
                    near = True
            if not near:
                return nxt, False
        k = occ_now[v]
        if k >= 0 and k != i and nxt[k] == here:
            return nxt, False  # swap between two forced moves
        nxt[i] = v
        occ_next[v] = i
    ag = np.empty(n, dtype=np.int64)
    cand = np.empty((n, 5), dtype=np.int64)
    ncand = np.empty(n, dtype=np.int64)
    part = np.empty(n, dtype=np.int64)
    idx = np.empty(n, dtype=np.int64)
    instack = np.zeros(n, dtype=np.bool_)
    for r in range(n):
        i = order[r]
        if nxt[i] == -1:  # the lifelong step's push (no facing, cycles allowed), guided
            _push(i, ag, cand, ncand, part, idx, tables, nbr, deg, occ_now, occ_next, nxt, goal,
                  tie, False, config, heading, cols, instack, False, gkeys, gvals, cells)
    taken = 0
    for v in range(cells):
        if occ_next[v] >= 0:
            taken += 1
    return nxt, taken == n  # else a forced move left two agents on one cell


def step(nbr: np.ndarray, deg: np.ndarray, config: np.ndarray, goal: np.ndarray, tables,
         order: np.ndarray, tie: np.ndarray, forced_who: np.ndarray, forced_where: np.ndarray,
         gkeys: np.ndarray, gvals: np.ndarray, cols: int) -> np.ndarray | None:
    """:func:`~.pibt.pibt_step` (``goals=goal``, swaps on, ``forced`` as the two arrays,
    ``guide`` as :func:`guide_arrays`) compiled; ``tables``: :func:`.pibt_numba.robot_tables`,
    ``order``: :func:`.pibt_numba.priority_order`, ``tie``: float64 per cell. None where the
    reference returns None."""
    # the PIBT kernels read graphs by index (robots may move on graphs of their own): here
    # every robot moves on the one graph
    one = (tables[0], tables[1], np.zeros(len(config), dtype=np.int64))
    nxt, ok = _step(nbr[None], deg[None], config, goal, one, order, tie, forced_who,
                    forced_where, gkeys, gvals, cols)
    return nxt if ok else None
