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

import numpy as np

from ..rotation import quarters, turn_towards
from ..sweep import move_dir
from .footprint_search import _Step
from .poses import (
    Mover,
    Pose,
    arrive,
    next_headings,
    pose_cells,
    pose_path,
    pose_states,
    successor,
)

__all__ = ["Mover", "Pose", "pose_cells", "successor", "arrive", "pose_states",
           "footprint_step", "next_headings", "pose_path"]


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
