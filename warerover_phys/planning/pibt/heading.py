"""One PIBT step for 1x1 robots that face one of four headings (the League of Robot Runners
``MAPF_T`` action model): each timestep a robot moves one cell *forward*, turns a quarter in
place (clockwise or counter-clockwise) or waits.

PIBT (Okumura et al., AIJ 2022) over the robots' actions instead of their cells. Robots are
taken in priority order; a robot ranks its four actions by the cost-to-go of the state
(cell, heading) each leads to,

    cost(v, h) = dist(v) + turns(v, h),

``dist`` the robot's distance table to its goal (moves, any heading) and ``turns(v, h)`` the
fewest quarter turns from ``h`` to a heading that points at a neighbour one move closer to
the goal (0 on the goal); between equal costs it prefers moving forward, then waiting, then
turning (so a robot on its goal does not spin). It takes the best action whose cell is free
next timestep: moving
forward reserves the cell ahead (and asks the robot standing there, if it has not chosen yet,
to move away first, by priority inheritance: that robot may only move forward, since turning
or waiting keeps it on the wanted cell); a turn or a wait keeps the robot's own cell. A robot
asked to move away that cannot stays, and its asker tries its next action. Two robots never
swap cells (a forward move into the cell of a robot moving into ours is skipped).

Compared with planning on cells and turning afterwards ("turn first, and whoever was to enter
the cell of a robot that turns waits too"), the ranking already knows which moves need turns,
so robots keep moving straight where they can, and a robot that has to turn does not
hold up the robots behind it in the same timestep by surprise.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..graph import UNREACHABLE as _UNREACHABLE
from .reference import in_priority_order

__all__ = ["STEP", "heading_pibt_step", "turns_to_progress", "Facing", "turn_first"]

STEP = ((0, 1), (1, 0), (0, -1), (-1, 0))
"""Headings 0-3: east (+col), south (+row), west (-col), north (-row)."""



def turns_to_progress(d: np.ndarray, v: int, h: int, neighbors: Sequence[Sequence[int]],
                      cols: int) -> int:
    """Fewest quarter turns from heading ``h`` at cell ``v`` to face a neighbour closer to
    the goal of distance table ``d`` (0 on the goal; 2 if no neighbour is closer).

    >>> d = np.array([1, 0, 1])  # a 1x3 corridor, goal in the middle
    >>> turns_to_progress(d, 0, 0, [(1,), (0, 2), (1,)], 3), turns_to_progress(d, 2, 0, [(1,), (0, 2), (1,)], 3)
    (0, 2)
    """
    dv = d[v]
    if dv == 0:
        return 0
    best = 2
    r, c = divmod(v, cols)
    for u in neighbors[v]:
        if d[u] < dv:
            want = STEP.index((u // cols - r, u % cols - c))
            t = (want - h) % 4
            t = min(t, 4 - t)
            if t < best:
                best = t
                if t == 0:
                    break
    return best


def _turns_by_mask() -> tuple[tuple[int, int, int, int], ...]:
    """``out[mask][h]``: fewest quarter turns from heading ``h`` to one of the headings in
    bit set ``mask`` (2 when it is empty), as :func:`turns_to_progress` counts them."""
    out = []
    for mask in range(16):
        row = []
        for h in range(4):
            best = 2
            for w in range(4):
                if mask >> w & 1:
                    t = (w - h) % 4
                    best = min(best, t, 4 - t)
            row.append(best)
        out.append(tuple(row))
    return tuple(out)


_TURNS = _turns_by_mask()
_ON_GOAL = (0, 0, 0, 0)


def steps_of(neighbors: Sequence[Sequence[int]], cols: int
             ) -> tuple[list[tuple[tuple[int, int], ...]], list[tuple[int, int, int, int]]]:
    """Per cell, its neighbours with the heading pointing at each (``(u, bit)``, bit
    ``1 << heading``), and the cell ahead for each heading (-1: none). Computed once per
    map and passed to :func:`heading_pibt_step` (``steps``) to save it every timestep."""
    nbr: list[tuple[tuple[int, int], ...]] = []
    ahead: list[tuple[int, int, int, int]] = []
    for v, near in enumerate(neighbors):
        r, c = divmod(v, cols)
        pairs = []
        row = [-1, -1, -1, -1]
        for u in near:
            h = STEP.index((u // cols - r, u % cols - c))
            pairs.append((u, 1 << h))
            row[h] = u
        nbr.append(tuple(pairs))
        ahead.append(tuple(row))  # type: ignore[arg-type]
    return nbr, ahead


def _turn_towards(h: int, want: int) -> int:
    """The heading after one quarter turn from ``h`` towards ``want`` (clockwise when it is
    behind)."""
    return (h + 1) % 4 if (want - h) % 4 in (1, 2) else (h - 1) % 4


def heading_pibt_step(neighbors: Sequence[Sequence[int]], cols: int, config: Sequence[int],
                      heading: Sequence[int], dists: Sequence[np.ndarray],
                      prio: Sequence[float], tie: np.ndarray,
                      escaping: frozenset[int] = frozenset(),
                      steps: tuple[list, list] | None = None, acyclic: bool = False,
                      ) -> tuple[list[int], list[int], list[str], frozenset[int]]:
    """Next cells, next headings and actions (``F`` forward, ``R`` clockwise, ``C``
    counter-clockwise, ``W`` wait) of every robot; see the module docstring.

    ``neighbors[v]``: the free 4-neighbours of cell ``v`` (linear ``row * cols + col``);
    ``dists[i]``: robot ``i``'s distance table (moves to its goal per cell); ``prio``:
    higher goes first; ``tie[v]``: in [0, 1), breaks ties between equally good forward moves.
    ``escaping``: the robots that turned last timestep to make way for another (the last
    return value): they move on forward if they can, rather than turn straight back.
    ``steps``: :func:`steps_of` of ``neighbors`` (computed here when not given).
    """
    n = len(config)
    nxt = [-1] * n
    nh = list(heading)
    acts = ["W"] * n
    occ_now = {v: i for i, v in enumerate(config)}
    occ_next: dict[int, int] = {}
    escaped: set[int] = set()

    nbr_of, ahead_of = steps if steps is not None else steps_of(neighbors, cols)

    def options(i: int) -> list[tuple[float, str, int, int]]:
        return _options(config[i], heading[i], dists[i], i in escaping, tie, nbr_of, ahead_of)

    active: set[int] = set()

    def push(i: int, pusher: int) -> bool:
        active.add(i)
        try:
            return choose(i, pusher)
        finally:
            active.discard(i)

    def choose(i: int, pusher: int) -> bool:
        """Choose robot ``i``'s action; ``pusher``: the cell of the robot that wants ``i``'s
        cell (-1: none), so ``i`` must move forward or fail. ``acyclic``: never into the
        cell of a robot still deciding (the robots pushing, up the chain): that would close
        a cycle of moves."""
        here = config[i]
        must_leave = pusher >= 0
        for _, act, v, h in options(i):
            if act != "F":
                if must_leave or here in occ_next:
                    continue
                nxt[i], nh[i], acts[i] = here, h, act
                occ_next[here] = i
                return True
            if v in occ_next:
                continue
            k = occ_now.get(v)
            if k is not None and (nxt[k] == here or (acyclic and k in active)):
                continue  # would swap cells with a robot moving into ours, or close a cycle
            nxt[i], nh[i], acts[i] = v, h, "F"
            occ_next[v] = i
            if k is not None and nxt[k] == -1 and not push(k, here):
                if occ_next.get(v) == i:
                    del occ_next[v]
                continue
            return True
        # Nothing worked: stay. A robot asked to leave turns towards the best way out
        # instead of waiting, so that it can leave next timestep (else two robots that face
        # each other would wait for each other for ever).
        nxt[i], nh[i], acts[i] = here, heading[i], "W"
        occ_next[here] = i
        if must_leave:
            out = _escape(config[i], heading[i], dists[i], pusher, neighbors, cols, occ_now,
                          occ_next, tie)
            if out >= 0:
                nh[i] = _turn_towards(heading[i], out)
                acts[i] = "R" if (out - heading[i]) % 4 in (1, 2) else "C"
                escaped.add(i)
        return False

    in_priority_order(prio, nxt, push)
    return nxt, nh, acts, frozenset(escaped)


def _turns_at(d, v: int, nbr_of) -> tuple[int, int, int, int]:
    """:func:`turns_to_progress` of cell ``v`` for each of the four headings."""
    dv = d[v]
    if dv == 0:
        return _ON_GOAL
    mask = 0
    for u, bit in nbr_of[v]:
        if d[u] < dv:
            mask |= bit
    return _TURNS[mask]


def _options(v: int, h: int, d, escaping: bool, tie: np.ndarray, nbr_of, ahead_of,
             ) -> list[tuple[float, str, int, int]]:
    """For :func:`heading_pibt_step`: a robot's actions at cell ``v`` facing ``h``
    (distance table ``d``), best first: (cost, action, next cell, next heading)."""
    out: list[tuple[float, str, int, int]] = []
    ahead = ahead_of[v][h]
    if ahead >= 0 and d[ahead] < _UNREACHABLE:
        cost = float(int(d[ahead]) + _turns_at(d, ahead, nbr_of)[h])
        if escaping:
            cost -= 4.0
        out.append((cost + 0.5 * float(tie[ahead]), "F", ahead, h))
    base = float(d[v])
    here_turns = _turns_at(d, v, nbr_of)
    hr, hc = (h + 1) % 4, (h - 1) % 4
    out.append((base + here_turns[hr] + 0.3, "R", v, hr))
    out.append((base + here_turns[hc] + 0.3, "C", v, hc))
    out.append((base + here_turns[h] + 0.27, "W", v, h))
    out.sort(key=lambda o: o[0])
    return out


def _escape(here: int, heading: int, d, pusher: int, neighbors: Sequence[Sequence[int]],
            cols: int, occ_now: dict[int, int], occ_next: dict[int, int], tie: np.ndarray,
            ) -> int:
    """For :func:`heading_pibt_step`: the heading of the best cell for a robot at ``here``
    facing ``heading`` to move away into (-1: none): not the pusher's cell, free next
    timestep, free now if possible, nearest its goal."""
    r, c = divmod(here, cols)
    best, key = -1, None
    for u in neighbors[here]:
        if u == pusher or u in occ_next or d[u] >= _UNREACHABLE:
            continue
        h = STEP.index((u // cols - r, u % cols - c))
        if h == heading:
            continue  # facing it already, and moving there failed
        kk = (u in occ_now, int(d[u]) + float(tie[u]))
        if key is None or kk < key:
            best, key = h, kk
    return best


# ------------------------------------------------------------------------- the turn-first rule


class Facing:
    """The ``turn-first`` rule's costs: a robot's distances to its goal plus, for the cells
    next to it, the quarter turns it needs to face them (PIBT then prefers going on
    straight ahead). Keyed ``(row + dr) * cols + col + dc``, which wraps at the map's side
    columns (kept: the compiled step, :func:`~.pibt_numba.pibt_step_nb` with ``heading``,
    reads the same)."""

    __slots__ = ("d", "here", "extra")

    def __init__(self, d, here: int, heading: int, cols: int) -> None:
        self.d = d
        self.here = here
        r, c = divmod(here, cols)
        self.extra = {}
        for h, (dr, dc) in enumerate(STEP):
            turns = (h - heading) % 4
            self.extra[(r + dr) * cols + c + dc] = min(turns, 4 - turns)

    def __getitem__(self, v: int) -> int:
        return int(self.d[v]) + self.extra.get(v, 0)


def turn_first(config: list[int], nxt: list[int], heading: list[int], acts: list[str],
               cols: int) -> list[int]:
    """PIBT's cells under the rotation model: a robot moves only forward; one whose cell lies
    in another direction turns towards it and stays, and whoever was to enter the cell of a
    robot that stays, stays too. Updates ``heading`` and ``acts``; returns the cells."""
    n = len(config)
    out = list(nxt)
    for i in range(n):
        if out[i] == config[i]:
            continue
        dr = out[i] // cols - config[i] // cols
        dc = out[i] % cols - config[i] % cols
        want = STEP.index((dr, dc))
        if want != heading[i]:
            diff = (want - heading[i]) % 4
            acts[i] = "R" if diff in (1, 2) else "C"
            heading[i] = (heading[i] + (1 if acts[i] == "R" else -1)) % 4
            out[i] = config[i]
    # Cascade: whoever enters a cell whose robot stays, stays.
    stack = [i for i in range(n) if out[i] == config[i]]
    entering: dict[int, int] = {out[i]: i for i in range(n) if out[i] != config[i]}
    while stack:
        i = stack.pop()
        j = entering.pop(config[i], None)
        if j is not None and out[j] != config[j]:
            out[j] = config[j]
            stack.append(j)
    for i in range(n):
        if out[i] != config[i] and acts[i] == "W":
            acts[i] = "F"
    return out
