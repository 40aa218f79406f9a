"""Book-keeping of corridor intrusions, shared by both executors: every AGV-second inside an
open corridor is counted, and an AGV caught inside when it opens gets a bounded exit time.

The executors check the open corridors (physics: every physics step, the body within the
margin of the person's space; grid: once per tick, a cell of the AGV on a corridor cell);
the loop hands each check to :func:`record_check` with the simulated time it covers. For
one check at time ``t`` lasting ``dt`` seconds, for each AGV found inside corridor ``c``
(the failed AGV that opened ``c`` is never listed; AGVs that are down are not counted
anywhere, they do not move):

- its ``dt`` is added to ``corridor_inside_agv_s``;
- if the AGV was **caught** by ``c`` (on its cells, or unable to stop before them, when
  ``c`` opened: :meth:`CorridorBook.catch`) and has not left yet, it is **exiting**: before its
  deadline (``open_s + bound_s``) the time is exit time, not intrusion; at the first check
  at or past the deadline it has **overrun** (logged ``corridor_exit_overrun``) and from then
  on its time inside counts as intrusion;
- otherwise the time counts as intrusion (``corridor_intrusion_agv_s``), and the first check
  of each visit starts a new intrusion (``corridor_intrusions``, logged
  ``corridor_intrusion`` with its depth).

A caught AGV has **exited** at the first check of ``c`` that does not find it inside after
one that did (logged
``corridor_exit`` with ``exit_s``, ``bound_s`` and ``within``); a later visit is an
intrusion. A corridor that closes, or an episode that ends, while a caught AGV is still
inside and before its deadline counts as an exit within the bound (``closed: true``). So
``corridor_caught_inside = corridor_exits_within_bound + corridor_exits_overrun``.

The exit bound is ``faults.exit_time_s`` if set, else derived per AGV when the corridor
opens (:func:`exit_bound_s`): the time to drive the cells out of the corridor at the plan's
move time, plus the move it may have to finish first, a half turn at its turn-rate limit,
speeding up and braking at its acceleration limit, and ``faults.exit_margin_s``.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING

from .book import CorridorBook, Grant

FAILED_STATE = 7
"""``world.AgvState.FAILED`` (a constant here: this module stays a leaf of ``world``)."""

if TYPE_CHECKING:
    from ..world import Agv, World
    from .corridors import Corridor

__all__ = ["CorridorBook", "Grant", "exit_bound_s", "record_check", "record_checks"]

Hit = tuple[int, int, float]
"""``(agv, corridor id, depth)``: one AGV found inside one corridor by one check."""


def record_checks(world: World, checks: Sequence[Iterable[Hit]], unit: str = "m") -> None:
    """The corridor checks an executor made during tick ``world.tick``, in order, evenly
    spread over the tick (a physics executor checks once per step)."""
    if not checks:
        return
    tick_s = float(world.scenario.tick_s)
    dt = tick_s / len(checks)
    t0 = world.tick * tick_s
    for i, hits in enumerate(checks):
        record_check(world, hits, t0 + i * dt, dt, unit)


def record_check(world: World, hits: Iterable[Hit], t_s: float, dt_s: float,
                 unit: str = "m") -> int:
    """One check at simulated time ``t_s`` covering ``dt_s`` seconds; returns how many new
    intrusions began. Hits of AGVs that are down, or for corridors no longer open, are
    ignored."""
    book: CorridorBook = world.corridor_book
    current: dict[tuple[int, int], float] = {}
    for agv, cid, depth in hits:
        if cid not in world.corridors or world.agvs[agv].state == FAILED_STATE:
            continue
        key = (agv, cid)
        current[key] = max(float(depth), current.get(key, 0.0))
    eps = 1e-9 * max(1.0, abs(t_s))
    # Caught AGVs not found inside any more have left.
    for key, g in book.grants.items():
        if g.settled or key in current or g.corridor not in world.corridors \
                or not g.seen_inside:
            continue
        if world.agvs[g.agv].state == FAILED_STATE:
            continue  # down: not looked at, its clock says nothing
        g.exit_s = t_s - g.open_s
        world.log("corridor_exit", agv=g.agv, corridor=g.corridor, exit_s=round(g.exit_s, 3),
                  bound_s=round(g.bound_s, 3), within=True, closed=False)
    new = 0
    for key, depth in current.items():
        book.inside_s += dt_s
        g = book.grants.get(key)
        if g is not None and g.exit_s is None and not g.closed:
            g.seen_inside = True
            if not g.overran and t_s < g.deadline_s - eps:
                continue  # still leaving within its bound
            if not g.overran:
                g.overran = True
                world.log("corridor_exit_overrun", agv=g.agv, corridor=g.corridor,
                          bound_s=round(g.bound_s, 3), depth=round(depth, 4), unit=unit)
        book.intrusion_s += dt_s
        if key not in book._visits:
            new += 1
            book.intrusions += 1
            world.fault_stats["corridor_intrusions"] += 1
            world.log("corridor_intrusion", agv=key[0], corridor=key[1],
                      depth=round(depth, 4), unit=unit)
            book._visits[key] = depth
        else:
            book._visits[key] = max(depth, book._visits[key])
    for key in [k for k in book._visits if k not in current]:
        del book._visits[key]
    return new


def exit_bound_s(world: World, agv: Agv, corridor: Corridor) -> float:
    """Seconds AGV ``agv`` may take to leave ``corridor`` (see the module docstring)."""
    spec = world.scenario.faults
    if spec.exit_time_s is not None:
        return float(spec.exit_time_s)
    t = agv.spec
    move_s = agv.ticks_per_move * world.scenario.tick_s
    cells = _cells_out(world, agv, corridor)
    return ((cells + 1) * move_s + math.pi / t.max_turn_rate_radps
            + t.max_speed_mps / t.max_accel_mps2 + spec.exit_margin_s)


def _cells_out(world: World, agv: Agv, corridor: Corridor) -> int:
    """Fewest 4-neighbour moves of ``agv``'s anchor to an anchor whose footprint is off the
    corridor's cells (obstacles block; 0 if it is already out; the map's rows + cols if no
    such anchor can be reached)."""
    from ..planning.paths import footprint_nodes

    lay, k = world.layout, agv.k
    rows, cols = lay.rows, lay.cols
    blocked = lay.obstacles

    def fits(r: int, c: int) -> bool:
        return (0 <= r <= rows - k and 0 <= c <= cols - k
                and not blocked[r:r + k, c:c + k].any())

    def out(node: int) -> bool:
        return not corridor.cells.intersection(footprint_nodes(node, k, cols))

    start = agv.node
    seen = {start}
    queue = deque([(start, 0)])
    while queue:
        node, d = queue.popleft()
        if out(node):
            return d
        r, c = divmod(node, cols)
        for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            nr, nc = r + dr, c + dc
            nxt = nr * cols + nc
            if fits(nr, nc) and nxt not in seen:
                seen.add(nxt)
                queue.append((nxt, d + 1))
    return rows + cols
