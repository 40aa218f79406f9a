"""Conflicts between timed paths, as CBS sees them: vertex, edge-swap, following and turn-sweep
conflicts of one pair of AGVs, the first of them in time, and whether a path fits a request."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from ..base import (
    AgentRequest,
    State,
    TimedPath,
    occupancy,
)
from ..reservation import ReservationTable
from ..sweep import Sweep, lock_keys, sweep_cells, turn_aware, turn_sweeps
from .frontier import swaps
from .turning_astar import turn_ok


@dataclass(frozen=True, slots=True)
class PairConflict:
    """A conflict between two planned agents (indices into the CBS agent list).

    ``kind`` is ``"vertex"`` (``cell`` is a shared cell at ``tick``), ``"target"`` (agent
    ``i`` is on ``cell`` of agent ``j``'s goal at ``tick``, while ``j`` already rests there)
    or ``"swap"`` (``moves`` holds each agent's state transition into ``tick``). Turn-aware
    agents add ``"sweep"`` (agent ``i``'s turn at anchor ``turn[0]`` at tick ``turn[1]``
    sweeps ``cell``, which agent ``j`` holds at ``tick``, the turn's tick or the next; when
    ``j`` holds it by a turn of its own, ``turn_j`` names that turn) and ``"lock"`` (the
    turns ``turn`` of ``i`` and ``turn_j`` of ``j`` at one tick share a turn lock).
    """

    kind: str
    tick: int
    i: int
    j: int
    cell: int = -1
    moves: tuple[tuple[State, State], tuple[State, State]] | None = None
    turn: tuple[int, int] | None = None
    turn_j: tuple[int, int] | None = None


def find_conflicts(paths: Sequence[TimedPath], sizes: Sequence[int], cols: int, t0: int,
                   t_end: int, limit: int = 1, turns: Sequence[AgentRequest] | None = None,
                   rows: int | None = None) -> tuple[list[PairConflict], int]:
    """The earliest ``limit`` conflicts among ``paths`` at ticks ``t0 .. t_end`` (at most one
    per pair and tick; each path rests at its end), and how many there are in all (cells
    shared plus swaps: a tie-breaker, not an exact figure). With ``turns`` (the agents of
    the paths, for their headings and sweeps) sweep and lock conflicts count too."""
    found, count = _cell_conflicts(paths, sizes, cols, t0, t_end, limit)
    if turns is None or not any(turn_aware(a) for a in turns):
        return found, count
    more, n = _turn_conflicts(paths, sizes, cols, rows, t0, t_end, turns)
    if not more:
        return found, count
    merged = sorted(found + more, key=lambda c: (c.tick, min(c.i, c.j), max(c.i, c.j)))
    return merged[:limit], count + n


def _turn_conflicts(paths: Sequence[TimedPath], sizes: Sequence[int], cols: int,
                    rows: int | None, t0: int, t_end: int, agents: Sequence[AgentRequest],
                    ) -> tuple[list[PairConflict], int]:
    """Sweep and lock conflicts among the planned agents (see :class:`PairConflict`)."""
    t_end = min(t_end, max((p.end_tick for p in paths), default=t0))
    nrows = rows if rows is not None else 1 << 30
    # Per agent: tick -> [(anchor, turn tick, swept cells)], and turn tick -> (anchor, locks).
    swept: list[dict[int, list[tuple[int, int, frozenset[int]]]]] = []
    locks: list[dict[int, tuple[int, frozenset[int]]]] = []
    for p, a in zip(paths, agents, strict=True):
        sw: Sweep | None = a.sweep
        by_tick: dict[int, list[tuple[int, int, frozenset[int]]]] = {}
        by_lock: dict[int, tuple[int, frozenset[int]]] = {}
        if sw is not None and (sw.cells or sw.locks):
            for i, anchor in turn_sweeps(p.states, cols, a.heading):
                t = p.start_tick + i
                if sw.cells:
                    cells = frozenset(sweep_cells(anchor, sw.cells, nrows, cols))
                    for tt in (t, t + 1):
                        by_tick.setdefault(tt, []).append((anchor, t, cells))
                if sw.locks:
                    by_lock[t] = (anchor, frozenset(lock_keys(anchor, sw.locks, rows, cols)))
        swept.append(by_tick)
        locks.append(by_lock)
    out: list[PairConflict] = []
    seen: set[tuple[int, int, int]] = set()
    n = len(paths)
    for i in range(n):
        for tt, turns_i in sorted(swept[i].items()):
            if not t0 <= tt <= t_end:
                continue
            for j in range(n):
                if j == i:
                    continue
                held = set(occupancy(paths[j].state_at(tt), sizes[j], cols))
                theirs = {c: (anc, t) for anc, t, cells in swept[j].get(tt, ())
                          for c in cells}
                for anchor, t, cells in turns_i:
                    hit = sorted(cells & held) or sorted(cells & theirs.keys())
                    if hit and (tt, i, j) not in seen:
                        seen.add((tt, i, j))
                        c = hit[0]
                        out.append(PairConflict("sweep", tt, i, j, cell=c, turn=(anchor, t),
                                                turn_j=None if c in held else theirs[c]))
        for t, (anchor, keys) in sorted(locks[i].items()):
            if not t0 <= t <= t_end:
                continue
            for j in range(i + 1, n):
                other = locks[j].get(t)
                if other is not None and not keys.isdisjoint(other[1]):
                    out.append(PairConflict("lock", t, i, j, turn=(anchor, t),
                                            turn_j=(other[0], t)))
    return out, len(out)


def _cell_conflicts(paths: Sequence[TimedPath], sizes: Sequence[int], cols: int, t0: int,
                    t_end: int, limit: int = 1) -> tuple[list[PairConflict], int]:
    n = len(paths)
    t_end = min(t_end, max((p.end_tick for p in paths), default=t0))
    found: list[PairConflict] = []
    seen: set[tuple[int, int, int]] = set()
    count = 0

    def add(conflict: PairConflict) -> None:
        key = (conflict.tick, min(conflict.i, conflict.j), max(conflict.i, conflict.j))
        if len(found) < limit and key not in seen:
            seen.add(key)
            found.append(conflict)

    prev_owner: dict[int, int] = {}
    prev_occ: list[tuple[int, ...]] = []
    prev_state: list[State] = []
    for t in range(t0, t_end + 1):
        states = [p.state_at(t) for p in paths]
        occ_t = [occupancy(s, sizes[i], cols) for i, s in enumerate(states)]
        owner: dict[int, int] = {}
        for i in range(n):
            for c in occ_t[i]:
                o = owner.get(c)
                if o is None:
                    owner[c] = i
                    continue
                count += 1
                o_rests, i_rests = t >= paths[o].end_tick, t >= paths[i].end_tick
                if o_rests and not i_rests:
                    add(PairConflict("target", t, i, o, cell=c))
                elif i_rests and not o_rests:
                    add(PairConflict("target", t, o, i, cell=c))
                else:
                    add(PairConflict("vertex", t, o, i, cell=c))
        if t > t0:
            moved = [states[i] != prev_state[i] for i in range(n)]
            for p in range(n):
                if not moved[p]:
                    continue
                after_p, before_p = set(occ_t[p]), set(prev_occ[p])
                for q in sorted({prev_owner.get(c, -1) for c in after_p}):
                    if q <= p or not moved[q]:
                        continue
                    after_q, before_q = set(occ_t[q]), set(prev_occ[q])
                    if after_q & before_p and not after_p & after_q \
                            and not before_p & before_q:
                        count += 1
                        add(PairConflict("swap", t, p, q, moves=(
                            (prev_state[p], states[p]), (prev_state[q], states[q]))))
        prev_owner, prev_occ, prev_state = owner, occ_t, states
    return found, count


def path_fits(res: ReservationTable, path: TimedPath, k: int,
              agent: AgentRequest | None = None) -> bool:
    """Does ``path`` (footprint ``k``) fit the committed paths of ``res`` for good: no shared
    cell at any tick, no swap, and no other AGV on its goal after it arrives? With a
    turn-aware ``agent``, also every turn: allowed where it turns, swept cells and turn
    locks free (:func:`~warerover_phys.planning.search.turning_astar.turn_ok`)."""
    cols, me = res.cols, path.agv
    if agent is not None and turn_aware(agent):
        rows = res.rows if res.rows is not None else 1 << 30
        for i, anchor in turn_sweeps(path.states, cols, agent.heading):
            if not turn_ok(res, agent, anchor, path.start_tick + i, rows, cols):
                return False
    prev: tuple[int, ...] | None = None
    for i, state in enumerate(path.states):
        t = path.start_tick + i
        cells = occupancy(state, k, cols)
        if not all(res.free(c, t, me) for c in cells):
            return False
        if prev is not None and state != path.states[i - 1] \
                and swaps(res, prev, cells, t - 1, me):
            return False
        prev = cells
    return all(res.last_use(c, me) < path.end_tick
               for c in occupancy(path.states[-1], k, cols))
