"""Heading-aware reachability for AGVs that may not turn in place everywhere (issue 13).

Pure functions over a motion graph's adjacency (no package imports, so
:mod:`~warerover_phys.planning.graph` can cache them): direction indices are 0 east,
1 south, 2 west, 3 north, and 4 "unknown" for a heading.
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["dead_ends", "turn_dist"]


def dead_ends(neighbors: Sequence[tuple[int, ...]], no_turn: frozenset[int], cols: int,
              expandable: Sequence[bool] | None = None) -> frozenset[tuple[int, int]]:
    """States ``(anchor, direction index)`` an AGV must never be in: it stands in a no-turn
    anchor facing that way, and driving straight ahead along the motion graph
    (``neighbors``; only into ``expandable`` anchors: never through a shelf's home while
    loaded) never reaches an anchor where it may turn. An AGV that enters one can never
    leave it."""
    if not no_turn:
        return frozenset()
    step = (1, cols, -1, -cols)
    memo: dict[tuple[int, int], bool] = {}
    for node in no_turn:
        for d in range(4):
            trail = []
            v = node
            ok = False
            while True:
                key = (v, d)
                if key in memo:
                    ok = memo[key]
                    break
                if v not in no_turn:
                    ok = True
                    break
                trail.append(key)
                nxt = v + step[d]
                if nxt not in neighbors[v] or len(trail) > len(no_turn) or (
                        expandable is not None and not expandable[nxt]):
                    break
                v = nxt
            for key in trail:
                memo[key] = ok
    return frozenset(k for k, ok in memo.items() if not ok)


def turn_dist(neighbors: Sequence[tuple[int, ...]], no_turn: frozenset[int],
              dead: frozenset[tuple[int, int]], cols: int, goal: int,
              goal_dead: frozenset[int] | None = None,
              expandable: Sequence[bool] | None = None) -> dict[tuple[int, int], int]:
    """Moves to ``goal`` from every state ``(anchor, heading index)`` (4: unknown) from which
    an AGV that may not turn at ``no_turn`` anchors, nor enter ``dead`` states (nor
    non-``expandable`` anchors other than the goal), can reach it in a heading not in
    ``goal_dead`` (default: any it is not stuck in, per ``dead``). States missing from the
    result cannot reach it. Turns cost nothing (as in the plans)."""
    step = (1, cols, -1, -cols)
    ends = [(goal, d) for d in range(4) if (d not in goal_dead if goal_dead is not None
                                            else (goal, d) not in dead)]
    dist = {e: 0 for e in ends}
    frontier = list(ends)
    n = 0
    while frontier:
        n += 1
        nxt = []
        for u, d in frontier:
            v = u - step[d]
            if not 0 <= v < len(neighbors) or u not in neighbors[v]:
                continue
            for h in range(5):
                if (h == d or v not in no_turn) and (v, h) not in dist and \
                        (h == 4 or (v, h) not in dead) and not (
                            v == goal and goal_dead is not None and h in goal_dead):
                    dist[(v, h)] = n
                    if h < 4 and (expandable is None or expandable[v]):
                        nxt.append((v, h))
        frontier = nxt
    return dist
