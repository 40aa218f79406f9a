"""LaCAM's configuration generator (:func:`~.pibt.pibt_step` with forced moves and guide
paths) compiled with numba: the same next configurations.

:func:`~.lacam.lacam_nodes` asks PIBT for one configuration per high-level iteration, with
the constraints of the low-level node as forced moves and (one-shot instances) the guide
paths of :mod:`.scatter`. :func:`step` runs that step as the compiled lifelong step of
:mod:`.pibt_numba` does (the same candidate sort, swaps and explicit push stack; its swap
functions are reused), with two additions: the forced moves are placed first and checked as
the reference checks them, and a robot's guide cell goes to the front of its candidates
before its swap partner is looked for, as in the reference. The high-level search stays in
Python (its generator draws are unchanged), so both give the same plans
(``tests/planning/test_scatter_numba.py``).

The guide paths are read from two sorted arrays: keys ``agent * cells + cell`` and the next
cell (:func:`guide_arrays`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..graph import UNREACHABLE as _UNR
from ..pibt.kernels import _dist, _swap_partner

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
def _guide_next(gkeys, gvals, key):
    lo = 0
    hi = gkeys.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if gkeys[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    if lo < gkeys.shape[0] and gkeys[lo] == key:
        return gvals[lo]
    return -1


@njit(cache=True)
def _setup(f, i, ag, cand, ncand, part, idx, tables, nbr, deg, occ_now, nxt, goal, tie,
           config, heading, cols, gkeys, gvals, cells):
    """``pibt_numba._setup`` with the guide cell moved to the front before the swap
    partner is looked for (as the reference's ``push``)."""
    here = config[i]
    keys = np.empty(5, dtype=np.float64)
    m = 0
    for t in range(deg[0, here] + 1):
        v = nbr[0, here, t] if t < deg[0, here] else here
        dv = _dist(tables, i, v, False, config, heading, cols)
        if t < deg[0, here] and dv >= _UNR:
            continue
        key = float(dv) + tie[v]
        j = m  # stable insertion: equal keys keep their order
        while j > 0 and keys[j - 1] > key:
            keys[j] = keys[j - 1]
            cand[f, j] = cand[f, j - 1]
            j -= 1
        keys[j] = key
        cand[f, j] = v
        m += 1
    if gkeys.shape[0] > 0:
        first = _guide_next(gkeys, gvals, i * cells + here)
        if first >= 0 and first != cand[f, 0]:
            at = -1
            for j in range(m):
                if cand[f, j] == first:
                    at = j
                    break
            if at > 0:
                for j in range(at, 0, -1):
                    cand[f, j] = cand[f, j - 1]
                cand[f, 0] = first
    partner = _swap_partner(i, cand[f, 0], tables, nbr, deg, occ_now, nxt, goal, False,
                            config, heading, cols)
    if partner >= 0:
        for j in range(m // 2):
            cand[f, j], cand[f, m - 1 - j] = cand[f, m - 1 - j], cand[f, j]
    ag[f] = i
    ncand[f] = m
    part[f] = partner
    idx[f] = 0


@njit(cache=True)
def _push(root, ag, cand, ncand, part, idx, tables, nbr, deg, occ_now, occ_next, nxt, goal,
          tie, config, heading, cols, gkeys, gvals, cells):
    """``pibt_numba._push`` (the reference's recursive push on an explicit stack)."""
    f = 0
    _setup(0, root, ag, cand, ncand, part, idx, tables, nbr, deg, occ_now, nxt, goal, tie,
           config, heading, cols, gkeys, gvals, cells)
    ret = False
    resume = False
    while f >= 0:
        i = ag[f]
        here = config[i]
        if resume:
            resume = False
            if ret:
                q = idx[f]
                partner = part[f]
                if q == 0 and partner >= 0 and nxt[partner] == -1 and occ_next[here] < 0:
                    nxt[partner] = here  # pull the partner along behind us
                    occ_next[here] = partner
                f -= 1
                resume = True
                continue
            idx[f] += 1
        descended = False
        while idx[f] < ncand[f]:
            q = idx[f]
            v = cand[f, q]
            if occ_next[v] >= 0:
                idx[f] += 1
                continue
            k = occ_now[v]
            if k >= 0 and k != i and nxt[k] == here:
                idx[f] += 1
                continue
            nxt[i] = v
            occ_next[v] = i
            if k >= 0 and k != i and nxt[k] == -1:
                f += 1
                _setup(f, k, ag, cand, ncand, part, idx, tables, nbr, deg, occ_now, nxt, goal,
                       tie, config, heading, cols, gkeys, gvals, cells)
                descended = True
                break
            partner = part[f]
            if q == 0 and partner >= 0 and nxt[partner] == -1 and occ_next[here] < 0:
                nxt[partner] = here
                occ_next[here] = partner
            ret = True
            f -= 1
            resume = True
            descended = True
            break
        if descended:
            continue
        nxt[i] = here
        occ_next[here] = i
        ret = False
        f -= 1
        resume = True
    return ret


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
    for r in range(n):
        i = order[r]
        if nxt[i] == -1:
            _push(i, ag, cand, ncand, part, idx, tables, nbr, deg, occ_now, occ_next, nxt, goal,
                  tie, config, heading, cols, gkeys, gvals, cells)
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
