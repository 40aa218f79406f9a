"""Book-keeping of corridor intrusions, shared by both executors.

An intrusion is counted once per (AGV, corridor) episode: from the check in which the AGV
is first found in the corridor's protected zone (grid: on one of its cells) until a check
finds it out again. AGVs listed in ``world.corridor_exempt`` (inside, or committed to enter,
when the corridor opened) are leaving and not counted; they lose the exemption once none of
their cells is a corridor cell (:func:`update_exemptions`, once per tick).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..world import World

__all__ = ["record_intrusions", "update_exemptions"]


def update_exemptions(world: World, route_of: Callable[[int], list] | None = None) -> None:
    """Drop the exemption of every AGV that is out of its corridor's cells and whose
    remaining committed route (``route_of(agv)``: states; the executor knows it) does not
    lead back in."""
    from ..planning.base import occupancy

    cols = world.layout.cols
    for cid, exempt in world.corridor_exempt.items():
        cells = world.corridors[cid].cells
        for agv in list(exempt):
            a = world.agvs[agv]
            states = [a.pos] + (route_of(agv) if route_of is not None else [])
            if not any(cells.intersection(occupancy(s, a.k, cols)) for s in states):
                exempt.discard(agv)


def record_intrusions(world: World, hits: Iterable[tuple[int, int, float]],
                      unit: str = "m") -> int:
    """Update the books with this check's ``(agv, corridor, depth)`` hits; returns how many
    new intrusions began."""
    current: dict[tuple[int, int], float] = {}
    for agv, cid, depth in hits:
        key = (agv, cid)
        current[key] = max(depth, current.get(key, 0.0))
    ongoing = world.__dict__.setdefault("_intruding", {})
    new = 0
    for (agv, cid), depth in current.items():
        if agv in world.corridor_exempt.get(cid, ()):
            continue
        if (agv, cid) not in ongoing:
            new += 1
            world.fault_stats["corridor_intrusions"] += 1
            world.log("corridor_intrusion", agv=agv, corridor=cid, depth=round(depth, 4),
                      unit=unit)
        ongoing[(agv, cid)] = max(depth, ongoing.get((agv, cid), 0.0))
    for key in list(ongoing):
        if key not in current:
            del ongoing[key]
    return new
