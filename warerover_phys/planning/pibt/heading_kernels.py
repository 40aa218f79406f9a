"""Lifelong PIBT for robots with headings, compiled with numba: :func:`~.heading.heading_pibt_step`
(forward / turn / wait) and the ``turn-first`` rule (PIBT on cells, then turn to face the
move) over the flat arrays of :mod:`.kernels`, with the same results as the Python reference.

See :mod:`.kernels` for the array layout and the cache; :func:`warm_up` compiles these steps."""

from __future__ import annotations

import numpy as np

from .kernels import _UNR, AVAILABLE, StepTables, njit, robot_tables, step_tables

__all__ = ["heading_step_nb", "turn_first_nb", "warm_up"]


@njit(cache=True)
def _turns_at(d, v, h, nbr, deg, nbr_dir, turns):
    dv = np.int64(d[v])
    if dv == 0:
        return 0
    mask = 0
    for t in range(deg[v]):
        if np.int64(d[nbr[v, t]]) < dv:
            mask |= 1 << nbr_dir[v, t]
    return turns[mask, h]


@njit(cache=True)
def _escape(i, pusher, tables, nbr, deg, nbr_dir, occ_now, occ_next, tie, config, heading):
    here = config[i]
    d = tables[0][tables[1][i]]
    best = -1
    have = False
    key_a = False
    key_b = 0.0
    for t in range(deg[here]):
        u = nbr[here, t]
        if u == pusher or occ_next[u] >= 0 or np.int64(d[u]) >= _UNR:
            continue
        h = nbr_dir[here, t]
        if h == heading[i]:
            continue
        a = occ_now[u] >= 0
        b = float(np.int64(d[u])) + tie[u]
        if not have or (a < key_a) or (a == key_a and b < key_b):
            best = h
            key_a = a
            key_b = b
            have = True
    return best


@njit(cache=True)
def _hsetup(f, i, pusher, ag, pus, kinds, cells, heads, nopt, idx, tables, nbr, deg, nbr_dir,
            ahead_of, turns, escaping, tie, config, heading):
    """Frame ``f`` for robot ``i`` asked to move by the robot on cell ``pusher`` (-1: none):
    its options (forward if it can, then clockwise, counter-clockwise, wait), stably sorted
    by the reference's costs."""
    here = config[i]
    h = heading[i]
    d = tables[0][tables[1][i]]
    costs = np.empty(4, dtype=np.float64)
    m = 0
    ahead = ahead_of[here, h]
    if ahead >= 0 and np.int64(d[ahead]) < _UNR:
        cost = float(np.int64(d[ahead]) + _turns_at(d, ahead, h, nbr, deg, nbr_dir, turns))
        if escaping[i]:
            cost -= 4.0
        costs[0] = cost + 0.5 * tie[ahead]
        kinds[f, 0] = 70  # F
        cells[f, 0] = ahead
        heads[f, 0] = h
        m = 1
    base = float(np.int64(d[here]))
    hr = (h + 1) % 4
    hc = (h + 3) % 4
    for q in range(3):
        if q == 0:
            c = base + _turns_at(d, here, hr, nbr, deg, nbr_dir, turns) + 0.3
            kind, hh = 82, hr  # R
        elif q == 1:
            c = base + _turns_at(d, here, hc, nbr, deg, nbr_dir, turns) + 0.3
            kind, hh = 67, hc  # C
        else:
            c = base + _turns_at(d, here, h, nbr, deg, nbr_dir, turns) + 0.27
            kind, hh = 87, h  # W
        j = m
        while j > 0 and costs[j - 1] > c:
            costs[j] = costs[j - 1]
            kinds[f, j] = kinds[f, j - 1]
            cells[f, j] = cells[f, j - 1]
            heads[f, j] = heads[f, j - 1]
            j -= 1
        costs[j] = c
        kinds[f, j] = kind
        cells[f, j] = here
        heads[f, j] = hh
        m += 1
    ag[f] = i
    pus[f] = pusher
    nopt[f] = m
    idx[f] = 0


@njit(cache=True)
def _hpush(root, ag, pus, kinds, cells, heads, nopt, idx, tables, nbr, deg, nbr_dir, ahead_of,
           turns, occ_now, occ_next, nxt, nh, acts, escaping, escaped, tie, config, heading,
           instack, acyclic):
    """The reference's recursive ``push(root, -1)`` on an explicit stack (see ``_push``).

    A compiled kernel, long on purpose: the recursion of the reference step unrolled onto one
    explicit stack (numba compiles no recursion with this many array arguments well); its
    frames' branches follow the reference's order line by line, which is what keeps both
    steps' results the same."""
    f = 0
    _hsetup(0, root, -1, ag, pus, kinds, cells, heads, nopt, idx, tables, nbr, deg, nbr_dir,
            ahead_of, turns, escaping, tie, config, heading)
    instack[root] = True
    ret = False
    resume = False
    while f >= 0:
        i = ag[f]
        here = config[i]
        must_leave = pus[f] >= 0
        if resume:
            resume = False
            if ret:
                instack[i] = False
                f -= 1
                resume = True
                continue
            v = cells[f, idx[f]]
            if occ_next[v] == i:
                occ_next[v] = -1
            idx[f] += 1
        descended = False
        while idx[f] < nopt[f]:
            q = idx[f]
            act = kinds[f, q]
            v = cells[f, q]
            if act != 70:
                if must_leave or occ_next[here] >= 0:
                    idx[f] += 1
                    continue
                nxt[i] = here
                nh[i] = heads[f, q]
                acts[i] = act
                occ_next[here] = i
                ret = True
                descended = True
                break
            if occ_next[v] >= 0:
                idx[f] += 1
                continue
            k = occ_now[v]
            if k >= 0 and (nxt[k] == here or (acyclic and instack[k])):
                idx[f] += 1
                continue
            nxt[i] = v
            nh[i] = heads[f, q]
            acts[i] = 70
            occ_next[v] = i
            if k >= 0 and nxt[k] == -1:
                f += 1
                _hsetup(f, k, here, ag, pus, kinds, cells, heads, nopt, idx, tables, nbr, deg,
                        nbr_dir, ahead_of, turns, escaping, tie, config, heading)
                instack[k] = True
                break
            ret = True
            descended = True
            break
        else:
            # Nothing worked: stay; a robot asked to leave turns towards a way out.
            nxt[i] = here
            nh[i] = heading[i]
            acts[i] = 87
            occ_next[here] = i
            if must_leave:
                out = _escape(i, pus[f], tables, nbr, deg, nbr_dir, occ_now, occ_next, tie,
                              config, heading)
                if out >= 0:
                    hd = heading[i]
                    diff = (out - hd) % 4
                    if diff == 1 or diff == 2:
                        nh[i] = (hd + 1) % 4
                        acts[i] = 82
                    else:
                        nh[i] = (hd + 3) % 4
                        acts[i] = 67
                    escaped[i] = True
            ret = False
            instack[i] = False
            f -= 1
            resume = True
            continue
        if descended:  # answered: back to the parent
            instack[i] = False
            f -= 1
            resume = True
    return ret


@njit(cache=True)
def _heading_kernel(nbr, deg, nbr_dir, ahead_of, turns, config, heading, tables, order, tie,
                    escaping, held, acyclic):
    n = config.shape[0]
    cells = nbr.shape[0]
    occ_now = np.full(cells, -1, dtype=np.int64)
    occ_next = np.full(cells, -1, dtype=np.int64)
    nxt = np.full(n, -1, dtype=np.int64)
    nh = heading.copy()
    acts = np.full(n, 87, dtype=np.uint8)
    escaped = np.zeros(n, dtype=np.bool_)
    instack = np.zeros(n, dtype=np.bool_)
    ag = np.empty(n, dtype=np.int64)
    pus = np.empty(n, dtype=np.int64)
    kinds = np.empty((n, 4), dtype=np.int64)
    cells_ = np.empty((n, 4), dtype=np.int64)
    heads = np.empty((n, 4), dtype=np.int64)
    nopt = np.empty(n, dtype=np.int64)
    idx = np.empty(n, dtype=np.int64)
    for i in range(n):
        occ_now[config[i]] = i
    for i in range(n):  # held robots wait where they are
        if held[i]:
            nxt[i] = config[i]
            occ_next[config[i]] = i
    for r in range(n):
        i = order[r]
        if nxt[i] == -1:
            _hpush(i, ag, pus, kinds, cells_, heads, nopt, idx, tables, nbr, deg, nbr_dir,
                   ahead_of, turns, occ_now, occ_next, nxt, nh, acts, escaping, escaped, tie,
                   config, heading, instack, acyclic)
    return nxt, nh, acts, escaped


def heading_step_nb(st: StepTables, config: np.ndarray, heading: np.ndarray, tables,
                    order: np.ndarray, tie: np.ndarray, escaping: np.ndarray,
                    held: np.ndarray | None = None, acyclic: bool = False
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`~.pibt_heading.heading_pibt_step` compiled: next cells, next headings, actions
    (``uint8`` ASCII codes of ``F`` / ``R`` / ``C`` / ``W``) and the robots that turned to make
    way (a bool array: next timestep's ``escaping``). ``held``: robots that must wait."""
    config = np.asarray(config, dtype=np.int64)
    held = np.zeros(len(config), dtype=np.bool_) if held is None else \
        np.asarray(held, dtype=np.bool_)
    return _heading_kernel(st.nbr, st.deg, st.nbr_dir, st.ahead, st.turns, config,
                           np.asarray(heading, dtype=np.int64), tables,
                           np.asarray(order, dtype=np.int64), np.asarray(tie, dtype=np.float64),
                           np.asarray(escaping, dtype=np.bool_), held, bool(acyclic))


@njit(cache=True)
def _turn_first_kernel(config, nxt, heading, cols, cells):
    n = config.shape[0]
    out = nxt.copy()
    hd = heading.copy()
    acts = np.full(n, 87, dtype=np.uint8)  # W
    for i in range(n):
        if out[i] == config[i]:
            continue
        dr = out[i] // cols - config[i] // cols
        dc = out[i] % cols - config[i] % cols
        if dr == 0:
            want = 0 if dc == 1 else 2
        else:
            want = 1 if dr == 1 else 3
        if want != hd[i]:
            diff = (want - hd[i]) % 4
            if diff == 1 or diff == 2:
                acts[i] = 82  # R
                hd[i] = (hd[i] + 1) % 4
            else:
                acts[i] = 67  # C
                hd[i] = (hd[i] + 3) % 4
            out[i] = config[i]
    # Cascade: whoever enters a cell whose robot stays, stays.
    entering = np.full(cells, -1, dtype=np.int64)
    stack = np.empty(n, dtype=np.int64)
    top = 0
    for i in range(n):
        if out[i] != config[i]:
            entering[out[i]] = i
        else:
            stack[top] = i
            top += 1
    while top > 0:
        top -= 1
        i = stack[top]
        j = entering[config[i]]
        entering[config[i]] = -1
        if j >= 0 and out[j] != config[j]:
            out[j] = config[j]
            stack[top] = j
            top += 1
    for i in range(n):
        if out[i] != config[i] and acts[i] == 87:
            acts[i] = 70  # F
    return out, hd, acts


def turn_first_nb(config: np.ndarray, nxt: np.ndarray, heading: np.ndarray, cols: int,
                  cells: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`~.pibt_heading.turn_first` compiled: (cells, headings, action codes) of PIBT's next cells
    ``nxt`` under the rotation model."""
    return _turn_first_kernel(np.asarray(config, dtype=np.int64),
                              np.asarray(nxt, dtype=np.int64),
                              np.asarray(heading, dtype=np.int64), cols, cells)


def warm_up(dtype=np.uint16) -> None:
    """Compile (or load from numba's cache) the heading steps for tables of ``dtype`` on a
    1 x 3 corridor."""
    if not AVAILABLE:
        return
    st = step_tables([(1,), (0, 2), (1,)], 3)
    tabs = robot_tables([np.array([2, 1, 0], dtype=dtype)])
    one = np.zeros(1, dtype=np.int64)
    turn_first_nb(one, one + 1, one, 3, 3)
    heading_step_nb(st, one, one, tabs, one, np.zeros(3), np.zeros(1, dtype=bool))
