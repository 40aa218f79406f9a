"""Independent validator of timed paths and executed trajectories.

It shares no code with the planners: it rebuilds every AGV's occupied cells per tick from
scratch and reports

- ``bounds`` / ``obstacle``: a footprint cell outside the grid or on an obstacle;
- ``move``: a step that is not a wait or a move to a 4-neighbour, or a slow AGV's move that
  does not take exactly its ``ticks_per_move`` ticks;
- ``vertex``: two AGVs' occupied cells overlap at a tick (footprints included);
- ``swap``: two AGVs pass through each other between two ticks.

:func:`validate_headings` checks the headings of rotation-aware plans (``planner.rotations``):
``heading`` (not one of the four directions, or a heading list that does not match the
states), ``against_heading`` (a move whose direction is not the heading the AGV faces when
it starts, or that changes the heading while under way) and ``turn`` (a heading that changes
while moving, by more than a half turn, or sooner than the turn's ticks allow).

A state per tick is ``(a, b)`` of flat anchor indices (``row * cols + col``): standing at
``a`` if equal, else moving from ``a`` to ``b`` and covering both footprints. After its last
state an AGV stays where it is.

:func:`validate_dwells` checks an executed episode's dwells against its motion: for every
dwell in the events (``work_started`` .. ``work_done``: pick, hand-over, place; and the tick
of every ``parked``) the AGV's recorded pose is on the dwell's goal throughout: on the grid
the executed state stands on the goal cell at every tick of the dwell; in physics every
recorded sample in the dwell's time span is within ``pos_tol_m`` of the goal footprint's
centre and within ``heading_tol_rad`` of the heading it had when the dwell began.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import chain

import numpy as np

__all__ = ["Conflict", "DwellViolation", "validate_states", "validate_cell_paths",
           "validate_headings", "dwell_intervals",
           "validate_dwells", "DWELL_POS_TOL_M", "DWELL_HEADING_TOL_RAD"]

DWELL_POS_TOL_M = 0.05
"""Physics: how far (metres) a dwelling AGV's centre may be from its goal's centre."""
DWELL_HEADING_TOL_RAD = 0.05
"""Physics: how far (radians) a dwelling AGV's heading may turn during the dwell."""


@dataclass(frozen=True, slots=True)
class Conflict:
    kind: str
    tick: int
    agvs: tuple[int, ...]
    cell: tuple[int, int] | None = None

    def __str__(self) -> str:
        where = f" at {self.cell}" if self.cell is not None else ""
        return f"{self.kind} conflict at tick {self.tick} between AGVs {self.agvs}{where}"


def _cells(anchor: int, k: int, cols: int) -> set[tuple[int, int]]:
    r, c = divmod(anchor, cols)
    return {(r + i, c + j) for i in range(k) for j in range(k)}


def validate_states(trajectories: Mapping[int, Sequence[tuple[int, int]]],
                    obstacles: np.ndarray, *, sizes: Mapping[int, int] | None = None,
                    ticks_per_move: Mapping[int, int] | None = None, start_tick: int = 0,
                    max_conflicts: int = 100) -> list[Conflict]:
    """Check per-tick states of every AGV; return at most ``max_conflicts`` conflicts.

    Plans of 1x1 AGVs that stand on one cell per tick (one-shot MAPF plans, executed
    states) are checked over numpy arrays (:func:`_validate_cells`, the same conflicts in
    the same order); footprints, slow AGVs and moving states take the general path."""
    rows, cols = obstacles.shape
    sizes = sizes or {}
    speeds = ticks_per_move or {}
    if all(v == 1 for v in sizes.values()) and all(v == 1 for v in speeds.values()) and \
            trajectories and all(len(s) and all(a == b for a, b in s)
                                 for s in trajectories.values()):
        return _validate_cells(trajectories, obstacles, start_tick, max_conflicts)
    return _validate_general(trajectories, obstacles, sizes, speeds, start_tick, max_conflicts)


def _validate_general(trajectories: Mapping[int, Sequence[tuple[int, int]]],
                      obstacles: np.ndarray, sizes: Mapping[int, int],
                      speeds: Mapping[int, int], start_tick: int, max_conflicts: int,
                      ) -> list[Conflict]:
    """:func:`validate_states` for any footprints, speeds and states."""
    rows, cols = obstacles.shape
    horizon = max((len(s) for s in trajectories.values()), default=0)
    out: list[Conflict] = []

    def at(agv: int, i: int) -> tuple[int, int]:
        states = trajectories[agv]
        return tuple(states[min(i, len(states) - 1)])

    def occupied(agv: int, i: int) -> set[tuple[int, int]]:
        a, b = at(agv, i)
        k = sizes.get(agv, 1)
        return _cells(a, k, cols) | (_cells(b, k, cols) if a != b else set())

    for agv, states in trajectories.items():
        m = speeds.get(agv, 1)
        # Ticks spent in the current move; unknown if the window starts mid-move.
        transit: int | None = None if states and states[0][0] != states[0][1] else 0
        for i, (a, b) in enumerate(states):
            for r, c in _cells(a, sizes.get(agv, 1), cols) | _cells(b, sizes.get(agv, 1), cols):
                if not (0 <= r < rows and 0 <= c < cols):
                    out.append(Conflict("bounds", start_tick + i, (agv,), (r, c)))
                elif obstacles[r, c]:
                    out.append(Conflict("obstacle", start_tick + i, (agv,), (r, c)))
            if a != b:
                ra, ca = divmod(a, cols)
                rb, cb = divmod(b, cols)
                if abs(ra - rb) + abs(ca - cb) != 1:
                    out.append(Conflict("move", start_tick + i, (agv,), (rb, cb)))
            if i == 0:
                continue
            pa, pb = states[i - 1]
            if (pa, pb) == (a, b) and a != b:
                transit = None if transit is None else transit + 1
            elif pa == pb and a != b and a == pa:
                transit = 1
            elif pa != pb and a == b == pb:
                if transit is not None and transit != m - 1:
                    out.append(Conflict("move", start_tick + i, (agv,), divmod(b, cols)))
                transit = 0
            elif pa == pb and a == b:
                if a != pa:
                    ra, ca = divmod(a, cols)
                    rp, cp = divmod(pa, cols)
                    if abs(ra - rp) + abs(ca - cp) != 1 or m != 1:
                        out.append(Conflict("move", start_tick + i, (agv,), (ra, ca)))
            else:
                out.append(Conflict("move", start_tick + i, (agv,), divmod(b, cols)))
    ids = sorted(trajectories)
    for i in range(horizon):
        owner: dict[tuple[int, int], int] = {}
        for agv in ids:
            for cell in occupied(agv, i):
                other = owner.get(cell)
                if other is not None:
                    out.append(Conflict("vertex", start_tick + i, (other, agv), cell))
                else:
                    owner[cell] = agv
        if i == 0:
            continue
        moved = [agv for agv in ids if at(agv, i) != at(agv, i - 1)]
        before = {agv: occupied(agv, i - 1) for agv in moved}
        after = {agv: occupied(agv, i) for agv in moved}
        for x, p in enumerate(moved):
            for q in moved[x + 1:]:
                if after[p] & before[q] and after[q] & before[p] \
                        and not after[p] & after[q] and not before[p] & before[q]:
                    out.append(Conflict("swap", start_tick + i, (p, q)))
        if len(out) >= max_conflicts:
            break
    return out[:max_conflicts]


def validate_cell_paths(paths: Sequence[Sequence[tuple[int, int]]], obstacles: np.ndarray,
                        *, max_conflicts: int = 100) -> list[Conflict]:
    """:func:`validate_states` for one-shot MAPF plans given as cell paths: agent ``i``
    stands on ``paths[i][t]`` (row, column) at tick ``t`` (and on its last cell after it),
    1x1. The same conflicts in the same order as :func:`validate_states` on the states
    ``(cell, cell)``, without building them (what ``warerover solve`` checks its plans
    with)."""
    if not paths:
        return []
    rows, cols = obstacles.shape
    lengths = [len(p) for p in paths]
    if min(lengths) == 0:
        return validate_states({i: [(r * cols + c,) * 2 for r, c in p]
                                for i, p in enumerate(paths)}, obstacles,
                               max_conflicts=max_conflicts)
    horizon = max(lengths)
    flat = np.fromiter(chain.from_iterable(chain.from_iterable(paths)), dtype=np.int64,
                       count=2 * sum(lengths)).reshape(-1, 2)
    nodes = flat[:, 0] * cols + flat[:, 1]
    pos = np.empty((horizon, len(paths)), dtype=np.int64)
    at = 0
    for j, n in enumerate(lengths):
        pos[:n, j] = nodes[at:at + n]
        pos[n:, j] = nodes[at + n - 1]
        at += n
    return _check_cells(pos, lengths, list(range(len(paths))), obstacles, 0, max_conflicts)


def _validate_cells(trajectories: Mapping[int, Sequence[tuple[int, int]]],
                    obstacles: np.ndarray, start_tick: int, max_conflicts: int,
                    ) -> list[Conflict]:
    """:func:`validate_states` for 1x1 AGVs standing on one cell per tick, vectorised."""
    ids = sorted(trajectories)
    horizon = max(len(trajectories[a]) for a in ids)
    pos = np.empty((horizon, len(ids)), dtype=np.int64)
    for j, agv in enumerate(ids):
        cells = np.fromiter((a for a, _ in trajectories[agv]), dtype=np.int64)
        pos[:len(cells), j] = cells
        pos[len(cells):, j] = cells[-1]
    lengths = [len(trajectories[a]) for a in ids]
    return _check_cells(pos, lengths, ids, obstacles, start_tick, max_conflicts,
                        order=list(trajectories))


def _check_cells(pos: np.ndarray, lengths: list[int], ids: list[int], obstacles: np.ndarray,
                 start_tick: int, max_conflicts: int, order: list[int] | None = None,
                 ) -> list[Conflict]:
    """The checks of :func:`_validate_cells` on ``pos`` (ticks x agents: agent ``ids[j]``'s
    cell at each tick, its last one repeated past ``lengths[j]``); per-agent conflicts are
    listed in the agents' ``order`` (default ``ids``)."""
    rows, cols = obstacles.shape
    horizon = len(pos)
    r, c = np.divmod(pos, cols)
    per_agent: list[list[Conflict]] = [[] for _ in ids]  # bounds, obstacles, moves
    off = (pos < 0) | (r >= rows)
    blocked = np.zeros_like(off)
    blocked[~off] = obstacles[r[~off], c[~off]]
    step = np.zeros_like(off)
    step[1:] = (np.abs(r[1:] - r[:-1]) + np.abs(c[1:] - c[:-1])) > 1
    bad = np.nonzero((off | blocked | step).T)  # agent by agent, tick by tick
    for j, t in zip(*bad, strict=True):
        if t >= lengths[j]:
            continue  # past its last state (the same state again)
        cell = (int(r[t, j]), int(c[t, j]))
        if off[t, j]:
            per_agent[j].append(Conflict("bounds", start_tick + int(t), (ids[j],), cell))
        elif blocked[t, j]:
            per_agent[j].append(Conflict("obstacle", start_tick + int(t), (ids[j],), cell))
        if step[t, j]:
            per_agent[j].append(Conflict("move", start_tick + int(t), (ids[j],), cell))
    index = {agv: j for j, agv in enumerate(ids)}
    out = [x for agv in (order if order is not None else ids) for x in per_agent[index[agv]]]
    if not _any_vertex_or_swap(pos, rows * cols):
        return out[:max_conflicts]  # the loop below would add nothing
    for t in range(horizon):
        row = pos[t]
        order = np.argsort(row, kind="stable")
        srt = row[order]
        dup = np.flatnonzero(srt[1:] == srt[:-1]) + 1
        if len(dup):  # each cell's first AGV owns it; the others conflict with it
            first: dict[int, int] = {}
            pairs = []
            for k in dup.tolist():
                v = int(srt[k])
                owner = first.setdefault(v, int(order[k - 1]))
                pairs.append((int(order[k]), owner, v))
            for agent, owner, v in sorted(pairs):
                out.append(Conflict("vertex", start_tick + t, (ids[owner], ids[agent]),
                                    divmod(v, cols)))
        if t == 0:
            continue
        prev = pos[t - 1]
        moved = np.flatnonzero(row != prev)
        if len(moved) > 1:
            where: dict[tuple[int, int], list[int]] = {}
            src, dst = prev[moved].tolist(), row[moved].tolist()
            for a, u, v in zip(moved.tolist(), src, dst, strict=True):
                where.setdefault((u, v), []).append(a)
            pairs = sorted((a, b) for a, u, v in zip(moved.tolist(), src, dst, strict=True)
                           for b in where.get((v, u), ()) if a < b)
            for a, b in pairs:
                out.append(Conflict("swap", start_tick + t, (ids[a], ids[b])))
        if len(out) >= max_conflicts:
            break
    return out[:max_conflicts]


def _any_vertex_or_swap(pos: np.ndarray, cells: int) -> bool:
    """Whether the per-tick loop of :func:`_validate_cells` can find a vertex or swap
    conflict in ``pos`` (ticks x agents, cells ``0..cells-1``): two agents on one cell at a
    tick, or two that exchange cells between two ticks, over all ticks at once (a valid plan
    of 1,000 agents: ~0.02 s instead of the loop's ~0.2 s). True where it cannot tell
    (cells off the grid): the loop then decides, so the conflicts are the same."""
    if pos.size == 0:
        return False
    if int(pos.min()) < 0 or int(pos.max()) >= cells or len(pos) * cells * cells >= 1 << 62:
        return True
    ordered = np.sort(pos, axis=1)
    if bool(np.any(ordered[:, 1:] == ordered[:, :-1])):
        return True
    before, after = pos[:-1], pos[1:]
    moved = before != after
    if int(moved.sum()) < 2:
        return False
    tick = np.broadcast_to(np.arange(len(before), dtype=np.int64)[:, None], before.shape)[moved]
    u, v = before[moved], after[moved]
    forward = (tick * cells + u) * cells + v
    backward = (tick * cells + v) * cells + u
    return bool(np.isin(backward, forward).any())


@dataclass(frozen=True, slots=True)
class DwellViolation:
    """A dwell during which the AGV was not on its goal."""

    agv: int
    stage: str
    start_tick: int
    end_tick: int
    cell: tuple[int, int]
    """The dwell's goal (anchor cell)."""
    tick: float
    """When it was off (tick; fractional for physics samples)."""
    detail: str

    def __str__(self) -> str:
        return (f"AGV {self.agv} off its {self.stage} goal {self.cell} at tick {self.tick:g} "
                f"(dwell ticks {self.start_tick}-{self.end_tick}): {self.detail}")


def dwell_intervals(events: Sequence[Mapping], end_tick: int | None = None
                    ) -> list[tuple[int, str, int, int, tuple[int, int]]]:
    """Dwells in an episode's events: ``(agv, stage, start_tick, end_tick, cell)``.

    A work stage runs from its ``work_started`` to its ``work_done`` (a dwell still open at
    the end of the events runs to ``end_tick``, or is left out if that is None; an AGV that
    failed during it is left out from its failure on); a ``parked`` event is a dwell of one
    tick, stage ``park``."""
    out = []
    open_: dict[int, tuple[str, int, tuple[int, int]]] = {}
    for ev in events:
        name = ev.get("event")
        if name == "work_started":
            open_[ev["agv"]] = (ev["stage"], ev["tick"], tuple(ev["cell"]))
        elif name == "work_done" and ev["agv"] in open_:
            stage, t0, cell = open_.pop(ev["agv"])
            out.append((ev["agv"], stage, t0, ev["tick"], cell))
        elif name == "agv_failed" and ev["agv"] in open_:
            stage, t0, cell = open_.pop(ev["agv"])
            out.append((ev["agv"], stage, t0, ev["tick"], cell))
            # it resumes on repair without a new work_started: check from the repair on
            open_[ev["agv"]] = (stage, -1, cell)
        elif name == "agv_repaired" and ev["agv"] in open_:
            stage, _, cell = open_[ev["agv"]]
            open_[ev["agv"]] = (stage, ev["tick"], cell)
        elif name == "parked":
            out.append((ev["agv"], "park", ev["tick"], ev["tick"], tuple(ev["cell"])))
    if end_tick is not None:
        for agv, (stage, t0, cell) in open_.items():
            if t0 >= 0:
                out.append((agv, stage, t0, end_tick, cell))
    return sorted(out, key=lambda d: (d[2], d[0]))


def validate_dwells(events: Sequence[Mapping], cols: int, *,
                    actual: Mapping[int, Sequence[tuple[int, int]]] | None = None,
                    trajectory: Mapping | None = None,
                    pos_tol_m: float = DWELL_POS_TOL_M,
                    heading_tol_rad: float = DWELL_HEADING_TOL_RAD,
                    max_violations: int = 100) -> list[DwellViolation]:
    """Check that every dwell in ``events`` happened on its goal (see the module docstring).

    ``actual``: executed states per tick per AGV from tick 0 (``paths.json`` ``actual`` /
    ``EpisodeResult.actual``), checked on the grid; ``trajectory``: recorded poses
    (``trajectories.npz``: ``t``, ``x``, ``y``, ``heading``, ``footprint``, ``cell_m``,
    ``tick_s``), checked in physics. Give either or both."""
    out: list[DwellViolation] = []
    end = None
    if actual is not None:
        end = max((len(s) - 1 for s in actual.values()), default=0)
    dwells = dwell_intervals(events, end)
    if actual is not None:
        for agv, stage, t0, t1, cell in dwells:
            node = cell[0] * cols + cell[1]
            states = actual[agv]
            for t in range(t0, min(t1, len(states) - 1) + 1):
                if tuple(states[t]) != (node, node):
                    a, b = states[t]
                    out.append(DwellViolation(agv, stage, t0, t1, cell, t,
                                              f"state {divmod(a, cols)} -> {divmod(b, cols)}"))
                    break
    if trajectory is not None:
        ts = np.asarray(trajectory["t"], dtype=float)
        tick_s = float(np.asarray(trajectory["tick_s"]))
        cell_m = float(np.asarray(trajectory["cell_m"]))
        k = np.asarray(trajectory["footprint"])
        xs, ys, hs = (np.asarray(trajectory[key]) for key in ("x", "y", "heading"))
        eps = 1e-6 * tick_s
        for agv, stage, t0, t1, cell in dwells:
            lo = np.searchsorted(ts, t0 * tick_s - eps)
            hi = np.searchsorted(ts, t1 * tick_s + eps, side="right")
            if hi <= lo:
                continue
            size = int(k[agv]) * cell_m
            gx, gy = cell[1] * cell_m + size / 2, cell[0] * cell_m + size / 2
            off = np.hypot(xs[lo:hi, agv] - gx, ys[lo:hi, agv] - gy)
            turn = np.abs((hs[lo:hi, agv] - hs[lo, agv] + np.pi) % (2 * np.pi) - np.pi)
            bad = np.flatnonzero((off > pos_tol_m) | (turn > heading_tol_rad))
            if len(bad):
                j = int(bad[0])
                out.append(DwellViolation(
                    agv, stage, t0, t1, cell, float(ts[lo + j] / tick_s),
                    f"{off[j]:.3f} m from the goal centre, heading turned {turn[j]:.3f} rad"))
        if len(out) >= max_violations:
            return out[:max_violations]
    return out[:max_violations]


def validate_headings(trajectories: Mapping[int, Sequence[tuple[int, int]]],
                      headings: Mapping[int, Sequence[int]], cols: int, *,
                      turn_ticks: Mapping[int, tuple[int, int]], start_tick: int = 0,
                      max_conflicts: int = 100) -> list[Conflict]:
    """Check rotation-aware plans: per AGV of ``headings`` (direction index per state: 0
    east, 1 south, 2 west, 3 north; AGVs without headings are not checked) against its
    states (``(a, b)`` flat anchors per tick, as for :func:`validate_states`) and its
    ``turn_ticks`` ``(quarter, half)``. Returns at most ``max_conflicts`` conflicts:

    - ``heading``: a heading outside 0..3, or not one per state;
    - ``against_heading``: a move whose direction differs from the heading of the state it
      starts from or of any state it covers (an AGV moves only straight ahead);
    - ``turn``: a heading that changes by a half turn or less between two states standing
      on the same anchor sooner than ``quarter`` (or ``half``) ticks after the AGV came to
      stand there with its previous heading: the ``q`` states before the change must all
      stand on that anchor with the previous heading (a turn at the very start of the
      states may have begun before them, so only the states given are checked); or a
      heading that changes while moving.

    Moves that are not to a 4-neighbour are :func:`validate_states`'s to report; they are
    skipped here."""
    out: list[Conflict] = []
    for agv in sorted(headings):
        states, heads = trajectories.get(agv), headings[agv]
        if states is None:
            continue
        if len(heads) != len(states) or any(h not in (0, 1, 2, 3) for h in heads):
            out.append(Conflict("heading", start_tick, (agv,)))
            continue
        q1, q2 = turn_ticks.get(agv, (1, 2))

        def direction(u: int, v: int) -> int | None:
            ru, cu = divmod(u, cols)
            rv, cv = divmod(v, cols)
            return {(0, 1): 0, (1, 0): 1, (0, -1): 2, (-1, 0): 3}.get((rv - ru, cv - cu))

        for i in range(1, len(states)):
            (pa, pb), (a, b) = states[i - 1], states[i]
            h0, h1 = heads[i - 1], heads[i]
            t = start_tick + i
            if a != b:  # moving a -> b at state i
                d = direction(a, b)
                if d is None:
                    continue
                if h1 != d or ((pa, pb) == (a, a) and h0 != d):
                    out.append(Conflict("against_heading", t, (agv,), divmod(b, cols)))
                elif (pa, pb) == (a, b) and h0 != h1:
                    out.append(Conflict("turn", t, (agv,), divmod(b, cols)))
            elif pa != pb:  # arriving at b
                d = direction(pa, pb)
                if d is not None and h1 != d:
                    out.append(Conflict("turn", t, (agv,), divmod(b, cols)))
            elif pa != a:  # a one-tick move pa -> a
                d = direction(pa, a)
                if d is not None and (h0 != d or h1 != d):
                    out.append(Conflict("against_heading", t, (agv,), divmod(a, cols)))
            elif h0 != h1:  # a turn in place ends here
                n = min((h1 - h0) % 4, (h0 - h1) % 4)
                q = q1 if n == 1 else q2
                first = max(0, i - q)
                if any(states[j] != (a, a) or heads[j] != h0 for j in range(first, i)):
                    out.append(Conflict("turn", t, (agv,), divmod(a, cols)))
            if len(out) >= max_conflicts:
                return out[:max_conflicts]
    return out[:max_conflicts]
