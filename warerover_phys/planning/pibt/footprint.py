"""Footprint-aware PIBT: one step for fleets of ``k x k`` AGVs with multi-tick moves.

PIBT (Okumura et al., AIJ 2022) generalised the standard way to large and slow agents:

- every agent has a *pose* ``(a, b, r)``: at rest on anchor ``b`` when ``r == 0`` (then
  ``a == b``), else moving from ``a`` to ``b`` and arriving in ``r`` ticks; while moving it
  covers both footprints;
- an agent in the middle of a move is fixed for the step (its next pose is forced); an agent
  at rest that starts a move to ``u`` commits to it: a fast agent (``m == 1`` tick per move)
  covers ``fp(u)`` next tick, a slow one covers ``fp(a) | fp(u)`` for ``m - 1`` ticks;
- agents decide in priority order. An agent that wants a pose claims the cells it would
  cover and *pushes* every undecided agent whose current cells overlap them (priority
  inheritance, recursively); if any pushed agent cannot get out of the way, every tentative
  decision made for that pose is rolled back and the agent tries its next pose, staying put
  last. An agent that could not be pushed is not pushed again in the same chain (as plain
  PIBT keeps it in place), which bounds the work;
- a slow agent at rest cannot free its cells within one tick (its move covers them too), so
  a pose that overlaps one is not taken this tick; instead, for its best pose, the agent
  *nudges* such agents: they are asked to start a move whose destination keeps clear of it;
- no agent enters cells of an agent that enters its own cells in the same tick (no swaps);
  instead, when an agent's best move runs head-on into an agent that wants its cells
  and has no room to step aside there, the agent makes way (tries its moves worst first)
  and pulls the other one along behind it, the "swap" of Okumura (AAMAS 2024) with a local
  room test: any neighbouring anchor of the other agent off the first one's way that no
  immovable agent (slow, decided, or already failed) covers.

Turning sweeps (issue 13): a turn-aware mover (one whose ``sweep``, ``locks`` or
``no_turn`` is set; see :mod:`~warerover_phys.planning.search.turning_astar`) has a heading (one per
agent, ``headings``). An agent at rest that starts a move in a new direction turns in place
first: only where it may turn, with its swept cells clear of every other agent now and
claimed for the next tick, and with none of its turn locks taken by another turn of the
same step. No move enters a dead end (a no-turn anchor faced so that it can never turn
again). Without turn-aware movers nothing changes.

Rotations (issue 15, ``planner.rotations``): a mover with ``rot`` (its quarter and half turn
ticks) and ``rdist`` (ticks to its goal from every (anchor, heading),
:func:`~warerover_phys.planning.rotation.rotation_dist`) moves only straight ahead; turns in
place are steps of their own, as in the League of Robot Runners' PIBT entries. Two modes
(``footprint_step(rotation=...)``):

``cascade`` (lifelong PIBT's): the step runs as for any agent, each rotation-aware agent's
targets ranked by the ticks to its goal through them (turn included, so the cell ahead
wins ties); afterwards an agent whose target is not ahead turns a quarter towards it and
stays, and every agent that would enter the cells of an agent that stays stays too, until
none does (the LoRR post-processing). Pushes, swaps and nudges work as before; an agent
pushed sideways turns there and drives off next step. An agent that makes way for a
head-on partner drives ahead first if it can, and ``undo`` keeps an agent from turning
straight back to the heading it just left (two agents turning to and fro in step).

``stay`` (LaCAM's configuration generator, which must realise its constraints exactly):

- its options are ranked by ``rdist``: the cell ahead, or a turn towards a side or back
  neighbour (turn ticks + move + the distance from there), or waiting. A turn holds only
  its own cells, so for PIBT it *is* staying: an agent whose best option is a turn (or
  that cannot go ahead) takes its own cells, and priority inheritance treats it as an
  agent that stays (it cannot be pushed off sideways);
- after the step every such agent that stays turns one quarter: towards its best option's
  direction, or, if a higher-priority agent tried and failed to push it away, towards the
  free neighbour it should escape to next (away from that agent), so that next step it can
  make room by driving ahead (without this two agents meeting head-on in a corridor would
  wait for each other for ever);
- a quarter turn of more than one tick is a pose ``(a, a, r)`` (standing on ``a``, ``r``
  ticks of the turn to go), forced like the rest of a slow move; the headings returned
  (``out_headings``) are those each agent has once its pose is done;
- a forced target (LaCAM's constraints) may be a turn: ``-1 - heading`` for "stay and turn
  a quarter to ``heading``"; a forced node never turns.

The step is used by the lifelong PIBT planner and, with forced moves as its constraints, as
the configuration generator of :mod:`footprint_lacam`.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..base import State, footprint_nodes
from ..graph import UNREACHABLE
from ..rotation import UNREACHABLE_T, quarters, turn_towards
from ..sweep import lock_keys, move_dir, sweep_cells

__all__ = ["Mover", "Pose", "pose_cells", "successor", "arrive", "pose_states",
           "footprint_step", "next_headings", "pose_path"]

Pose = tuple[int, int, int]
"""``(a, b, r)``: at rest on ``b`` if ``r == 0``, else moving ``a -> b``, ``r`` ticks to go."""


@dataclass(frozen=True, slots=True)
class Mover:
    """One agent as the footprint-aware solvers see it."""

    k: int
    """Footprint side (cells)."""
    m: int
    """Ticks per one-cell move."""
    neighbors: Sequence[tuple[int, ...]]
    """Adjacency of its own motion graph (anchor nodes)."""
    dist: np.ndarray
    """Moves from every anchor to its goal (``UNREACHABLE`` where none)."""
    goal: int
    sweep: tuple[tuple[int, int], ...] = ()
    """Cells a turn in place holds (offsets from the anchor; turn-aware movers only)."""
    locks: tuple[tuple[int, int], ...] = ()
    """Turn locks of a turn in place (anchor offsets)."""
    no_turn: frozenset[int] = frozenset()
    """Anchors where it must not turn."""
    dead: frozenset[tuple[int, int]] = frozenset()
    """States ``(anchor, direction index)`` it must never enter."""
    rows: int = 0
    """Grid rows (to clip swept cells; turn-aware movers only)."""
    goal_dead: frozenset[int] | None = None
    """Headings it must not arrive at its goal in (None: the ``dead`` ones)."""
    tdist: Mapping[tuple[int, int], int] | None = None
    """Moves to its goal from each state ``(anchor, heading index)`` that can reach it
    (turn-aware movers with no-turn anchors; None: use ``dist``)."""
    rot: tuple[int, int] | None = None
    """Rotation-aware mover: ticks of a quarter and a half turn in place (None: turns are
    free)."""
    rdist: np.ndarray | None = None
    """Rotation-aware mover: ticks to its goal from ``[anchor, heading]``."""
    prefer: Mapping[int, float] | None = None
    """Plain movers: this step's preference of target anchors, lower first (the ``learned``
    planner's policy ranking); anchors it does not name come after, by distance. None: by
    distance to the goal, as PIBT."""

    @property
    def turns(self) -> bool:
        return bool(self.sweep or self.locks or self.no_turn)


def pose_cells(pose: Pose, k: int, cols: int) -> tuple[int, ...]:
    """Cells a pose covers: the footprint, or both footprints while moving."""
    a, b, r = pose
    if r == 0:
        return footprint_nodes(b, k, cols)
    return tuple(dict.fromkeys(footprint_nodes(a, k, cols) + footprint_nodes(b, k, cols)))


def successor(pose: Pose, target: int, m: int) -> Pose:
    """The pose one tick later for an agent at rest that heads for ``target`` (itself to
    stay), or the forced next pose of an agent in the middle of a move."""
    a, b, r = pose
    if r > 1:
        return (a, b, r - 1)
    if r == 1:
        return (b, b, 0)
    if target == b or m == 1:
        return (target, target, 0)
    return (b, target, m - 1)


def arrive(pose: Pose) -> tuple[State, ...]:
    """The states after ``pose`` until the agent is at rest (empty if it is)."""
    a, b, r = pose
    return ((a, b),) * (r - 1) + ((b, b),) if r > 0 else ()


def next_headings(headings: Sequence[int], before: Sequence[Pose], after: Sequence[Pose],
                  cols: int) -> tuple[int, ...]:
    """Each agent's heading after a step from poses ``before`` to ``after``: the direction
    of a move it started, else unchanged."""
    return tuple(move_dir(p[1], q[1], cols) if p[2] == 0 and q[1] != p[1] else h
                 for h, p, q in zip(headings, before, after, strict=True))


def pose_path(poses: Sequence[Pose], heads: Sequence[int], first: int,
              ) -> tuple[tuple[State, ...], tuple[int, ...]]:
    """:func:`pose_states` with the heading of every state, for a rotation-aware agent:
    ``heads[j]`` is its heading once ``poses[j]`` is done, ``first`` the heading it has in
    the first state. A turn pose ``(a, a, r > 0)`` keeps the heading it had before the
    turn; the turn's last state shows the new one. Trailing repeats (same state and
    heading) are dropped."""
    states: list[State] = []
    hs: list[int] = []
    prev = first
    for (a, b, r), h in zip(poses, heads, strict=True):
        sh = prev if a == b and r > 0 else h
        states.append((a, b))
        hs.append(sh)
        prev = sh
    tail = arrive(poses[-1])
    for j, st in enumerate(tail):
        states.append(st)
        hs.append(heads[-1] if j == len(tail) - 1 else prev)
    end = len(states)
    while end > 1 and states[end - 1] == states[end - 2] and hs[end - 1] == hs[end - 2]:
        end -= 1
    return tuple(states[:end]), tuple(hs[:end])


def pose_states(poses: Sequence[Pose]) -> tuple[State, ...]:
    """Per-tick states of a sequence of poses, finishing any move still under way, without
    trailing repeats (after its last state an AGV stays where it is)."""
    states = [(a, b) for a, b, _ in poses] + list(arrive(poses[-1]))
    end = len(states)
    while end > 1 and states[end - 1] == states[end - 2]:
        end -= 1
    return tuple(states[:end])


class _Step:
    """The working state of one step (see the module doc)."""

    def __init__(self, movers: Sequence[Mover], poses: Sequence[Pose], cols: int,
                 tie: np.ndarray, budget: int, headings: Sequence[int] | None = None,
                 rotation: str = "stay") -> None:
        self.movers, self.poses, self.cols, self.tie = movers, poses, cols, tie
        self.headings = headings
        self.turning = headings is not None and any(mv.turns for mv in movers)
        self.nxt_swept: list[tuple[int, ...]] = [()] * len(poses)
        self.nxt_locks: list[tuple[int, ...]] = [()] * len(poses)
        self.lock_owner: dict[int, int] = {}
        self.cur = [pose_cells(p, mv.k, cols) for p, mv in zip(poses, movers, strict=True)]
        self.cur_set = [frozenset(c) for c in self.cur]
        self.occ_now = {c: i for i, cells in enumerate(self.cur) for c in cells}
        n = len(poses)
        self.nxt: list[Pose | None] = [None] * n
        self.nxt_cells: list[tuple[int, ...]] = [()] * n
        self.occ_next: dict[int, int] = {}
        self.log: list[int] = []
        self.stuck: set[int] = set()
        self.keep: set[int] = set()
        """Agents decided for a nudge: never rolled back."""
        self.chain = 0
        """Log length when the current top-level push began."""
        self.budget = budget
        self.cascade = rotation == "cascade"
        self.rotating = headings is not None and any(mv.rot is not None for mv in movers) \
            and not self.cascade
        """Rotation-aware movers, a turn counting as staying (see the module doc)."""
        if self.cascade and headings is None:
            self.cascade = False
        self.forced_turn: dict[int, int] = {}
        """Rotation-aware agents forced to stay and turn: agent -> heading after it."""
        self.escape: dict[int, int] = {}
        """Rotation-aware agents a higher-priority agent failed to push away: the
        direction to turn to, to make room next step."""
        self.pushers: list[int] = []

    # ------------------------------------------------------------------ bookkeeping

    def decide(self, i: int, pose: Pose, cells: tuple[int, ...],
               turn: tuple[tuple[int, ...], tuple[int, ...]] = ((), ())) -> None:
        self.nxt[i], self.nxt_cells[i] = pose, cells
        for c in cells:
            self.occ_next[c] = i
        swept, keys = turn
        if swept or keys:
            swept = tuple(c for c in swept if c not in self.occ_next)
            for c in swept:
                self.occ_next[c] = i
            for key in keys:
                self.lock_owner[key] = i
            self.nxt_swept[i], self.nxt_locks[i] = swept, keys
        self.log.append(i)

    def undo(self, i: int) -> None:
        for c in self.nxt_cells[i]:
            del self.occ_next[c]
        if self.nxt_swept[i] or self.nxt_locks[i]:
            for c in self.nxt_swept[i]:
                del self.occ_next[c]
            for key in self.nxt_locks[i]:
                del self.lock_owner[key]
            self.nxt_swept[i], self.nxt_locks[i] = (), ()
        self.nxt[i], self.nxt_cells[i] = None, ()

    def head_on_trap(self, i: int, target: int, d: int) -> bool:
        """Would agent ``i`` (1x1), entering ``target`` facing ``d`` where it may not turn,
        meet head-on, on the straight run it must now drive before it may turn again, an
        agent that faces it and may not turn there either? Then neither could ever pass
        (there is no reversing)."""
        mv = self.movers[i]
        if mv.k != 1 or target not in mv.no_turn:
            return False
        step = (1, self.cols, -1, -self.cols)[d]
        back = (d + 2) % 4
        assert self.headings is not None
        cur = target
        for _ in range(len(mv.no_turn)):
            if cur not in mv.no_turn:
                return False
            ahead = cur + step
            if ahead not in mv.neighbors[cur]:
                return False
            for x in {self.occ_now.get(ahead), self.occ_next.get(ahead)}:
                if x is None or x < 0 or x == i or self.movers[x].k != 1 or \
                        ahead not in self.movers[x].no_turn:
                    continue
                nxt = self.nxt[x]
                if nxt is not None and nxt[1] == ahead and self.poses[x][1] != ahead:
                    facing = move_dir(self.poses[x][1], ahead, self.cols)
                elif self.poses[x][1] == ahead and self.poses[x][2] == 0:
                    facing = self.headings[x]
                else:
                    continue
                if facing == back:
                    return True
            cur = ahead
        return False

    def turn_claim(self, i: int, target: int,
                   ) -> tuple[tuple[int, ...], tuple[int, ...]] | None:
        """What agent ``i`` (at rest) must claim to head for ``target``: its turn's swept
        cells and locks if the move needs a turn (empty if not), or None if the move is
        not allowed (a dead end, or a turn it may not make now)."""
        mv, (_, here, r) = self.movers[i], self.poses[i]
        if not self.turning or not mv.turns or r or target == here:
            return (), ()
        d = move_dir(here, target, self.cols)
        if target == mv.goal and mv.goal_dead is not None:
            if d in mv.goal_dead:
                return None
        elif (target, d) in mv.dead:
            return None
        assert self.headings is not None
        if target != mv.goal and self.head_on_trap(i, target, d):
            return None
        if d == self.headings[i]:
            return (), ()
        if here in mv.no_turn:
            return None
        swept = sweep_cells(here, mv.sweep, mv.rows, self.cols) if mv.sweep else ()
        for c in swept:
            if self.occ_now.get(c, i) != i or self.occ_next.get(c, i) != i:
                return None
        keys = lock_keys(here, mv.locks, mv.rows, self.cols) if mv.locks else ()
        for key in keys:
            if self.lock_owner.get(key, i) != i:
                return None
        return swept, keys

    def rollback(self, mark: int) -> None:
        """Forget every decision taken since the log had ``mark`` entries, except those
        taken for a nudge (they stay valid: see :meth:`nudge`)."""
        kept = []
        while len(self.log) > mark:
            i = self.log.pop()
            if i in self.keep:
                kept.append(i)
            else:
                self.undo(i)
        self.log.extend(reversed(kept))

    def fits(self, i: int, cells: tuple[int, ...]) -> bool:
        """No cell claimed by another agent, and no swap with an agent already decided."""
        for c in cells:
            owner = self.occ_next.get(c)
            if owner is not None and owner != i:
                return False
            x = self.occ_now.get(c)
            if x is not None and x != i and self.nxt[x] is not None \
                    and not self.cur_set[i].isdisjoint(self.nxt_cells[x]):
                return False
        return True

    def blockers(self, i: int, cells: tuple[int, ...]) -> list[int] | None:
        """Undecided agents standing on ``cells`` that must move away, or None if one
        cannot (already failed in this chain, or slow: its move would keep its cells)."""
        out: list[int] = []
        for c in cells:
            x = self.occ_now.get(c)
            if x is None or x == i or self.nxt[x] is not None or x in out:
                continue
            if x in self.stuck or self.movers[x].m > 1:
                return None
            out.append(x)
        return out

    # ------------------------------------------------------------------ PIBT

    def candidates(self, i: int, avoid: frozenset[int]) -> list[int]:
        """Targets of an agent at rest, best first (its own node last among equals)."""
        mv, here = self.movers[i], self.poses[i][1]
        d, tie = mv.dist, self.tie
        if mv.rot is not None and self.cascade:
            return self._cascade_candidates(i, avoid)
        if mv.rot is not None and self.rotating:
            near = list(dict.fromkeys(t for _, t, _ in self.rot_options(i)))
            if avoid:
                near = [v for v in near
                        if avoid.isdisjoint(footprint_nodes(v, mv.k, self.cols))]
            return near
        if mv.tdist is not None and self.headings is not None:
            return self._turn_candidates(i, avoid)
        near = [v for v in mv.neighbors[here] if d[v] < UNREACHABLE] + [here]
        if avoid:
            near = [v for v in near
                    if avoid.isdisjoint(footprint_nodes(v, mv.k, self.cols))]
        if mv.prefer is not None:
            pref, last = mv.prefer, float("inf")
            return sorted(near, key=lambda v: (pref.get(v, last), d[v] + tie[v]))
        return sorted(near, key=lambda v: d[v] + tie[v])

    def rot_options(self, i: int) -> list[tuple[float, int, int]]:
        """A rotation-aware agent's options at rest, best first: ``(ticks to its goal,
        target node, direction)``: the cell ahead (target that cell), a turn towards
        another neighbour (target its own node, direction the neighbour's) or waiting
        (its own node, direction -1)."""
        mv, here = self.movers[i], self.poses[i][1]
        assert mv.rot is not None and mv.rdist is not None and self.headings is not None
        rd, tie, cols = mv.rdist, self.tie, self.cols
        h = self.headings[i]
        q1, q2 = mv.rot
        opts: list[tuple[float, int, int]] = []
        for v in mv.neighbors[here]:
            d = move_dir(here, v, cols)
            r = int(rd[v, d])
            if r >= UNREACHABLE_T:
                continue
            if d == h or h > 3:
                opts.append((mv.m + r + tie[v], v, d))
            else:
                q = q1 if quarters(h, d) == 1 else q2
                opts.append((q + mv.m + r + tie[v], here, d))
        wait = int(rd[here, h]) if h < 4 else int(rd[here].min())
        opts.append((1 + min(wait, UNREACHABLE_T) + tie[here], here, -1))
        opts.sort()
        return opts

    def _ahead_of(self, i: int) -> int | None:
        """The neighbour straight ahead of a rotation-aware agent at rest (None if none)."""
        mv, here = self.movers[i], self.poses[i][1]
        h = self.headings[i] if self.headings is not None else 4
        if h > 3:
            return None
        v = here + (1, self.cols, -1, -self.cols)[h]
        return v if v in mv.neighbors[here] else None

    def _cascade_candidates(self, i: int, avoid: frozenset[int]) -> list[int]:
        """Targets of a rotation-aware agent in ``cascade`` mode: every neighbour and its
        own node, ranked by the ticks to its goal through them (the turn towards a
        neighbour included)."""
        mv, here = self.movers[i], self.poses[i][1]
        assert mv.rot is not None and mv.rdist is not None and self.headings is not None
        rd, tie, cols, h = mv.rdist, self.tie, self.cols, self.headings[i]
        q1, q2 = mv.rot
        score = {here: 1 + int(rd[here, h] if h < 4 else rd[here].min()) + tie[here]}
        for v in mv.neighbors[here]:
            d = move_dir(here, v, cols)
            r = int(rd[v, d])
            if r >= UNREACHABLE_T:
                continue
            n = 0 if h > 3 else quarters(h, d)
            score[v] = (0, q1, q2)[n] + mv.m + r + tie[v]
        near = sorted(score, key=score.__getitem__)
        if avoid:
            near = [v for v in near if avoid.isdisjoint(footprint_nodes(v, mv.k, cols))]
        return near

    def note_escape(self, i: int, against: int | None = None) -> None:
        """Agent ``i`` (rotation-aware, at rest) could not be pushed away by ``against``
        (default: the agent pushing it now), or must make way for it: remember the
        neighbour it should turn to, to make room next step (off that agent's cells,
        unclaimed, not ahead (that failed); fewest agents on it now, fewest quarter turns,
        nearest to its goal)."""
        mv, here = self.movers[i], self.poses[i][1]
        assert mv.rdist is not None and self.headings is not None
        p = against if against is not None else (self.pushers[-1] if self.pushers else None)
        bad = frozenset() if p is None else self.cur_set[p].union(self.nxt_cells[p])
        best = None
        for v in mv.neighbors[here]:
            d = move_dir(here, v, self.cols)
            r = int(mv.rdist[v, d])
            cells = footprint_nodes(v, mv.k, self.cols)
            if r >= UNREACHABLE_T or d == self.headings[i] or not bad.isdisjoint(cells) or \
                    any(self.occ_next.get(c, i) != i for c in cells):
                continue
            busy = sum(1 for c in cells if self.occ_now.get(c, i) != i)
            key = (busy, quarters(self.headings[i], d), r + self.tie[v])
            if best is None or key < best[0]:
                best = (key, d)
        if best is not None:
            self.escape[i] = best[1]

    def _turn_candidates(self, i: int, avoid: frozenset[int]) -> list[int]:
        """:meth:`candidates` by the moves left from the state (anchor, heading) each
        target leads to (a turn-aware mover that may not turn everywhere)."""
        mv, here = self.movers[i], self.poses[i][1]
        assert mv.tdist is not None and self.headings is not None
        td, tie, cols = mv.tdist, self.tie, self.cols
        score = {here: td.get((here, self.headings[i]), UNREACHABLE)}
        for v in mv.neighbors[here]:
            s = td.get((v, move_dir(here, v, cols)))
            if s is not None:
                score[v] = s
        near = list(score)
        if avoid:
            near = [v for v in near
                    if avoid.isdisjoint(footprint_nodes(v, mv.k, self.cols))]
        return sorted(near, key=lambda v: (score[v] + tie[v], v != here))

    def try_target(self, i: int, target: int) -> bool:
        """Take ``target`` for agent ``i`` if every agent in the way can be pushed aside."""
        mv = self.movers[i]
        pose = successor(self.poses[i], target, mv.m)
        cells = pose_cells(pose, mv.k, self.cols)
        if not self.fits(i, cells):
            return False
        turn = self.turn_claim(i, target)
        if turn is None:
            return False
        ahead = self.blockers(i, cells)
        if ahead is None or (ahead and self.budget <= 0):
            return False
        self.budget -= len(ahead)
        mark = len(self.log)
        self.decide(i, pose, cells, turn)
        self.pushers.append(i)
        try:
            for x in ahead:
                if self.nxt[x] is None and not self.push(x):
                    self.rollback(mark)
                    return False
        finally:
            self.pushers.pop()
        return True

    def push(self, i: int, avoid: frozenset[int] = frozenset()) -> bool:
        """Decide agent ``i`` (at rest); with ``avoid``, its destination keeps clear of
        those cells (a nudge). False if it has no pose that fits."""
        cands = self.candidates(i, avoid)
        here = self.poses[i][1]
        partner = -1
        if not avoid and cands[0] != here:
            # A rotation-aware agent never makes way for a head-on partner: it pushes, and
            # the partner, unable to leave ahead, turns to escape (note_escape).
            partner = -1 if self.rotating and self.movers[i].rot is not None else \
                self.head_on(i, cands[0])
            if partner >= 0:
                cands.reverse()  # make way, then pull the partner along behind
                if self.cascade and self.movers[i].rot is not None:
                    # ... by driving ahead if it can (a side step would be a turn, and
                    # turning to the worst side every step spins it round)
                    ahead = self._ahead_of(i)
                    if ahead in cands:
                        cands.remove(ahead)
                        cands.insert(0, ahead)
            else:
                self.nudge(i, cands[0])
        for idx, target in enumerate(cands):
            if self.try_target(i, target):
                if idx == 0 and partner >= 0 and target != here \
                        and self.nxt[partner] is None:
                    self.try_target(partner, self.candidates(partner, frozenset())[0])
                return True
        if not avoid:
            self.stuck.add(i)
            if self.rotating and self.movers[i].rot is not None:
                self.note_escape(i)
        return False

    # ------------------------------------------------------------------ swap

    def head_on(self, i: int, best: int) -> int:
        """An agent at rest on ``best``'s footprint that heads into ``i``'s cells and
        cannot step aside there: the two must swap (Okumura, AAMAS 2024), so ``i`` makes
        way. -1 if none."""
        mv = self.movers[i]
        for c in footprint_nodes(best, mv.k, self.cols):
            j = self.occ_now.get(c)
            if j is None or j == i or self.nxt[j] is not None or j in self.stuck:
                continue
            want = self.candidates(j, frozenset())[0]
            if want == self.poses[j][1] or self.cur_set[i].isdisjoint(
                    footprint_nodes(want, self.movers[j].k, self.cols)):
                continue
            if not self.can_step_aside(j, i, best):
                return j
        return -1

    def can_step_aside(self, j: int, i: int, best: int) -> bool:
        """Has ``j`` a neighbouring anchor off ``i``'s way (clear of ``i``'s cells and of
        ``best``, no closer to ``i``'s goal) that nothing immovable covers? (A turn-aware
        ``j`` only where it may drive: no turn where it may not turn, no dead end.)"""
        mj, mi = self.movers[j], self.movers[i]
        blocked = self.cur_set[i].union(footprint_nodes(best, mi.k, self.cols))
        ref = mi.dist[best]
        here = self.poses[j][1]
        for u in mj.neighbors[here]:
            if mj.dist[u] >= UNREACHABLE or mi.dist[u] < ref:
                continue
            if self.rotating and mj.rot is not None and \
                    mj.rdist[u, move_dir(here, u, self.cols)] >= UNREACHABLE_T:
                continue  # (a side step of a rotation-aware agent turns first: it
                # escapes there next step, see note_escape)
            if self.turning and mj.turns:
                assert self.headings is not None
                d = move_dir(here, u, self.cols)
                if (u, d) in mj.dead or (d != self.headings[j] and here in mj.no_turn) or (
                        mj.tdist is not None and (u, d) not in mj.tdist):
                    continue
            cells = footprint_nodes(u, mj.k, self.cols)
            if blocked.isdisjoint(cells) and not any(self.immovable(c, j) for c in cells):
                return True
        return False

    def immovable(self, c: int, j: int) -> bool:
        """Does something ``j`` cannot push keep cell ``c`` next tick?"""
        owner = self.occ_next.get(c)
        if owner is not None:
            return owner != j
        x = self.occ_now.get(c)
        return x is not None and x != j and self.nxt[x] is None and (
            self.movers[x].m > 1 or x in self.stuck)

    def nudge(self, i: int, target: int) -> None:
        """Ask slow agents at rest on ``target``'s footprint to start moving off it.

        Their moves (and the pushes they need) are kept even if a decision of this chain is
        rolled back later, so they keep clear of the cells of ``i`` and of every agent with
        a decision in this chain: each of those may still stay where it is.

        A turn-aware agent whose move to ``target`` is a turn nudges every agent at rest
        there the same way: such an agent often has to turn to get out of the way, and two
        neighbours may not turn in the same tick, so it moves first and ``i`` follows a
        tick later.
        """
        mv = self.movers[i]
        dest = footprint_nodes(target, mv.k, self.cols)
        turn_first = self.turning and mv.turns and self.poses[i][2] == 0 and \
            target != self.poses[i][1] and self.headings is not None and \
            move_dir(self.poses[i][1], target, self.cols) != self.headings[i]
        slow = [x for x in dict.fromkeys(self.occ_now.get(c) for c in dest)
                if x is not None and x != i and self.nxt[x] is None
                and (self.movers[x].m > 1 or turn_first) and x not in self.stuck]
        if not slow or self.budget <= 0:
            return
        self.budget -= len(slow)
        guard = [c for y in [i, *self.log[self.chain:]] for c in self.cur[y]
                 if c not in self.occ_next]
        for c in guard:
            self.occ_next[c] = -1
        mark = len(self.log)
        avoid = frozenset(dest)
        for x in slow:
            if self.nxt[x] is None:
                self.push(x, avoid)
        for c in guard:
            self.occ_next.pop(c, None)
        self.keep.update(self.log[mark:])

    def force(self, i: int, target: int) -> bool:
        if target < 0:  # stay and turn a quarter (rotation-aware agents)
            self.forced_turn[i] = -1 - target
            target = self.poses[i][1]
        pose = successor(self.poses[i], target, self.movers[i].m)
        cells = pose_cells(pose, self.movers[i].k, self.cols)
        if not self.fits(i, cells):
            return False
        turn = self.turn_claim(i, target)
        if turn is None:
            return False
        self.decide(i, pose, cells, turn)
        return True


def footprint_step(movers: Sequence[Mover], poses: Sequence[Pose], prio: Sequence[float],
                   tie: np.ndarray, cols: int, forced: Mapping[int, int] | None = None,
                   budget: int | None = None, headings: Sequence[int] | None = None,
                   out_headings: list[int] | None = None, rotation: str = "stay",
                   undo: Mapping[int, int] | None = None) -> list[Pose] | None:
    """Next pose of every agent, or None if the ``forced`` targets (agent -> node; the
    agent's own node to stay) contradict each other or cannot be made room for.

    Agents in the middle of a move always take their forced next pose. ``tie`` (one value
    in [0, 0.5) per node) breaks ties between equally good targets; ``budget`` caps the
    number of pushes (default ``50 * len(poses) + 100``); when it runs out, agents only
    take targets nobody stands on. ``headings``: per agent the direction index it faces
    (:func:`~warerover_phys.planning.sweep.move_dir`; 4: unknown), needed for turn-aware
    movers (see the module doc). ``out_headings`` (an empty list; with ``headings``) gets
    each agent's heading once its next pose is done (turns of rotation-aware agents
    included). ``rotation``: how rotation-aware movers take part (``stay``: a turn is a
    way of staying, the default; ``cascade``: they are ranked like any agent, with turn
    costs, then every one whose target is not ahead turns towards it instead and the
    agents that would enter its cells stay too; see the module doc). ``undo`` (cascade
    mode): per agent the heading it turned away from in the step before; it does not turn
    straight back to it (it waits instead), which stops two agents from turning to and
    fro in step with each other.
    """
    n = len(poses)
    step = _Step(movers, poses, cols, tie, 50 * n + 100 if budget is None else budget,
                 headings, rotation)
    fixed = {i: p[1] for i, p in enumerate(poses) if p[2] > 0}
    fixed.update(forced or {})
    for i in sorted(fixed):
        if not step.force(i, fixed[i]):
            return None
    order = sorted(range(n), key=lambda i: -prio[i])
    # Agents standing where a forced agent goes must move first.
    first = [i for i in order if step.nxt[i] is None
             and any(step.occ_next.get(c, i) != i for c in step.cur[i])]
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 8 * n + 1000))
    try:
        for i in first + order:
            if step.nxt[i] is None:
                step.chain = len(step.log)
                ok = step.push(i)
                step.stuck.clear()
                if not ok:
                    return None
    finally:
        sys.setrecursionlimit(limit)
    out = [p for p in step.nxt if p is not None]
    if len(out) != n:
        return None
    if out_headings is not None and headings is not None:
        out_headings[:] = next_headings(headings, poses, out, cols)
        if step.rotating:
            _rotate(step, out, out_headings, fixed)
        elif step.cascade and not _cascade(step, out, out_headings, fixed, undo or {}):
            return None
    return out


def _cascade(step: _Step, out: list[Pose], heads: list[int], fixed: Mapping[int, int],
             undo: Mapping[int, int]) -> bool:
    """``cascade`` mode: a rotation-aware agent whose target is not ahead turns a quarter
    towards it and stays; then every agent that would enter cells of an agent that stays
    stays too, until none does. False if a forced move would have to stay."""
    assert step.headings is not None
    cols = step.cols
    for i, mv in enumerate(step.movers):
        p = step.poses[i]
        if mv.rot is not None and i in step.forced_turn:  # forced to stay and turn
            new, h = step.forced_turn[i], step.headings[i]
            if new != h and h < 4:
                heads[i] = new
                q = mv.rot[0] if quarters(h, new) == 1 else mv.rot[1]
                out[i] = (p[1], p[1], q - 1) if q > 1 else (p[1], p[1], 0)
            continue
        if mv.rot is None or p[2] != 0 or out[i][1] == p[1]:
            continue
        h = step.headings[i]
        d = move_dir(p[1], out[i][1], cols)
        if h > 3 or d == h:
            continue
        if i in fixed:
            return False
        new = turn_towards(h, d)
        if undo.get(i) == new:
            new = h  # no turning straight back: wait
        heads[i] = new
        q = mv.rot[0] if new != h else 1
        out[i] = (p[1], p[1], q - 1) if q > 1 else (p[1], p[1], 0)
    while True:
        owner: dict[int, int] = {}
        clash = None
        for i, pose in enumerate(out):
            for c in pose_cells(pose, step.movers[i].k, cols):
                j = owner.get(c)
                if j is not None:
                    clash = (j, i)
                    break
                owner[c] = i
            if clash is not None:
                break
        if clash is None:
            return True
        for x in clash:  # the one that moves into the other's cells stays
            p = step.poses[x]
            if p[2] == 0 and out[x][1] != p[1]:
                if x in fixed:
                    return False
                out[x] = (p[1], p[1], 0)
                heads[x] = step.headings[x]
                break
        else:
            return False


def _rotate(step: _Step, out: list[Pose], heads: list[int], fixed: Mapping[int, int]) -> None:
    """Turn the rotation-aware agents that stay (see the module doc), in place."""
    for i, mv in enumerate(step.movers):
        if mv.rot is None or step.poses[i][2] != 0 or out[i][1] != step.poses[i][1]:
            continue
        h = heads[i]
        if i in step.forced_turn:
            new = step.forced_turn[i]
        elif i in fixed or h > 3:
            continue
        else:
            d = step.escape.get(i)
            if d is None:
                best = step.rot_options(i)[0]
                d = best[2] if best[1] == step.poses[i][1] else -1
            if d < 0 or d == h:
                continue
            new = turn_towards(h, d)
        if new == h:
            continue
        heads[i] = new
        q = mv.rot[0] if quarters(h, new) == 1 else mv.rot[1]
        here = step.poses[i][1]
        out[i] = (here, here, q - 1) if q > 1 else (here, here, 0)
