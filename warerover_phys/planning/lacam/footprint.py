"""LaCAM for fleets of ``k x k`` AGVs with multi-tick moves.

The search of :mod:`lacam` (Okumura, AAAI 2023) over configurations of *poses* (see
:mod:`footprint_pibt`): a pose holds the agent's anchor and, while it is moving, where it
moves and how many ticks it still needs, so two configurations that look alike but differ
in a slow agent's progress are different nodes. An agent in the middle of a move has one
successor (its next pose), so low-level constraints only bind agents at rest ("agent ``i``
heads for node ``v`` next"); the footprint-aware PIBT step generates each successor
configuration under them. With every agent at rest constrained the step either builds that
exact configuration or rejects it, so the search stays complete: it finds a solution if one
exists and otherwise reports the space exhausted.

Rotations (``planner.rotations``): a rotation-aware agent's heading is part of the search
node (a configuration reached again facing other ways is a new node), and its low-level
constraints are "drive ahead", "stay" and "turn a quarter either way" (the turns are forced
targets ``-1 - heading`` of :func:`~warerover_phys.planning.pibt.footprint.footprint_step`),
so the search stays complete over (pose, heading) configurations. ``stats["headings"]``
then holds each returned configuration's headings.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from ..graph import UNREACHABLE
from ..pibt.footprint import Mover, Pose, footprint_step, next_headings
from ..rotation import UNREACHABLE_T

__all__ = ["footprint_lacam", "footprint_priorities", "update_footprint_priorities"]

Config = tuple[Pose, ...]


@dataclass(slots=True)
class _Low:
    who: tuple[int, ...] = ()
    where: tuple[int, ...] = ()

    @property
    def depth(self) -> int:
        return len(self.who)


@dataclass(slots=True)
class _High:
    config: Config
    parent: _High | None
    prio: list[float]
    order: list[int]
    """Agents at rest that are not held, highest priority first: the constraint order."""
    headings: tuple[int, ...] | None = None
    """Each agent's heading here, along this node's parent chain (turn-aware fleets)."""
    tree: deque = field(default_factory=lambda: deque([_Low()]))


def footprint_priorities(movers: Sequence[Mover], poses: Sequence[Pose]) -> list[float]:
    """Ties broken by remaining moves: farther agents first (a value in [0, 1))."""
    d = [float(mv.dist[p[1]]) for mv, p in zip(movers, poses, strict=True)]
    top = max(d, default=0.0) + 1.0
    return [x / top for x in d]


def update_footprint_priorities(prio: Sequence[float], movers: Sequence[Mover],
                                config: Config) -> list[float]:
    """Back to the fractional part on arrival (at rest on the goal), else one more."""
    return [p - int(p) if c[2] == 0 and c[1] == mv.goal else p + 1.0
            for p, mv, c in zip(prio, movers, config, strict=True)]


def _make_high(held_set: set[int], headings: Sequence[int] | None, cols: int, config: Config,
               parent: _High | None, prio: list[float],
               heads: tuple[int, ...] | None = None) -> _High:
    """A high-level node: its agents in priority order (the held and the moving left out)
    and, for turn-aware fleets, the headings its parent chain gives it."""
    order = sorted((i for i in range(len(config)) if i not in held_set and config[i][2] == 0),
                   key=lambda i: -prio[i])
    if headings is not None and heads is None:
        heads = tuple(headings) if parent is None else next_headings(
            parent.headings, parent.config, config, cols)
    return _High(config, parent, prio, order, heads)


def _unsolvable(movers: Sequence[Mover], start: Config, headings: Sequence[int] | None,
                held_set: set[int]) -> bool:
    """Can some agent (not held) not reach its goal from its start pose and heading?"""
    return any(_rot_unreachable(mv, start[i][1], headings[i]) if (
        mv.rdist is not None and headings is not None and headings[i] < 4) else (
        mv.dist[start[i][1]] >= UNREACHABLE or (
            mv.tdist is not None and headings is not None
            and (start[i][1], headings[i]) not in mv.tdist))
        for i, mv in enumerate(movers) if i not in held_set)


def _stop_reason(iterations: int, max_iterations: int | None, deadline: float) -> str | None:
    """``"iterations"`` once the work budget is spent (deterministic), ``"time"`` once the
    deadline passed (checked every 64 iterations), else None."""
    if max_iterations is not None and iterations > max_iterations:
        return "iterations"
    if iterations % 64 == 0 and time.monotonic() > deadline:
        return "time"
    return None


def footprint_lacam(movers: Sequence[Mover], starts: Sequence[Pose], cols: int,
                    deadline: float, rng: np.random.Generator, held: Sequence[int] = (),
                    prio: list[float] | None = None, max_iterations: int | None = None,
                    headings: Sequence[int] | None = None, rotation: str = "stay",
                    ) -> tuple[list[Config] | None, dict]:
    """Configurations from ``starts`` until every agent rests on its goal, or None.

    Agents in ``held`` never move (their goal must be where they stand). Returns
    (configurations or None, stats); None with ``stats["exhausted"]`` True means there is
    no solution, otherwise ``max_iterations`` high-level iterations were spent
    (``stats["stopped"] == "iterations"``: deterministic) or the deadline (a
    ``time.monotonic()`` value, a safety stop) passed (``"time"``).

    ``rotation``: the configuration generator's mode for rotation-aware agents
    (:func:`~warerover_phys.planning.pibt.footprint.footprint_step`; ``stay``, the default,
    realises every low-level constraint exactly; ``cascade`` measured no better here).

    ``headings`` (turn-aware fleets, see :mod:`footprint_pibt`): each agent's direction
    index at the start. A node keeps the headings its parent chain gives it; a
    configuration reached again with other headings is the same node (the search stays
    sound, the found plan follows the parent chain).
    """
    n_nodes = len(movers[0].dist) if movers else 0
    ties = rng.random(n_nodes + 4099) * 0.5
    start: Config = tuple(starts)
    goal: Config = tuple((mv.goal, mv.goal, 0) for mv in movers)
    held_set = set(held)
    stay = {i: start[i][1] for i in held_set}

    rotating = headings is not None and any(mv.rot is not None for mv in movers)

    make = partial(_make_high, held_set, headings, cols)
    if _unsolvable(movers, start, headings, held_set):
        # An agent that cannot reach its goal: no configuration search can succeed.
        return None, {"iterations": 0, "explored": 0, "exhausted": True,
                      "stopped": "unreachable"}
    root = make(start, None, prio if prio is not None else footprint_priorities(movers, start))
    stack = [root]
    explored: dict = {(start, root.headings) if rotating else start: root}
    iterations = 0
    while stack:
        iterations += 1
        stop = _stop_reason(iterations, max_iterations, deadline)
        if stop is not None:
            return None, {"iterations": iterations, "explored": len(explored),
                          "exhausted": False, "stopped": stop}
        node = stack[-1]
        if node.config == goal:
            configs, heads = _unwind(node)
            stats = {"iterations": iterations, "explored": len(explored)}
            if rotating:
                stats["headings"] = heads
            return configs, stats
        if not node.tree:
            stack.pop()
            continue
        low = node.tree.popleft()
        if low.depth < len(node.order):
            _grow(node, low, movers, rng)
        salt = int(rng.integers(4096))
        forced = dict(stay)
        forced.update(zip(low.who, low.where, strict=True))
        out_heads: list[int] = []
        nxt = footprint_step(movers, node.config, node.prio, ties[salt:], cols, forced,
                             headings=node.headings,
                             out_headings=out_heads if rotating else None,
                             rotation=rotation)
        if nxt is None:
            continue
        config = tuple(nxt)
        key = (config, tuple(out_heads)) if rotating else config
        known = explored.get(key)
        if known is not None:
            stack.append(known)
            continue
        new = make(config, node, update_footprint_priorities(node.prio, movers, config),
                   tuple(out_heads) if rotating else None)
        stack.append(new)
        explored[key] = new
    return None, {"iterations": iterations, "explored": len(explored), "exhausted": True}


def _grow(node: _High, low: _Low, movers: Sequence[Mover], rng: np.random.Generator) -> None:
    """Add the children of a low-level node: the next agent in order heads for each of its
    possible targets."""
    i = node.order[low.depth]
    mv = movers[i]
    here = node.config[i][1]
    if mv.rot is not None and node.headings is not None and node.headings[i] < 4:
        h = node.headings[i]
        cands = [v for v in mv.neighbors[here] if mv.rdist[v, h] < UNREACHABLE_T
                 and _ahead(here, v, h, mv)] + [here, -1 - (h + 1) % 4, -1 - (h + 3) % 4]
    else:
        cands = [v for v in mv.neighbors[here] if mv.dist[v] < UNREACHABLE] + [here]
    rng.shuffle(cands)
    for v in cands:
        node.tree.append(_Low(low.who + (i,), low.where + (v,)))


def _rot_unreachable(mv: Mover, here: int, h: int) -> bool:
    """Can a rotation-aware agent on ``here`` facing ``h`` not reach its goal? (From a
    sink, such as a loaded AGV's own shelf home, it leaves through a neighbour: the
    distance tables only count moves out of anchors it may drive through.)"""
    rd = mv.rdist
    assert rd is not None
    if rd[here, h] < UNREACHABLE_T:
        return False
    return all(rd[v, d] >= UNREACHABLE_T for v in mv.neighbors[here] for d in range(4))


def _ahead(here: int, v: int, h: int, mv: Mover) -> bool:  # noqa: ARG001
    """Is neighbour ``v`` (of ``mv``'s graph) straight ahead of an agent on ``here``
    facing ``h``? (Vertical neighbours are a row apart, horizontal ones adjacent.)"""
    d = v - here
    if d == 1:
        return h == 0
    if d == -1:
        return h == 2
    return h == (1 if d > 0 else 3)


def _unwind(node: _High) -> tuple[list[Config], list[tuple[int, ...] | None]]:
    configs: list[Config] = []
    heads: list[tuple[int, ...] | None] = []
    walk: _High | None = node
    while walk is not None:
        configs.append(walk.config)
        heads.append(walk.headings)
        walk = walk.parent
    configs.reverse()
    heads.reverse()
    return configs, heads
