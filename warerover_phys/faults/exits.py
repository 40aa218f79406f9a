"""Where AGVs caught inside a safety corridor go: the nearest free spot outside it.

An AGV caught inside a corridor when it opens (:meth:`~.book.CorridorBook.catch`, reason
``inside``) has a bounded time to leave (:func:`~.intrusion_log.exit_bound_s`). Its own goal
may lie inside the corridor (its shelf, its station) or be unreachable while the corridor is
open, and then no plan takes it out: it would wait for the repair and overrun. The loop
asks :func:`exit_spots` each tick which caught AGVs still need to be sent out and where to,
and makes that spot the AGV's goal for a while (a yield, planned through the planner like
any goal; the motion graphs let an AGV inside a closed area only move nearer its edge).

This module only reads the world: the loop (:mod:`warerover_phys.sim`) applies the answer.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..planning.paths import occupancy

if TYPE_CHECKING:
    from ..world import World

__all__ = ["exit_spots", "inside_open_corridor"]

FAILED_STATE = 7
"""``world.AgvState.FAILED``."""
_WORK_STATES = (2, 4, 6)
"""``world.AgvState`` PICKING, HANDOVER, PLACING: the AGV works in place."""


def inside_open_corridor(world: World, agv_id: int) -> int | None:
    """The id of an open corridor that AGV ``agv_id`` has an unsettled exit grant for and
    whose cells it stands or drives on now (None: none)."""
    agv = world.agvs[agv_id]
    cols = world.layout.cols
    mine = set(occupancy(agv.pos, agv.k, cols))
    for (a, cid), g in world.corridor_book.grants.items():
        if a != agv_id or g.settled or cid not in world.corridors:
            continue
        if mine & world.corridors[cid].cells:
            return cid
    return None


def exit_spots(world: World, already: dict[int, int] | None = None) -> dict[int, int]:
    """Caught AGVs that must be sent out now -> the anchor to go to (the nearest plain floor
    anchor outside every open corridor that nobody holds for good; see
    :func:`~warerover_phys.planning.search.astar.nearest_free_anchor`). Only AGVs that stand,
    are not down and do not work in place are sent (one that works finishes first, then
    leaves); ``already`` (agv -> spot) are AGVs sent before whose spot is still good,
    left out."""
    from ..planning.base import AgentRequest
    from ..planning.search.astar import nearest_free_anchor

    already = already or {}
    out: dict[int, int] = {}
    closed = set()
    for c in world.corridors.values():
        closed |= c.cells
    cols = world.layout.cols
    rows = world.layout.rows
    rim = set()  # cells next to a corridor
    for cell in closed:
        r, c = divmod(cell, cols)
        rim.update(rr * cols + cc for rr, cc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1))
                   if 0 <= rr < rows and 0 <= cc < cols)
    rim -= closed
    taken = set()  # spots given to others (now or before): one AGV per spot
    for a, spot in already.items():
        taken.update(occupancy((spot, spot), world.agvs[a].k, cols))
    for agv in world.agvs:
        if agv.state == FAILED_STATE or int(agv.state) in _WORK_STATES or not agv.standing:
            continue
        if inside_open_corridor(world, agv.id) is None:
            continue
        spot = already.get(agv.id)
        if spot is not None and not closed.intersection(occupancy((spot, spot), agv.k, cols)):
            continue
        shelf = agv.trip.shelf if agv.loaded and agv.trip is not None else None
        graph = world.graphs.get(agv.k, agv.loaded, shelf)
        probe = AgentRequest(agv.id, agv.node, agv.node, k=agv.k)
        radius = 2 * (world.layout.rows + world.layout.cols)
        # Not on the corridor's edge if it can be helped: an AGV waiting there could
        # stand in the way out of the next one.
        spot = None
        for avoid in (closed | rim | taken, closed | taken):
            spot = nearest_free_anchor(graph, world.reservations, probe, radius=radius,
                                       keep_clear=world.keep_clear(),
                                       avoid=frozenset(avoid))
            if spot is not None:
                break
        if spot is not None:
            out[agv.id] = spot
            taken.update(occupancy((spot, spot), agv.k, cols))
    return out
