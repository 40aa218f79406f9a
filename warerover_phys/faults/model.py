"""The fault model of an episode: random, scheduled and on-demand failures, their repairs,
and the safety corridors that open and close with them.

Each tick, before the scheduler runs (:meth:`FaultProcess.step`):

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

from typing import TYPE_CHECKING

import numpy as np

from ..errors import ScenarioError
from ..planning.base import TimedPath, occupancy
from ..planning.graph import GraphSet
from ..world import AgvState

if TYPE_CHECKING:
    from ..world import Agv, World

__all__ = ["FaultProcess"]


class FaultProcess:
    def __init__(self, world: World, executor=None) -> None:
        self.world = world
        self.executor = executor
        """The executor, asked to stop AGVs short of a new corridor (physics)."""
        self.spec = world.scenario.faults
        self.rng = world.rngs["faults"]
        self._next_corridor = 0
        self._corridor_of: dict[int, int] = {}
        """Failed AGV -> its corridor id."""

    # ------------------------------------------------------------------------- per tick

    def step(self) -> None:
        w = self.world
        for agv in w.agvs:
            if agv.state == AgvState.FAILED:
                w.fault_stats["down_ticks"] += 1
                if agv.repair_at is not None and agv.repair_at <= w.tick:
                    self.repair(agv.id)
        for fault in self.spec.scheduled:
            if fault.tick == w.tick and w.agvs[fault.agv].state != AgvState.FAILED:
                self.fail(fault.agv, fault.repair_ticks)
        rand = self.spec.random
        if rand.prob_per_tick > 0:
            draws = self.rng.random(len(w.agvs))
            span = self.rng.integers(rand.repair_ticks, (rand.repair_ticks_max or
                                                         rand.repair_ticks) + 1, len(w.agvs))
            for agv in w.agvs:
                if draws[agv.id] >= rand.prob_per_tick or not self._active(agv):
                    continue
                if rand.max_down is not None and self.down() >= rand.max_down:
                    break
                self.fail(agv.id, int(span[agv.id]))

    def down(self) -> int:
        return sum(1 for a in self.world.agvs if a.state == AgvState.FAILED)

    def _active(self, agv: Agv) -> bool:
        """Working on a trip (WareRover draws failures for AGVs with a task)."""
        return agv.state not in (AgvState.FAILED, AgvState.IDLE)

    # ------------------------------------------------------------------------- events

    def fail(self, agv_id: int, repair_ticks: int | None) -> None:
        """Fail an AGV now (``repair_ticks`` None: until :meth:`repair` is called)."""
        from .corridors import plan_corridor

        w = self.world
        repair_at = None if repair_ticks is None else w.tick + int(repair_ticks)
        agv = w.fail(agv_id, repair_at)
        # It stays where it is: a path that rests on its current state.
        w.reservations.commit(TimedPath(agv.id, w.tick, (agv.pos,)), agv.k)
        cells = occupancy(agv.pos, agv.k, w.layout.cols)
        try:
            corridor = plan_corridor(w.layout, self._next_corridor, agv.id, cells,
                                     self.spec.corridor_width_m, self.spec.corridor_margin_m)
        except ScenarioError as err:         # name the scenario file, not <scenario>
            raise err.with_file(w.scenario.source) if w.scenario.source else err from None
        self._next_corridor += 1
        self._corridor_of[agv.id] = corridor.id
        w.corridors[corridor.id] = corridor
        w.corridor_exempt[corridor.id] = set()
        w.log("corridor_opened", corridor=corridor.id, agv=agv.id,
              access=list(corridor.access), cells=len(corridor.cells))
        w.corridor_log.append({
            "id": corridor.id, "agv": agv.id, "open_tick": w.tick, "close_tick": None,
            "polygon": _rings(corridor.polygon), "zone": _rings(corridor.zone),
            "cells": sorted(corridor.cells)})
        self._close_cells()
        self._clear_paths(corridor)

    def repair(self, agv_id: int) -> None:
        w = self.world
        w.repair(agv_id)
        cid = self._corridor_of.pop(agv_id, None)
        if cid is not None:
            w.corridors.pop(cid, None)
            w.corridor_exempt.pop(cid, None)
            w.log("corridor_closed", corridor=cid, agv=agv_id)
            for entry in w.corridor_log:
                if entry["id"] == cid:
                    entry["close_tick"] = w.tick
            self._close_cells()

    # ------------------------------------------------------------------------- helpers

    def _close_cells(self) -> None:
        """New motion graphs with the open corridors' cells closed (distances are cached
        per graph set, so this costs one lazy rebuild per corridor event)."""
        w = self.world
        rows, cols = w.layout.rows, w.layout.cols
        masks = np.zeros((len(w.corridors), rows * cols), dtype=bool)
        for i, c in enumerate(w.corridors.values()):
            masks[i, list(c.cells)] = True
        w.graphs = GraphSet(w.layout, closed=masks.reshape(-1, rows, cols)
                            if len(masks) else None)

    def _clear_paths(self, corridor) -> None:
        """AGVs inside the corridor, or that can no longer stop before it, are exempt until
        they are out; AGVs whose remaining route would enter it stop as soon as they can
        and are replanned."""
        w = self.world
        cells, cols, t = corridor.cells, w.layout.cols, w.tick
        res = w.reservations
        stop_short = getattr(self.executor, "stop_short", None)
        for agv in w.agvs:
            if agv.id == corridor.agv:
                continue
            exempt = bool(cells.intersection(occupancy(agv.pos, agv.k, cols)))
            path = res.paths.get(agv.id)
            if path is not None:
                # Grid AGVs run ``delay`` ticks behind their plan; physics ones follow the
                # action graph, which holds what they have left.
                ahead = list(path.states[max(0, t - agv.delay - path.start_tick):])
                if stop_short is not None and getattr(self.executor, "_bound", False):
                    ahead = ahead + self.executor.route_states(agv.id)
                if any(cells.intersection(occupancy(s, agv.k, cols)) for s in ahead):
                    keep = [agv.pos]
                    if stop_short is not None and getattr(self.executor, "_bound", False):
                        exempt |= stop_short(agv.id, cells)
                    else:  # grid: finish the move in progress (to a standing state)
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
            if exempt:
                w.corridor_exempt[corridor.id].add(agv.id)


def _rings(shape) -> list[list[list[float]]]:
    """Exterior rings of a (multi)polygon as ``[[x, y], ...]`` lists in metres."""
    geoms = getattr(shape, "geoms", [shape])
    return [[[round(x, 4), round(y, 4)] for x, y in g.exterior.coords] for g in geoms
            if not g.is_empty]
