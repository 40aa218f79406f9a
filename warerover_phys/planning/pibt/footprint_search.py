"""The search state of one footprint PIBT step (:func:`~.footprint.footprint_step`): who holds
which cell now and next, the recursive choice of each agent's next pose with priority
inheritance, swaps and make-room pushes. See :mod:`.footprint` for the rules."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..base import footprint_nodes
from ..graph import UNREACHABLE
from ..rotation import UNREACHABLE_T, quarters
from ..sweep import lock_keys, move_dir, sweep_cells
from .poses import Mover, Pose, pose_cells, successor


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
