"""The one adapter between the web server and the simulation.

Everything the server knows about :class:`~warerover_phys.sim.Simulation` goes through
:class:`LiveSession`: build an episode from a scenario (with overrides), step it, read a
snapshot of it as arrays, fail / repair AGVs through the simulation's on-demand fault path,
add orders, and restart with another executor or seed. When the simulation core changes its
interface, this module is the only one to adapt.

What it reads of the core (the list to check when the core changes): ``Simulation(scenario,
seed)``, ``.step()``, ``.done``, ``.fail()`` / ``.repair()``, ``.planned``, ``.actual``,
``.last_report.poses`` (continuous poses on physics), ``.executor.trajectory()``; ``world.agvs`` (``id``, ``type_name``, ``spec``, ``k``, ``pos``,
``state``, ``loaded``, ``trip``, ``standing``, ``node``, ``ticks_per_move``,
``blocked_ticks``), ``world.layout``, ``world.tick``, ``world.status``,
``world.completed_tick``, ``world.orders``, ``Simulation.add_orders()``, ``world.corridors``,
``world.corridor_log``, ``world.fault_stats``, ``world.events``, ``world.goal_of()``,
``world.cell()``, ``world.reservations.paths``; ``config.load_scenario`` /
``scenario_from_dict``; ``render.trajectory`` (``recording_from_episode``, ``_centres``).

A snapshot reuses the renderer's conventions (:mod:`warerover_phys.render.trajectory`):
body centres in metres of a ``k x k`` AGV anchored at a flat node, a state between two cells
drawn half-way, headings from the last move.

>>> s = LiveSession.from_default(root=".")
>>> s.step(3)
3
>>> snap = s.snapshot()
>>> snap.x.shape == (len(s.sim.world.agvs),)
True
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..render.trajectory import _centres

__all__ = ["LiveSession", "LiveSnapshot", "DEFAULT_SCENARIO", "STATE_NAMES"]

log = logging.getLogger(__name__)

STATE_NAMES = ("idle", "to_shelf", "picking", "to_station", "handover", "returning",
               "placing", "failed")
FAILED = 7
NO_NODE = 0xFFFFFFFF
"""Padding of planned-path nodes in a frame."""

DEFAULT_SCENARIO: dict[str, Any] = {
    "name": "demo",
    "seed": 0,
    "max_ticks": 5000,
    "tick_s": 1.0,
    "layout": {
        "cell_m": 1.0, "size": [15, 20],
        "shelf_blocks": [{"origin": [4, 6], "rows": 2, "cols": 4},
                         {"origin": [4, 12], "rows": 2, "cols": 4},
                         {"origin": [9, 6], "rows": 2, "cols": 4},
                         {"origin": [9, 12], "rows": 2, "cols": 4}],
        "stations": [[3, 0], [4, 0], [5, 0], [6, 0], [8, 0], [9, 0], [10, 0], [11, 0]],
        "parking": [{"origin": [14, 6], "rows": 1, "cols": 9}],
        "access_points": [[0, 19]],
        "inventory": {"num_skus": 64, "skus_per_shelf": 4, "seed": 0},
    },
    "fleet": {"types": {"agv": {"footprint": 1, "body_m": [0.7, 0.7]}},
              "agvs": [{"type": "agv", "count": 9}]},
    "orders": {"pattern": "constant", "duration_ticks": 4000,
               "constant": {"batch": 3, "every_ticks": 10}},
    "scheduler": "ta",
    "planner": "astar",
    "executor": "grid",
}
"""The episode ``warerover serve`` shows when started without a scenario: the paper's
20 x 15 basic map with a steady order stream."""


@dataclass(frozen=True, eq=False)
class LiveSnapshot:
    """One moment of the live episode (arrays indexed by AGV id; metres, radians)."""

    tick: int
    time_s: float
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    state: np.ndarray
    loaded: np.ndarray
    paths: np.ndarray
    """``(N, H)`` flat anchor nodes of the planned states ahead (``NO_NODE`` padding)."""


class LiveSession:
    """A running episode that a server steps and reads; every call holds :attr:`lock`."""

    def __init__(self, scenario_path: Path | None, root: Path, *,
                 overrides: list[tuple[str, Any]] | None = None, seed: int | None = None,
                 path_len: int = 8) -> None:
        self.root = Path(root).resolve()
        self.scenario_path = scenario_path
        self.overrides = list(overrides or [])
        self.seed = seed
        self.path_len = path_len
        self.lock = threading.RLock()
        self.version = 0
        """Bumped on every change a client should see (tick, fault, restart)."""
        self.scene_version = 0
        """Bumped when the scene (layout, fleet) changes: a restart."""
        self._order_rng = np.random.default_rng(12345)
        self._build()

    @classmethod
    def from_default(cls, root: str | Path, **kw: Any) -> LiveSession:
        return cls(None, Path(root), **kw)

    # ------------------------------------------------------------------------- building

    def _load_scenario(self, overrides: list[tuple[str, Any]]):
        from ..config import load_scenario, scenario_from_dict

        if self.scenario_path is None:
            return scenario_from_dict(dict(DEFAULT_SCENARIO), source=None, overrides=overrides)
        return load_scenario(self.scenario_path, overrides)

    def _build(self) -> None:
        from ..sim import Simulation

        scenario = self._load_scenario(self.overrides)
        sim = Simulation(scenario, self.seed)
        self.scenario, self.sim = scenario, sim
        w = self.sim.world
        lay = w.layout
        self.cols, self.cell_m = lay.cols, float(lay.cell_m)
        self.k = np.array([a.k for a in w.agvs], dtype=np.int64)
        self._heading = np.zeros(len(w.agvs))
        self._last_xy: np.ndarray | None = None
        self.tp_points: list[tuple[int, int]] = [(0, 0)]
        self.wall_started = time.perf_counter()
        self.ticks_run = 0
        self.step_wall_s = 0.0
        self.scene_version += 1
        self.version += 1

    def restart(self, executor: str | None = None, seed: int | None = None,
                planner: str | None = None) -> None:
        """Start the episode again (optionally with another executor, planner or seed)."""
        with self.lock:
            old = (list(self.overrides), self.seed)
            for key, value in (("executor.name", executor), ("planner.name", planner)):
                if value is not None:
                    self.overrides = [(k, v) for k, v in self.overrides if k != key]
                    self.overrides.append((key, value))
            if seed is not None:
                self.seed = seed
            try:
                self._build()
            except Exception:
                self.overrides, self.seed = old     # keep the episode that runs
                raise

    # ------------------------------------------------------------------------- stepping

    @property
    def done(self) -> bool:
        return self.sim.done

    @property
    def executor_name(self) -> str:
        return str(self.scenario.executor.name)

    def step(self, count: int = 1) -> int:
        """Run up to ``count`` ticks (fewer if the episode ends); returns ticks run."""
        ran = 0
        with self.lock:
            for _ in range(count):
                if self.sim.done:
                    break
                t0 = time.perf_counter()
                self.sim.step()
                self.step_wall_s += time.perf_counter() - t0
                self.ticks_run += 1
                ran += 1
                w = self.sim.world
                done = len(w.completed_tick)
                if done != self.tp_points[-1][1] or w.tick % 10 == 0:
                    self.tp_points.append((w.tick, done))
            if ran:
                self.version += 1
        return ran

    # ------------------------------------------------------------------------- control

    def _check_agv(self, agv_id: int) -> None:
        n = len(self.sim.world.agvs)
        if not 0 <= agv_id < n:
            raise ValueError(f"AGV {agv_id} does not exist (ids 0..{n - 1})")

    def fail(self, agv_id: int, repair_ticks: int | None = None) -> None:
        """Fail an AGV through the simulation's on-demand fault path."""
        with self.lock:
            self._check_agv(agv_id)
            if self.sim.world.agvs[agv_id].state == FAILED:
                raise ValueError(f"AGV {agv_id} has already failed")
            self.sim.fail(agv_id, repair_ticks)
            self.version += 1

    def repair(self, agv_id: int) -> None:
        with self.lock:
            self._check_agv(agv_id)
            if self.sim.world.agvs[agv_id].state != FAILED:
                raise ValueError(f"AGV {agv_id} has not failed")
            self.sim.repair(agv_id)
            self.version += 1

    def add_orders(self, count: int, station: int | None = None,
                   sku: int | None = None) -> list[int]:
        """Add ``count`` orders now (random SKU and station unless given); returns their ids.

        Ids start at 1,000,000 so they never meet the scenario stream's ids."""
        from ..orders import Order

        with self.lock:
            w = self.sim.world
            lay = w.layout
            sizes = lay.sku_sizes
            if station is not None and not 0 <= station < len(lay.stations):
                raise ValueError(f"station {station} does not exist (0..{len(lay.stations) - 1})")
            if sku is not None and not 0 <= sku < len(sizes):
                raise ValueError(f"SKU {sku} does not exist (0..{len(sizes) - 1})")
            first = max([10**6 - 1, *w.orders.keys()]) + 1
            rng = self._order_rng
            orders = []
            for i in range(count):
                s = int(rng.integers(len(sizes))) if sku is None else sku
                st = int(rng.integers(len(lay.stations))) if station is None else station
                orders.append(Order(first + i, w.tick, s, st, int(sizes[s])))
            self.sim.add_orders(orders)
            self.version += 1
            return [o.id for o in orders]

    # ------------------------------------------------------------------------- reading

    def scene(self) -> dict[str, Any]:
        """What stays the same during an episode: layout and fleet (JSON-ready)."""
        with self.lock:
            w = self.sim.world
            lay = w.layout
            return {
                "name": self.scenario.name, "rows": lay.rows, "cols": lay.cols,
                "cell_m": self.cell_m, "tick_s": float(self.scenario.tick_s),
                "grid": "".join(str(int(v)) for v in np.asarray(lay.grid).ravel()),
                "shelves": [[s.anchor[0], s.anchor[1], s.size] for s in lay.shelves],
                "stations": [list(s) for s in lay.stations],
                "access_points": [list(a) for a in lay.access_points],
                "agvs": [{"id": a.id, "type": a.type_name, "k": a.k,
                          "body_m": [float(v) for v in a.spec.body_m]} for a in w.agvs],
                "executor": self.executor_name,
                "planner": str(self.scenario.planner.name),
                "scheduler": str(self.scenario.scheduler.name),
                "max_ticks": int(self.scenario.max_ticks),
                "seed": int(self.scenario.seed if self.seed is None else self.seed),
            }

    def _poses(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        w = self.sim.world
        report = self.sim.last_report
        if report is not None and report.poses is not None:
            poses = report.poses
            return poses[:, 0].copy(), poses[:, 1].copy(), poses[:, 2].copy()
        a = np.array([g.pos[0] for g in w.agvs], dtype=np.int64)
        b = np.array([g.pos[1] for g in w.agvs], dtype=np.int64)
        xy = 0.5 * (_centres(a, self.k, self.cols, self.cell_m)
                    + _centres(b, self.k, self.cols, self.cell_m))
        if self._last_xy is not None and self._last_xy.shape == xy.shape:
            d = xy - self._last_xy
            moved = np.abs(d).sum(axis=1) > 1e-9
            self._heading = np.where(moved, np.arctan2(d[:, 1], d[:, 0]), self._heading)
        self._last_xy = xy
        return xy[:, 0].copy(), xy[:, 1].copy(), self._heading.copy()

    def _paths_ahead(self) -> np.ndarray:
        w = self.sim.world
        h = self.path_len
        out = np.full((len(w.agvs), h), NO_NODE, dtype=np.uint32)
        if h == 0:
            return out
        paths = w.reservations.paths
        tick = w.tick
        for aid, path in paths.items():
            if aid >= len(out):
                continue
            i0 = tick - path.start_tick
            states = path.states[max(i0, 0):]
            last = w.agvs[aid].pos[1]
            j = 0
            for s in states:
                node = s[1]
                if node == last:
                    continue
                out[aid, j] = node
                last = node
                j += 1
                if j == h:
                    break
        return out

    def snapshot(self) -> LiveSnapshot:
        with self.lock:
            w = self.sim.world
            x, y, heading = self._poses()
            return LiveSnapshot(
                tick=int(w.tick), time_s=float(w.tick * self.scenario.tick_s), x=x, y=y,
                heading=heading,
                state=np.array([int(a.state) for a in w.agvs], dtype=np.uint8),
                loaded=np.array([a.loaded for a in w.agvs], dtype=np.uint8),
                paths=self._paths_ahead())

    def status(self) -> dict[str, Any]:
        """Counters and open corridors (JSON-ready)."""
        with self.lock:
            w = self.sim.world
            done = len(w.completed_tick)
            total = len(w.status)
            tick = int(w.tick)
            corridors = [{"id": e["id"], "agv": e["agv"], "zone": e["zone"],
                          "cells": e["cells"]} for e in w.corridor_log
                         if e["close_tick"] is None and e["id"] in w.corridors]
            wall = self.step_wall_s
            return {
                "tick": tick, "time_s": tick * float(self.scenario.tick_s),
                "orders_total": total, "orders_done": done,
                "orders_pending": sum(1 for s in w.status.values() if int(s) == 0),
                "throughput": done / tick if tick else 0.0,
                "failed": [a.id for a in w.agvs if a.state == FAILED],
                "corridors": corridors,
                "done": self.sim.done,
                "executor": self.executor_name,
                "sim_ticks_per_s": self.ticks_run / wall if wall > 0 else 0.0,
                "tp_points": self.tp_points[-400:],
                "intrusions": int(w.fault_stats.get("corridor_intrusions", 0)),
            }

    def agv_info(self, agv_id: int) -> dict[str, Any]:
        """What a tooltip shows: id, type, task, speed, whom it waits for."""
        with self.lock:
            self._check_agv(agv_id)
            w = self.sim.world
            agv = w.agvs[agv_id]
            report = self.sim.last_report
            speed = 0.0
            if report is not None and report.speeds is not None:
                speed = float(report.speeds[agv_id])
            elif not agv.standing:
                speed = self.cell_m / float(self.scenario.tick_s) / max(1, agv.ticks_per_move)
            trip = None
            if agv.trip is not None:
                trip = {"id": agv.trip.id, "shelf": agv.trip.shelf,
                        "orders": list(agv.trip.orders), "stops": list(agv.trip.stops),
                        "stop": agv.trip.stop_idx}
            goal = w.goal_of(agv)
            return {
                "id": agv.id, "type": agv.type_name, "k": agv.k,
                "state": STATE_NAMES[int(agv.state)], "loaded": bool(agv.loaded),
                "cell": list(w.cell(agv.node)), "goal": None if goal is None
                else list(w.cell(goal)), "speed_mps": round(speed, 3), "trip": trip,
                "waiting_for": self._waiting_for(agv_id), "blocked_ticks": agv.blocked_ticks,
            }

    def _waiting_for(self, agv_id: int) -> list[int]:
        """AGVs standing on the cells of ``agv_id``'s next planned move."""
        from ..planning.base import occupancy

        w = self.sim.world
        path = w.reservations.paths.get(agv_id)
        agv = w.agvs[agv_id]
        if path is None or agv.state == FAILED:
            return []
        nxt = None
        for s in path.states[max(0, w.tick - path.start_tick):]:
            if s[1] != agv.node:
                nxt = s[1]
                break
        if nxt is None:
            return []
        want = set(occupancy((nxt, nxt), agv.k, self.cols))
        return [o.id for o in w.agvs if o.id != agv_id
                and want & set(occupancy(o.pos, o.k, self.cols))]

    def recording(self):
        """The episode so far as a :class:`~warerover_phys.render.trajectory.Recording`
        (the renderer's own builder: physics trajectory, or the grid executor's states)."""
        from ..render.trajectory import recording_from_episode
        from ..sim import EpisodeResult

        with self.lock:
            sim = self.sim
            result = EpisodeResult(
                metrics={}, events=list(sim.world.events), planned=list(sim.planned),
                actual={k: list(v) for k, v in sim.actual.items()}, world=sim.world,
                trajectory=sim.executor.trajectory())
            return recording_from_episode(result)

    def agv_at(self, x: float, y: float) -> int | None:
        """The AGV whose body centre is nearest to ``(x, y)`` metres (within a cell)."""
        snap = self.snapshot()
        d = (snap.x - x) ** 2 + (snap.y - y) ** 2
        i = int(d.argmin())
        return i if d[i] <= (self.cell_m * max(1, int(self.k[i]))) ** 2 else None
