"""Recorded episodes for rendering: load ``trajectories.npz`` or build the same arrays from a
grid-executor :class:`~warerover_phys.sim.EpisodeResult`, and sample them at any time.

A :class:`Recording` holds the trajectory arrays (the dict of
``PhysicsExecutor.trajectory``: ``t`` (T,), ``x``, ``y``, ``heading``, ``state``, ``loaded``
(T, N), ``footprint``, ``body_m``, ``cell_m``, ``tick_s``, ``grid``, ``corridors_json``) plus
what the heads-up line and the planned paths need: order arrival and completion ticks (from
the episode's events) and the committed plans. :meth:`Recording.at` interpolates a snapshot
at any simulated time (positions linear, headings along the shorter arc), so the video frame
rate is independent of the physics step and of the recording rate.

No OpenCV here: this module is numpy only.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import WareroverError

if TYPE_CHECKING:
    from ..sim import EpisodeResult
    from .frame import Scene, Snapshot

__all__ = ["Recording", "load_trajectory", "recording_from_episode", "grid_trajectory"]

FAILED = 7
"""``AgvState.FAILED``."""
IDLE = 0
TO_SHELF = 1
TO_STATION = 3
REQUIRED = ("t", "x", "y", "heading", "state", "loaded", "footprint", "body_m", "cell_m",
            "tick_s", "grid")


@dataclass(frozen=True, eq=False)
class Recording:
    """An episode's executed poses and the events a renderer shows, sampled by :meth:`at`."""

    t: np.ndarray
    """Sample times (T,), seconds, increasing."""
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    state: np.ndarray
    loaded: np.ndarray
    footprint: np.ndarray
    body_m: np.ndarray
    cell_m: float
    tick_s: float
    grid: np.ndarray
    corridors: tuple[dict, ...] = ()
    order_created: np.ndarray | None = None
    """Arrival tick of every order (sorted); None when the events are unknown."""
    order_done: np.ndarray | None = None
    """Completion tick of every completed order (sorted)."""
    plans: dict[int, list[tuple[int, np.ndarray]]] = field(default_factory=dict)
    """AGV -> committed plans ``(start tick, (L, 2) centre points in metres)``, by tick."""
    _scene: list = field(default_factory=list, repr=False)
    _plan_index: list = field(default_factory=list, repr=False)

    @property
    def num_agvs(self) -> int:
        return int(self.x.shape[1])

    @property
    def start_s(self) -> float:
        return float(self.t[0])

    @property
    def end_s(self) -> float:
        return float(self.t[-1])

    @property
    def ticks(self) -> int:
        """The last tick covered by the recording."""
        return int(math.floor(self.end_s / self.tick_s + 1e-9))

    def scene(self) -> Scene:
        """The static part of every frame (one object, so its background is drawn once)."""
        if not self._scene:
            from .frame import Scene

            self._scene.append(Scene(grid=self.grid, cell_m=self.cell_m, body_m=self.body_m,
                                     footprint=self.footprint))
        return self._scene[0]

    def at(self, time_s: float, path_ticks: int = 0) -> Snapshot:
        """The state at simulated time ``time_s`` (clamped to the recording): poses
        interpolated between the two samples around it, discrete fields from the earlier."""
        from .frame import Snapshot

        t = self.t
        q = min(max(float(time_s), float(t[0])), float(t[-1]))
        i = int(np.searchsorted(t, q, side="right")) - 1
        i = min(max(i, 0), len(t) - 1)
        j = min(i + 1, len(t) - 1)
        w = 0.0 if j == i else (q - float(t[i])) / (float(t[j]) - float(t[i]))
        x = self.x[i] + w * (self.x[j] - self.x[i])
        y = self.y[i] + w * (self.y[j] - self.y[i])
        h0 = self.heading[i]
        dh = (self.heading[j] - h0 + np.pi) % (2 * np.pi) - np.pi
        heading = h0 + w * dh
        k = j if w >= 1.0 else i
        state, loaded = self.state[k], self.loaded[k]
        tick = q / self.tick_s
        corridors = tuple(c for c in self.corridors
                          if c["open_tick"] <= tick and (c["close_tick"] is None
                                                         or tick < c["close_tick"]))
        done = total = None
        if self.order_created is not None and self.order_done is not None:
            total = int(np.searchsorted(self.order_created, tick, side="right"))
            done = int(np.searchsorted(self.order_done, tick, side="right"))
        paths = self._paths_ahead(tick, x, y, path_ticks) if path_ticks > 0 else None
        return Snapshot(scene=self.scene(), time_s=q, tick_s=self.tick_s, x=x, y=y,
                        heading=heading, state=state, loaded=loaded, corridors=corridors,
                        orders_done=done, orders_total=total, paths=paths)

    def _paths_ahead(self, tick: float, x: np.ndarray, y: np.ndarray,
                     horizon: int) -> list[np.ndarray | None]:
        """For each AGV, its current position followed by the next ``horizon`` points of the
        latest plan committed by ``tick`` (from the plan point nearest to where it is)."""
        if not self._plan_index:
            self._plan_index.append({aid: np.array([p[0] for p in plans], dtype=np.float64)
                                     for aid, plans in self.plans.items() if plans})
        index = self._plan_index[0]
        out: list[np.ndarray | None] = [None] * self.num_agvs
        now = int(tick)
        for aid, starts in index.items():
            if aid >= self.num_agvs:
                continue
            n = int(starts.searchsorted(tick, side="right")) - 1
            if n < 0:
                continue
            start, points = self.plans[aid][n]
            lo = max(0, min(now - start - 2, len(points) - 1))
            window = points[lo:lo + horizon + 4]
            hx, hy = x[aid], y[aid]
            near = lo + int(((window[:, 0] - hx) ** 2 + (window[:, 1] - hy) ** 2).argmin())
            ahead = points[near + 1:near + 1 + horizon]
            if len(ahead):
                pts = np.empty((len(ahead) + 1, 2))
                pts[0] = hx, hy
                pts[1:] = ahead
                out[aid] = pts
        return out


# ------------------------------------------------------------------------------ building


def _centres(nodes: np.ndarray, k: int, cols: int, cell_m: float) -> np.ndarray:
    """Body centres (metres) of a ``k x k`` AGV anchored at flat ``nodes``."""
    r, c = np.divmod(np.asarray(nodes, dtype=np.int64), cols)
    return np.stack([(c + k / 2) * cell_m, (r + k / 2) * cell_m], axis=-1)


def _plans(planned: list[dict], footprint: np.ndarray, cols: int, cell_m: float,
           ) -> dict[int, list[tuple[int, np.ndarray]]]:
    """Committed plans as centre points; ``states`` are ``[from, to]`` flat nodes or
    ``[[row, col], [row, col]]`` cells (``paths.json``)."""
    out: dict[int, list[tuple[int, np.ndarray]]] = {}
    for p in planned:
        aid, states = int(p["agv"]), p["states"]
        if not states or aid >= len(footprint):
            continue
        arr = np.asarray(states, dtype=np.float64)
        if arr.ndim == 3:                       # cells -> nodes
            arr = arr[..., 0] * cols + arr[..., 1]
        pts = 0.5 * (_centres(arr[:, 0], int(footprint[aid]), cols, cell_m)
                     + _centres(arr[:, 1], int(footprint[aid]), cols, cell_m))
        out.setdefault(aid, []).append((int(p["tick"]), pts))
    for plans in out.values():
        plans.sort(key=lambda p: p[0])
    return out


def _orders(events: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    created = sorted(e["tick"] for e in events if e.get("event") == "order_created")
    done = sorted(e["tick"] for e in events if e.get("event") == "order_completed")
    return np.asarray(created, dtype=np.float64), np.asarray(done, dtype=np.float64)


def _from_dict(traj: dict, events: list[dict] | None, planned: list[dict] | None,
               source: str) -> Recording:
    missing = [k for k in REQUIRED if k not in traj]
    if missing:
        raise WareroverError(f"{source}: not a trajectory file (missing {', '.join(missing)})")
    t = np.asarray(traj["t"], dtype=np.float64)
    if t.ndim != 1 or len(t) == 0:
        raise WareroverError(f"{source}: trajectory has no samples")
    grid = np.asarray(traj["grid"])
    cell_m, tick_s = float(traj["cell_m"]), float(traj["tick_s"])
    footprint = np.asarray(traj["footprint"], dtype=np.int64)
    corridors: tuple[dict, ...] = ()
    if "corridors_json" in traj:
        corridors = tuple(json.loads(str(traj["corridors_json"])))
    created = done = None
    if events is not None:
        created, done = _orders(events)
    plans = _plans(planned, footprint, grid.shape[1], cell_m) if planned else {}
    return Recording(
        t=t, x=np.asarray(traj["x"], dtype=np.float64), y=np.asarray(traj["y"], dtype=np.float64),
        heading=np.asarray(traj["heading"], dtype=np.float64),
        state=np.asarray(traj["state"], dtype=np.int8),
        loaded=np.asarray(traj["loaded"], dtype=bool), footprint=footprint,
        body_m=np.asarray(traj["body_m"], dtype=np.float64), cell_m=cell_m, tick_s=tick_s,
        grid=grid, corridors=corridors, order_created=created, order_done=done, plans=plans)


def load_trajectory(path: str | Path) -> Recording:
    """Load ``trajectories.npz`` (a file, or a run folder holding one). ``events.jsonl`` and
    ``paths.json`` beside it, when present, give the order counts and the planned paths."""
    p = Path(path)
    if p.is_dir():
        p = p / "trajectories.npz"
    if not p.is_file():
        raise WareroverError(f"{p}: no such trajectory file")
    try:
        with np.load(p, allow_pickle=False) as data:
            traj = {k: data[k] for k in data.files}
    except (OSError, ValueError) as err:
        raise WareroverError(f"{p}: cannot read trajectories ({err})") from None
    events = planned = None
    ev_file, paths_file = p.with_name("events.jsonl"), p.with_name("paths.json")
    if ev_file.is_file():
        events = [json.loads(line) for line in ev_file.read_text(encoding="utf-8").splitlines()
                  if line.strip()]
    if paths_file.is_file():
        planned = json.loads(paths_file.read_text(encoding="utf-8")).get("planned")
    return _from_dict(traj, events, planned, str(p))


def grid_trajectory(result: EpisodeResult) -> dict[str, np.ndarray]:
    """The ``trajectories.npz`` arrays of a grid-executor episode: one sample per tick, body
    centres of the executed states (a state between two cells is half-way), headings from
    the move direction (kept while standing), task states and cargo from the events."""
    world = result.world
    lay = world.layout
    cols, cell_m = lay.cols, float(lay.cell_m)
    agvs = world.agvs
    n = len(agvs)
    ticks = max(len(v) for v in result.actual.values())
    footprint = np.array([a.k for a in agvs], dtype=np.int64)
    pos = np.zeros((ticks, n, 2))
    for a in agvs:
        states = np.asarray(result.actual[a.id], dtype=np.int64)
        states = np.vstack([states, np.repeat(states[-1:], ticks - len(states), axis=0)])
        pos[:, a.id] = 0.5 * (_centres(states[:, 0], a.k, cols, cell_m)
                              + _centres(states[:, 1], a.k, cols, cell_m))
    # Heading at a sample: the direction of the last move that ended there or earlier
    # (before its first move an AGV faces that move).
    step = np.diff(pos, axis=0)
    moving = np.abs(step).sum(axis=2) > 1e-9
    ang = np.arctan2(step[..., 1], step[..., 0])
    last = np.where(moving.any(axis=0), ang[moving.argmax(axis=0), np.arange(n)], 0.0) \
        if ticks > 1 else np.zeros(n)
    heading = np.zeros((ticks, n))
    heading[0] = last
    for t in range(1, ticks):
        last = np.where(moving[t - 1], ang[t - 1], last)
        heading[t] = last
    state = np.zeros((ticks, n), dtype=np.int8)
    loaded = np.zeros((ticks, n), dtype=bool)
    before: dict[int, int] = {}
    """Failed AGV -> its state when it failed (it resumes there)."""
    for e in result.events:          # in tick order: each event sets the rest of the episode
        ev, tick = e.get("event"), int(e["tick"])
        if ev not in ("trip_started", "shelf_picked", "shelf_returned", "agv_failed",
                      "agv_repaired") or tick >= ticks:
            continue
        aid = int(e["agv"])
        if ev == "trip_started":
            state[tick:, aid] = TO_SHELF
        elif ev == "shelf_picked":
            state[tick:, aid] = TO_STATION
            loaded[tick:, aid] = True
        elif ev == "shelf_returned":
            state[tick:, aid] = IDLE
            loaded[tick:, aid] = False
        elif ev == "agv_failed":
            before[aid] = IDLE if e.get("orders_released") else int(state[tick, aid])
            state[tick:, aid] = FAILED
        else:
            state[tick:, aid] = before.pop(aid, IDLE)
    return {
        "t": np.arange(ticks, dtype=np.float64) * float(world.scenario.tick_s),
        "x": pos[..., 0], "y": pos[..., 1], "heading": heading, "state": state,
        "loaded": loaded, "footprint": footprint,
        "body_m": np.array([a.spec.body_m for a in agvs], dtype=np.float64),
        "cell_m": np.array(cell_m), "tick_s": np.array(float(world.scenario.tick_s)),
        "grid": np.asarray(lay.grid).copy(),
        "corridors_json": np.array(json.dumps(getattr(world, "corridor_log", []))),
    }


def recording_from_episode(result: EpisodeResult) -> Recording:
    """A :class:`Recording` of a finished episode: the physics executor's trajectory, or one
    built from the grid executor's per-tick states (:func:`grid_trajectory`)."""
    traj = result.trajectory if result.trajectory is not None else grid_trajectory(result)
    return _from_dict(traj, result.events, result.planned, "episode")
