"""Poses of ``k x k`` AGVs with multi-tick moves, as the footprint PIBT step sees them: a pose is
``(a, b, r)`` (at rest on ``b`` if ``r == 0``, else moving ``a -> b`` with ``r`` ticks to go);
an agent is a :class:`Mover`. Re-exported by :mod:`.footprint`."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..base import State, footprint_nodes
from ..sweep import move_dir

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
