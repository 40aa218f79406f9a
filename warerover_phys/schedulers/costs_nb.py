"""TA's options per AGV x SKU, compiled: the nearest candidate shelves and their best trips.

One pass over idle AGVs x (SKU, usable shelf) pairs, with no temporary as large as the
pairs: per AGV and SKU it keeps the ``keep`` shelves nearest by Manhattan distance (ties by
shelf id) in a small sorted buffer, then their trip lengths and the shortest.
Without numba the same function runs as Python (numba is a dependency; slow but the same).
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

__all__ = ["AVAILABLE", "best_trips"]


@njit(cache=True)
def best_trips(table, far, nodes, agv_r, agv_c, anchor_node, anchor_r,
               anchor_c, shelf, starts, ends, leg, keep, unreachable, rows, cols, best,
               opt_d, opt_s):  # pragma: no cover - compiled
    """For AGV ``i`` and SKU run ``g`` fill ``best[rows[i], cols[g]]`` (the shortest trip,
    ``unreachable`` where none) and, at ``[rows[i], cols[g], :keep]``, ``opt_d`` and
    ``opt_s``: its candidates' trips (``unreachable``: none, and from the count of
    candidates on) and shelves, in no order.

    Trip of AGV ``i`` with the shelf ``s`` of pair ``p``: ``table[nodes[i], s]`` (``far``:
    none) plus ``leg[p]``. Pairs ``starts[g]
    .. ends[g] - 1`` hold run ``g``'s shelves ``shelf[p]``.
    """
    big = anchor_node.shape[0]
    near = np.empty(keep, dtype=np.int64)
    near_key = np.empty(keep, dtype=np.int64)
    for i in range(nodes.shape[0]):
        node, r, c = nodes[i], agv_r[i], agv_c[i]
        for g in range(starts.shape[0]):
            # The ``keep`` nearest by (Manhattan distance, shelf id), insertion-sorted.
            nc = 0
            if ends[g] - starts[g] <= keep:  # every shelf of the run is a candidate
                for p in range(starts[g], ends[g]):
                    near[nc] = p
                    nc += 1
            else:
                nc = _nearest(shelf, anchor_r, anchor_c, starts[g], ends[g], r, c, big, keep,
                              near, near_key)
            # Their trips (unsorted: OptionTable.shelves sorts the few TA commits) and the
            # shortest.
            bd = unreachable
            bi, bj = rows[i], cols[g]
            for q in range(nc):
                s = shelf[near[q]]
                u = np.int64(table[node, s])
                if u == far:
                    u = unreachable
                d = min(u + leg[near[q]], unreachable)
                opt_d[bi, bj, q] = d
                opt_s[bi, bj, q] = s
                bd = min(bd, d)
            for q in range(nc, keep):
                opt_d[bi, bj, q] = unreachable
            best[bi, bj] = bd


@njit(cache=True)
def _nearest(shelf, anchor_r, anchor_c, start, end, r, c, big, keep, near,
             near_key):  # pragma: no cover - compiled
    """The ``keep`` pairs of ``start .. end - 1`` whose shelves are nearest to ``(r, c)`` by
    (Manhattan distance, shelf id), into ``near`` (insertion-sorted); returns the count."""
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
