"""The fault model of an episode: random, scheduled and on-demand failures, their repairs,
and the safety corridors that open and close with them.

The model only *draws* events; the loop (:mod:`warerover_phys.sim`) applies them with
:func:`open_failure` and :func:`close_failure`, the only code that changes the world for a
fault. Each tick, before the scheduler runs, in three stages (each drawn after the one
before it has been applied):

1. AGVs whose repair is due are repaired and their corridors close;
2. scheduled failures of this tick fire (``faults.scheduled``);
3. every *active* AGV (one working on a trip, not idle) fails with
   probability ``faults.random.prob_per_tick``, at most ``max_down`` AGVs down at once; a
   repair takes ``repair_ticks`` ticks, or a number drawn uniformly from
   [``repair_ticks``, ``repair_ticks_max``]. The draws come from the episode's ``faults``
   generator, one vector per tick, so they do not depend on what else happens.

A failure stops the AGV where it is (the physics executor brakes it within its deceleration
limit) and opens a corridor (:func:`~.corridors.plan_corridor`) from it to the nearest
maintenance access point. While a corridor is open its cells are closed for planning
(:class:`~warerover_phys.planning.graph.GraphSet` with ``closed``): nobody enters, AGVs
already inside leave. Every AGV whose committed path would enter the corridor is stopped at
the end of its current move and replanned (counted in ``failure_replans``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ScenarioError
from ..planning.graph import GraphSet
from ..planning.paths import TimedPath, occupancy
from ..world import AgvState

if TYPE_CHECKING:
    from ..config import FaultsSpec
    from ..executors.base import Executor, TickView
    from ..world import Agv, World
    from .corridors import Corridor

__all__ = ["FaultEvent", "FaultModel", "open_failure", "close_failure"]


@dataclass(frozen=True, slots=True)
class FaultEvent:
    kind: str
    """``fail`` or ``repair``."""
    agv: int
    repair_ticks: int | None = None
    """``fail``: ticks until the repair (None: only on demand)."""


class FaultModel:
    """Draws the failures and repairs of each tick from the episode's ``faults`` generator.
    It reads the AGVs (state, ``repair_at``) and never changes them."""

    def __init__(self, spec: FaultsSpec, rng: np.random.Generator) -> None:
        self.spec = spec
        self.rng = rng

    def repairs(self, tick: int, agvs: Sequence[Agv]) -> list[FaultEvent]:
        """Stage 1: failed AGVs whose repair is due."""
        return [FaultEvent("repair", a.id) for a in agvs if a.state == AgvState.FAILED
                and a.repair_at is not None and a.repair_at <= tick]

    def scheduled(self, tick: int, agvs: Sequence[Agv]) -> list[FaultEvent]:
        """Stage 2: the scenario's scheduled failures of this tick (of working AGVs)."""
        out, down = [], {a.id for a in agvs if a.state == AgvState.FAILED}
        for fault in self.spec.scheduled:
            if fault.tick == tick and fault.agv not in down:
                out.append(FaultEvent("fail", fault.agv, fault.repair_ticks))
                down.add(fault.agv)
        return out

    def random(self, agvs: Sequence[Agv]) -> list[FaultEvent]:
        """Stage 3: every active AGV fails with ``prob_per_tick`` (at most ``max_down``
        down at once). One vector of draws per tick, whatever happens."""
        rand = self.spec.random
        if rand.prob_per_tick <= 0:
            return []
        n = len(agvs)
        draws = self.rng.random(n)
        span = self.rng.integers(rand.repair_ticks,
                                 (rand.repair_ticks_max or rand.repair_ticks) + 1, n)
        down = sum(1 for a in agvs if a.state == AgvState.FAILED)
        out = []
        for agv in agvs:
            if draws[agv.id] >= rand.prob_per_tick or not _active(agv):
                continue
            if rand.max_down is not None and down >= rand.max_down:
                break
            out.append(FaultEvent("fail", agv.id, int(span[agv.id])))
            down += 1
        return out


def _active(agv: Agv) -> bool:
    """Working on a trip (WareRover draws failures for AGVs with a task)."""
    return agv.state not in (AgvState.FAILED, AgvState.IDLE)


# ----------------------------------------------------------------------------- applying

def open_failure(world: World, agv_id: int, repair_ticks: int | None,
                 executor: Executor, view: TickView) -> Corridor:
    """Fail an AGV now: it stops where it is, a corridor opens around it, its cells close
    in the motion graphs and every AGV whose route would enter stops short (the executor
    says how: see :meth:`Executor.stop_short`)."""
    from .corridors import plan_corridor

    w = world
    spec = w.scenario.faults
    repair_at = None if repair_ticks is None else w.tick + int(repair_ticks)
    agv = w.fail(agv_id, repair_at)
    # It stays where it is: a path that rests on its current state.
    w.reservations.commit(TimedPath(agv.id, w.tick, (agv.pos,)), agv.k)
    cells = occupancy(agv.pos, agv.k, w.layout.cols)
    try:
        corridor = plan_corridor(w.layout, len(w.corridor_log), agv.id, cells,
                                 spec.corridor_width_m, spec.corridor_margin_m)
    except ScenarioError as err:  # name the scenario file, not <scenario>
        raise err.with_file(w.scenario.source) if w.scenario.source else err from None
    w.corridors[corridor.id] = corridor
    w.log("corridor_opened", corridor=corridor.id, agv=agv.id,
          access=list(corridor.access), cells=len(corridor.cells))
    w.corridor_log.append({
        "id": corridor.id, "agv": agv.id, "open_tick": w.tick, "close_tick": None,
        "polygon": _rings(corridor.polygon), "zone": _rings(corridor.zone),
        "rects": [list(r) for r in corridor.rects], "margin_m": corridor.margin_m,
        "cells": sorted(corridor.cells)})
    _close_cells(w)
    _clear_paths(w, corridor, executor, view)
    return corridor


def close_failure(world: World, agv_id: int) -> None:
    """Repair a failed AGV now; its corridor closes and its cells reopen. If it stands in
    another AGV's open corridor (that one failed while it was down), it is caught there as
    if that corridor had just opened: a bounded time to leave, not an intruder."""
    w = world
    w.repair(agv_id)
    cid = next((c for c, corridor in w.corridors.items() if corridor.agv == agv_id), None)
    if cid is not None:
        w.corridors.pop(cid, None)
        w.corridor_book.closed(w, cid)
        w.log("corridor_closed", corridor=cid, agv=agv_id)
        for entry in w.corridor_log:
            if entry["id"] == cid:
                entry["close_tick"] = w.tick
        _close_cells(w)
    _catch_repaired(w, agv_id)


def _catch_repaired(w: World, agv_id: int) -> None:
    """AGV ``agv_id``, repaired now, is caught by every open corridor whose cells it stands
    on (it was down when they opened, so :func:`_clear_paths` left it out)."""
    from .intrusion_log import exit_bound_s

    agv = w.agvs[agv_id]
    mine = set(occupancy(agv.pos, agv.k, w.layout.cols))
    for corridor in w.corridors.values():
        if corridor.agv == agv_id or not mine & corridor.cells:
            continue
        bound = exit_bound_s(w, agv, corridor)
        w.corridor_book.catch(agv_id, corridor.id, w.tick * w.scenario.tick_s, bound,
                              "repaired_inside")
        w.log("corridor_caught", agv=agv_id, corridor=corridor.id, reason="repaired_inside",
              bound_s=round(bound, 3))


def _close_cells(w: World) -> None:
    """New motion graphs with the open corridors' cells closed (distances are cached
    per graph set, so this costs one lazy rebuild per corridor event)."""
    rows, cols = w.layout.rows, w.layout.cols
    masks = np.zeros((len(w.corridors), rows * cols), dtype=bool)
    for i, c in enumerate(w.corridors.values()):
        masks[i, list(c.cells)] = True
    w.graphs = GraphSet(w.layout, closed=masks.reshape(-1, rows, cols)
                        if len(masks) else None)


def _clear_paths(w: World, corridor: Corridor, executor: Executor, view: TickView) -> None:
    """AGVs inside the corridor, or that can no longer stop before it, are caught: they get
    a bounded time to leave (:func:`~.intrusion_log.exit_bound_s`), after which their time
    inside counts as intrusion; AGVs whose remaining route would enter it stop as soon as
    they can and are replanned."""
    from .intrusion_log import exit_bound_s

    cells, cols, t = corridor.cells, w.layout.cols, w.tick
    res = w.reservations
    for agv in w.agvs:
        if agv.id == corridor.agv:
            continue
        inside = bool(cells.intersection(occupancy(agv.pos, agv.k, cols)))
        exempt = inside
        path = res.paths.get(agv.id)
        if path is not None:
            # Grid AGVs run ``delay`` ticks behind their plan; physics ones follow the
            # action graph, which holds what they have left (``remaining``).
            ahead = list(path.states[max(0, t - agv.delay - path.start_tick):])
            ahead += executor.remaining(agv.id)
            if any(cells.intersection(occupancy(s, agv.k, cols)) for s in ahead):
                keep = [agv.pos]
                handled, enters = executor.stop_short(agv.id, cells, view)
                if handled:
                    exempt |= enters
                else:  # finish the move in progress (to a standing state)
                    for s in ahead[1:]:
                        if keep[-1][0] == keep[-1][1]:
                            break
                        keep.append(s)
                    exempt |= any(cells.intersection(occupancy(s, agv.k, cols))
                                  for s in keep)
                if agv.state != AgvState.FAILED:  # a failed one keeps standing
                    res.commit(TimedPath(agv.id, t, tuple(keep)), agv.k)
                    agv.retry_at = t
                    w.fault_stats["failure_replans"] += 1
        if exempt and agv.state != AgvState.FAILED:  # a failed one is not counted anyway
            bound = exit_bound_s(w, agv, corridor)
            reason = "inside" if inside else "cannot_stop"
            w.corridor_book.catch(agv.id, corridor.id, t * w.scenario.tick_s, bound, reason)
            w.log("corridor_caught", agv=agv.id, corridor=corridor.id, reason=reason,
                  bound_s=round(bound, 3))


def _rings(shape) -> list[list[list[float]]]:
    """Exterior rings of a (multi)polygon as ``[[x, y], ...]`` lists in metres."""
    geoms = getattr(shape, "geoms", [shape])
    return [[[round(x, 4), round(y, 4)] for x, y in g.exterior.coords] for g in geoms
            if not g.is_empty]
