"""TA's options per AGV x SKU, compiled: the nearest candidate shelves and their trips.

One pass over idle AGVs x (SKU, usable shelf) pairs with no temporary as large as the pairs:
per AGV and SKU the ``keep`` shelves nearest by Manhattan distance (ties by shelf id) go
into a small sorted buffer, then their trip lengths are read and the shortest kept
(:func:`best_trips`). The ranked option shelves are wanted only for the pairs the matching
picks; :func:`ranked_options` computes them for those alone (at 5,000 AGVs x 800 SKUs,
keeping every pair's options would take 100 MB a call).
Without numba the same functions run as Python (numba is a dependency; slow but the same).
"""

from __future__ import annotations

import numpy as np

try:
    from numba import njit
    AVAILABLE = True
except ImportError:  # pragma: no cover - numba is a dependency; the Python loop remains
    AVAILABLE = False

    def njit(*args, **kwargs):  # type: ignore[no-redef]
        if args and callable(args[0]):
            return args[0]
        return lambda f: f

__all__ = ["AVAILABLE", "best_trips", "ranked_options"]


@njit(cache=True)
def best_trips(table, far, nodes, agv_r, agv_c, anchor_r, anchor_c, shelf, starts, ends,
               leg, keep, unreachable, rows, cols, best):  # pragma: no cover - compiled
    """``best[rows[i], cols[g]]``: the shortest trip of AGV ``i`` (standing on ``nodes[i]``,
    cell ``agv_r[i], agv_c[i]``) with one of the ``keep`` shelves of run ``g`` nearest to
    it, ``unreachable`` where none has a trip.

    Run ``g`` is pairs ``starts[g] .. ends[g] - 1``, pair ``p`` is shelf ``shelf[p]``; the
    trip with it is ``table[nodes[i], shelf[p]]`` (``far``: no way) plus ``leg[p]``. (The
    loops are written out here, not shared with :func:`ranked_options` through a helper:
    a compiled call per AGV and SKU doubles the time.)
    """
    near = np.empty(keep, dtype=np.int64)
    near_key = np.empty(keep, dtype=np.int64)
    for i in range(nodes.shape[0]):
        node, r, c = nodes[i], agv_r[i], agv_c[i]
        for g in range(starts.shape[0]):
            if ends[g] - starts[g] <= keep:  # every shelf of the run is a candidate
                nc = 0
                for p in range(starts[g], ends[g]):
                    near[nc] = p
                    nc += 1
            else:
                nc = _nearest(shelf, anchor_r, anchor_c, starts[g], ends[g], r, c, keep, near,
                              near_key)
            bd = unreachable
            for q in range(nc):
                u = np.int64(table[node, shelf[near[q]]])
                if u == far:
                    u = unreachable
                bd = min(bd, u + leg[near[q]])
            best[rows[i], cols[g]] = min(bd, unreachable)


@njit(cache=True)
def ranked_options(table, far, nodes, agv_r, agv_c, anchor_r, anchor_c, shelf, starts, ends,
                   leg, keep, unreachable, agv, run, out):  # pragma: no cover - compiled
    """For each ``(agv[m], run[m])`` (indices as in :func:`best_trips`): ``out[m]`` the
    candidate shelves with a trip, by (trip, shelf id), -1 after."""
    near = np.empty(keep, dtype=np.int64)
    near_key = np.empty(keep, dtype=np.int64)
    ranked = np.empty(keep, dtype=np.int64)
    for m in range(agv.shape[0]):
        i, g = agv[m], run[m]
        if ends[g] - starts[g] <= keep:
            nc = 0
            for p in range(starts[g], ends[g]):
                near[nc] = p
                nc += 1
        else:
            nc = _nearest(shelf, anchor_r, anchor_c, starts[g], ends[g], agv_r[i], agv_c[i],
                          keep, near, near_key)
        no = 0
        for q in range(nc):  # insertion by (trip, shelf id); no trip, no option
            u = np.int64(table[nodes[i], shelf[near[q]]])
            d = unreachable if u == far else min(u + leg[near[q]], unreachable)
            s = shelf[near[q]]
            if d >= unreachable:
                continue
            k = no
            no += 1
            while k > 0 and (ranked[k - 1] > d or (ranked[k - 1] == d and out[m, k - 1] > s)):
                ranked[k] = ranked[k - 1]
                out[m, k] = out[m, k - 1]
                k -= 1
            ranked[k] = d
            out[m, k] = s
        for q in range(no, keep):
            out[m, q] = -1


@njit(cache=True)
def _nearest(shelf, anchor_r, anchor_c, start, end, r, c, keep, near,
             near_key):  # pragma: no cover - compiled
    """The ``keep`` pairs of ``start .. end - 1`` whose shelves are nearest to ``(r, c)`` by
    (Manhattan distance, shelf id), into ``near`` (insertion-sorted); returns ``keep``."""
    big = anchor_r.shape[0]
    nc = 0
    for p in range(start, end):
        s = shelf[p]
        key = (abs(anchor_r[s] - r) + abs(anchor_c[s] - c)) * big + s
        if nc < keep:
            q = nc
            nc += 1
        elif key < near_key[keep - 1]:
            q = keep - 1
        else:
            continue
        while q > 0 and near_key[q - 1] > key:
            near_key[q] = near_key[q - 1]
            near[q] = near[q - 1]
            q -= 1
        near_key[q] = key
        near[q] = p
    return nc
