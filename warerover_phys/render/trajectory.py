"""Recorded episodes for rendering: load ``trajectories.npz`` or build the same arrays from a
grid-executor :class:`~warerover_phys.sim.EpisodeResult`, and sample them at any time.

A :class:`Recording` holds the trajectory arrays (the dict of
``PhysicsExecutor.trajectory``: ``t`` (T,), ``x``, ``y``, ``heading``, ``state``, ``loaded``
(T, N), ``footprint``, ``body_m``, ``cell_m``, ``tick_s``, ``grid``, ``corridors_json``, and,
in recordings made since issue 36, ``exec_state``, ``blocker``, ``plan_tick`` (T, N): what each
AGV was doing, see :mod:`warerover_phys.executors.recording`) plus what the heads-up line
and the planned paths need: order arrival and completion ticks (from the episode's events)
and the committed plans. :meth:`Recording.at` interpolates a snapshot at any simulated time
(positions linear, headings along the shorter arc), so the video frame rate is independent
of the physics step and of the recording rate. The path ahead of each AGV starts from its
recorded progress in its plan (:mod:`.plans`), never from the clock.

No OpenCV here: this module is numpy only.
"""

from __future__ import annotations

import json
import math
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import WareroverError
from ..executors.recording import EXEC_FIELDS, EXEC_STATES
from ..poses import _centres, states_poses
from .plans import PlanIndex, finish_times, plan_progress

if TYPE_CHECKING:
    from ..sim import EpisodeResult
    from .frame import Scene, Snapshot

__all__ = ["Recording", "load_trajectory", "recording_from_episode", "grid_trajectory",
           "ghost_poses", "recording_with_ghosts"]

FAILED = 7
"""``AgvState.FAILED``."""
IDLE = 0
TO_SHELF = 1
TO_STATION = 3
REQUIRED = ("t", "x", "y", "heading", "state", "loaded", "footprint", "body_m", "cell_m",
            "tick_s", "grid")
SWITCH_SHOW_S = 3.0
"""Seconds a switched edge stays drawn after it was switched."""


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
    ghost: dict[str, np.ndarray] | None = None
    """Planned poses drawn as ghosts: ``t`` (G,) seconds, ``x``, ``y``, ``heading`` (G, N)
    (:func:`ghost_poses`); None: taken from :attr:`plans` when ghosts are asked for."""
    exec_state: np.ndarray | None = None
    """(T, N) what each AGV was doing (``EXEC_STATES`` codes); None: not recorded."""
    blocker: np.ndarray | None = None
    """(T, N) the AGV a waiting AGV waits for (-1: none)."""
    plan_tick: np.ndarray | None = None
    """(T, N) each AGV's progress in its plan (plan ticks; -1: at its plan's start)."""
    switches: tuple[dict, ...] = ()
    """Switched edges of the dependency graph (``reorder`` events: ``t_s``, ``first``,
    ``then``, ``cells``), each shown for :data:`SWITCH_SHOW_S` seconds after it."""
    _scene: list = field(default_factory=list, repr=False)
    _plan_index: list = field(default_factory=list, repr=False)
    _run: dict = field(default_factory=dict, repr=False)
    """What :meth:`at` computes once: finish times and the planned makespan."""

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

            states = None
            if self.exec_state is not None:
                seen = np.zeros(len(EXEC_STATES), dtype=bool)
                for r in range(0, len(self.exec_state), 2048):   # memory maps: in blocks
                    block = np.asarray(self.exec_state[r:r + 2048]).ravel()
                    seen |= np.bincount(np.clip(block, 0, len(seen) - 1).astype(np.int64),
                                        minlength=len(seen)) > 0
                states = tuple(np.flatnonzero(seen).tolist())
            self._scene.append(Scene(grid=self.grid, cell_m=self.cell_m, body_m=self.body_m,
                                     footprint=self.footprint, states=states,
                                     corridors=bool(self.corridors)))
        return self._scene[0]

    @property
    def plan_execution(self) -> bool:
        """A fixed plan executed (``warerover execute``, the open-loop gap): no orders, one
        plan per AGV from tick 0, and what each AGV did recorded."""
        if "plan_execution" not in self._run:
            self._run["plan_execution"] = self.exec_state is not None and bool(self.plans) and (
                self.order_created is None or not len(self.order_created)) and all(
                len(p) == 1 and p[0][0] == 0 for p in self.plans.values())
        return self._run["plan_execution"]

    def plan_index(self) -> PlanIndex:
        """The committed plans as flat arrays (built once)."""
        if not self._plan_index:
            self._plan_index.append(PlanIndex(self.plans, self.num_agvs))
        return self._plan_index[0]

    def at(self, time_s: float, path_ticks: int = 0, ghosts: bool = False) -> Snapshot:
        """The state at simulated time ``time_s`` (clamped to the recording): poses
        interpolated between the two samples around it, discrete fields from the earlier.
        ``path_ticks``: the planned steps ahead of each AGV to include; planned poses come
        from :attr:`ghost`, or, with ``ghosts``, from the plans at that time."""
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
        ex = {name: None if arr is None else np.asarray(arr[k]) for name, arr in
              (("exec_state", self.exec_state), ("blocker", self.blocker),
               ("plan_tick", self.plan_tick))}
        paths = progress = None
        if self.plans and (path_ticks > 0 or self.plan_execution):
            index = self.plan_index()
            entry = index.select(tick)
            rel = index.progress_index(entry, ex["plan_tick"], x, y)
            if path_ticks > 0:
                paths = index.ahead(entry, rel, ex["exec_state"], x, y, path_ticks)
            if self.plan_execution:
                progress = plan_progress(index, entry, rel, ex["exec_state"], q, self.tick_s,
                                         *self._run_figures(index))
        ghost = _sample(self.ghost, q) if self.ghost is not None else \
            self.plan_index().pose_at(tick) if ghosts and self.plans else None
        switches = tuple(s for s in self.switches if s["t_s"] <= q < s["t_s"] + SWITCH_SHOW_S)
        return Snapshot(scene=self.scene(), time_s=q, tick_s=self.tick_s, x=x, y=y,
                        heading=heading, state=state, loaded=loaded, corridors=corridors,
                        orders_done=done, orders_total=total, paths=paths, ghosts=ghost,
                        exec_state=ex["exec_state"], blocker=ex["blocker"], progress=progress,
                        switches=switches)

    def _run_figures(self, index: PlanIndex) -> tuple[np.ndarray, float]:
        """Each AGV's finish time and the planned makespan (seconds), computed once."""
        if "finish" not in self._run:
            planned = index.finish_tick(index.select(0.0))
            self._run["finish"] = finish_times(self.t, self.exec_state)
            self._run["planned"] = float(planned.max(initial=0)) * self.tick_s
        return self._run["finish"], self._run["planned"]


def _sample(g: dict[str, np.ndarray], q: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses of ``g`` (``t``, ``x``, ``y``, ``heading``) at time ``q``, interpolated (held
    at the ends)."""
    t = g["t"]
    q = min(max(q, float(t[0])), float(t[-1]))
    i = min(max(int(np.searchsorted(t, q, side="right")) - 1, 0), len(t) - 1)
    j = min(i + 1, len(t) - 1)
    w = 0.0 if j == i else (q - float(t[i])) / (float(t[j]) - float(t[i]))
    dh = (g["heading"][j] - g["heading"][i] + np.pi) % (2 * np.pi) - np.pi
    return (g["x"][i] + w * (g["x"][j] - g["x"][i]), g["y"][i] + w * (g["y"][j] - g["y"][i]),
            g["heading"][i] + w * dh)


def ghost_poses(states: dict[int, list], footprint: np.ndarray, cols: int, cell_m: float,
                tick_s: float) -> dict[str, np.ndarray]:
    """Planned poses of per-tick grid states (a plan's timing: tick ``k`` at ``k * tick_s``
    seconds), as :attr:`Recording.ghost`. Between ticks the ghost moves linearly; it turns
    at once when a move starts (plans carry no turning time)."""
    pos, heading = states_poses(states, np.asarray(footprint), cols, cell_m)
    # face the next move while standing before it (the body turns before it drives)
    return {"t": np.arange(len(pos), dtype=np.float64) * float(tick_s),
            "x": pos[..., 0], "y": pos[..., 1], "heading": _facing(pos, heading)}


def _facing(pos: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """``heading`` where a move starts after tick ``t``: the ghost faces the move from
    ``t`` on (``states_poses`` gives it on arrival)."""
    out = heading.copy()
    if len(pos) > 1:
        step = np.diff(pos, axis=0)
        moving = np.abs(step).sum(axis=2) > 1e-9
        ang = np.arctan2(step[..., 1], step[..., 0])
        out[:-1] = np.where(moving, ang, out[:-1])
    return out


def recording_with_ghosts(trajectory: dict, ghost: dict[str, np.ndarray],
                          source: str = "open loop",
                          planned: list[dict] | None = None,
                          switches: tuple[dict, ...] = ()) -> Recording:
    """A :class:`Recording` of an executor's ``trajectory`` dict with ``ghost`` poses
    (:func:`ghost_poses`) to draw beside the bodies (``Style(ghosts=True)``), the
    ``planned`` paths (``{"agv", "tick", "states"}``, as ``EpisodeResult.planned``) and the
    ``reorder`` events' switched edges (``Style(switches=True)``)."""
    import dataclasses

    rec = _from_dict(trajectory, None, planned, source)
    n = rec.num_agvs
    for key in ("x", "y", "heading"):
        if np.asarray(ghost[key]).shape != (len(ghost["t"]), n):
            raise WareroverError(f"{source}: ghost {key}: expected shape "
                                 f"({len(ghost['t'])}, {n})")
    return dataclasses.replace(rec, ghost={k: np.asarray(v, dtype=np.float64)
                                           for k, v in ghost.items()},
                               switches=tuple(switches))


# ------------------------------------------------------------------------------ building


def _plans(planned: list[dict], footprint: np.ndarray, cols: int, cell_m: float,
           ) -> dict[int, list[tuple[int, np.ndarray]]]:
    """Committed plans as centre points; ``states`` are ``[from, to]`` flat nodes or
    ``[[row, col], [row, col]]`` cells (``paths.json``)."""
    out: dict[int, list[tuple[int, np.ndarray]]] = {}
    for p in planned:
        aid, states = int(p["agv"]), p["states"]
        if not states or not 0 <= aid < len(footprint):
            continue
        arr = np.asarray(states, dtype=np.float64)
        if arr.shape[1:] not in ((2,), (2, 2)) or not np.isfinite(arr).all():
            raise ValueError(f"states of AGV {aid} must be from/to pairs of cells")
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
               source: str, plans_source: str = "plans") -> Recording:
    missing = [k for k in REQUIRED if k not in traj]
    if missing:
        raise WareroverError(f"{source}: not a trajectory file (missing {', '.join(missing)})")
    try:
        return _build(traj, events, planned, source, plans_source)
    except WareroverError:
        raise
    except (ValueError, TypeError, KeyError, IndexError, OverflowError, AttributeError) as err:
        raise WareroverError(f"{source}: not a valid trajectory ({type(err).__name__}: "
                             f"{str(err).splitlines()[0] if str(err) else 'bad value'})") from None


def _build(traj: dict, events: list[dict] | None, planned: list[dict] | None,
           source: str, plans_source: str) -> Recording:
    def bad(field: str, why: str) -> WareroverError:
        return WareroverError(f"{source}: {field}: {why}")

    t = np.asarray(traj["t"], dtype=np.float64)
    if t.ndim != 1 or len(t) == 0:
        raise WareroverError(f"{source}: trajectory has no samples")
    if not np.isfinite(t).all() or (len(t) > 1 and (np.diff(t) < 0).any()):
        raise bad("t", "sample times must be finite and non-decreasing")
    arrays = {}
    for key, dtype in (("x", np.float64), ("y", np.float64), ("heading", np.float64),
                       ("state", np.int8), ("loaded", bool)):
        a = np.asarray(traj[key])
        if a.ndim != 2 or a.shape[0] != len(t):
            raise bad(key, f"expected shape ({len(t)}, AGVs) (got {a.shape})")
        if a.dtype.kind not in "biuf":
            raise bad(key, f"expected numbers (got {a.dtype})")
        if dtype is np.float64 and not np.isfinite(a).all():
            raise bad(key, "values must be finite")
        arrays[key] = a.astype(dtype, copy=False)
    n = arrays["x"].shape[1]
    if any(a.shape[1] != n for a in arrays.values()):
        raise bad("x", "arrays disagree on the number of AGVs")
    grid = np.asarray(traj["grid"])
    if grid.ndim != 2 or grid.dtype.kind not in "iu" or 0 in grid.shape:
        raise bad("grid", f"expected a 2-D integer array (got {grid.dtype} {grid.shape})")
    cell_m, tick_s = float(traj["cell_m"]), float(traj["tick_s"])
    for key, v in (("cell_m", cell_m), ("tick_s", tick_s)):
        if not (math.isfinite(v) and v > 0):
            raise bad(key, f"must be a positive finite number (got {v})")
    footprint = np.asarray(traj["footprint"])
    body_m = np.asarray(traj["body_m"])
    if footprint.shape != (n,) or footprint.dtype.kind not in "iu" or (footprint < 1).any():
        raise bad("footprint", f"expected {n} positive integers (got {footprint.shape})")
    if body_m.shape != (n, 2) or body_m.dtype.kind not in "iuf" or \
            not np.isfinite(body_m).all() or (body_m <= 0).any():
        raise bad("body_m", f"expected ({n}, 2) positive sizes (got {body_m.shape})")
    footprint = footprint.astype(np.int64)
    corridors: tuple[dict, ...] = ()
    if "corridors_json" in traj:
        try:
            corridors = tuple(json.loads(str(traj["corridors_json"])))
        except ValueError:
            raise bad("corridors_json", "not valid JSON") from None
        for c in corridors:
            if not isinstance(c, dict) or "open_tick" not in c or "close_tick" not in c:
                raise bad("corridors_json", "each corridor needs open_tick and close_tick")
    created = done = None
    if events is not None:
        created, done = _orders(events)
    try:
        plans = _plans(planned, footprint, grid.shape[1], cell_m) if planned else {}
    except (ValueError, TypeError, KeyError, IndexError, OverflowError) as err:
        why = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise WareroverError(f"{plans_source}: planned: not valid plans ({why})") from None
    execution = _execution_fields(traj, len(t), n, bad)
    return Recording(
        t=t, x=arrays["x"], y=arrays["y"], heading=arrays["heading"], state=arrays["state"],
        loaded=arrays["loaded"], footprint=footprint, body_m=body_m.astype(np.float64),
        cell_m=cell_m, tick_s=tick_s, grid=grid, corridors=corridors, order_created=created,
        order_done=done, plans=plans, **execution)


def _execution_fields(traj: dict, t: int, n: int, bad) -> dict[str, np.ndarray | None]:
    """``exec_state``, ``blocker``, ``plan_tick`` when the recording has them (all or
    none), checked; ``bad(field, why)`` makes the error."""
    have = [k for k in EXEC_FIELDS if k in traj]
    if not have:
        return dict.fromkeys(EXEC_FIELDS)
    if len(have) != len(EXEC_FIELDS):
        missing = sorted(set(EXEC_FIELDS) - set(have))
        raise bad(missing[0], "missing (the execution fields come together)")
    out = {}
    for key in EXEC_FIELDS:
        a = np.asarray(traj[key])
        if a.shape != (t, n) or a.dtype.kind not in "iu":
            raise bad(key, f"expected integers of shape ({t}, {n}) (got {a.dtype} {a.shape})")
        out[key] = a
    state = out["exec_state"]
    if len(state) and (int(state.min()) < 0 or int(state.max()) >= len(EXEC_STATES)):
        raise bad("exec_state", f"codes must be 0..{len(EXEC_STATES) - 1}")
    blocker = out["blocker"]
    if len(blocker) and (int(blocker.min()) < -1 or int(blocker.max()) >= n):
        raise bad("blocker", f"must be -1 or an AGV id below {n}")
    return out


def _read_json(path: Path, lines: bool) -> object:
    """A JSON (``lines``: JSON-lines) file beside a trajectory, or a one-line error."""
    from ..inputs import read_text

    try:
        text = read_text(path, path.name, 2**30)  # a regular file, at most 1 GiB
        if lines:
            out = [json.loads(line) for line in text.splitlines() if line.strip()]
            if not all(isinstance(e, dict) for e in out):
                raise ValueError("every line must be a JSON object")
            return out
        return json.loads(text)
    except (ValueError, UnicodeDecodeError, RecursionError) as err:
        why = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise WareroverError(f"{path}: corrupt or truncated ({why})") from None


def load_trajectory(path: str | Path) -> Recording:
    """Load ``trajectories.npz`` (a file, or a run folder holding one). ``events.jsonl`` and
    ``paths.json`` beside it, when present, give the order counts and the planned paths.

    A run folder whose files do not match its ``manifest.json`` (a mixed or half-written set,
    :func:`warerover_phys.util.atomic.check_set`) is refused; so is any corrupt or truncated file,
    with a :class:`WareroverError` naming it."""
    from ..util.atomic import check_set

    p = Path(path)
    if p.is_dir():
        p = p / "trajectories.npz"
    from ..inputs import check_regular_file, load_npz

    check_regular_file(p, "trajectory")  # before the folder's manifest is read
    check_set(p.parent)
    try:
        traj = load_npz(p, "trajectory")
    except zlib.error as err:
        raise WareroverError(f"{p}: cannot read trajectories ({err})") from None
    events = planned = None
    ev_file, paths_file = p.with_name("events.jsonl"), p.with_name("paths.json")
    if ev_file.is_file():
        events = _read_json(ev_file, lines=True)
        for i, e in enumerate(events):
            if e.get("event") in ("order_created", "order_completed") and \
                    not isinstance(e.get("tick"), int | float):
                raise WareroverError(f"{ev_file}: line {i + 1}: tick: expected a number "
                                     f"(got {e.get('tick')!r})")
    if paths_file.is_file():
        data = _read_json(paths_file, lines=False)
        planned = data.get("planned") if isinstance(data, dict) else None
        if not isinstance(data, dict) or not isinstance(planned, list | None):
            raise WareroverError(f"{paths_file}: planned: expected a list of plans")
        for i, plan in enumerate(planned or []):
            if not (isinstance(plan, dict) and isinstance(plan.get("agv"), int)
                    and isinstance(plan.get("tick"), int)
                    and isinstance(plan.get("states"), list)):
                raise WareroverError(f"{paths_file}: planned[{i}]: expected agv, tick, states")
    return _from_dict(traj, events, planned, str(p), str(paths_file))


def grid_trajectory(result: EpisodeResult) -> dict[str, np.ndarray]:
    """The ``trajectories.npz`` arrays of a grid-executor episode: one sample per tick, body
    centres of the executed states (see :func:`states_poses`), task states and cargo from
    the events, and what each AGV was doing (:func:`~warerover_phys.executors.grid_record.
    grid_execution`)."""
    from ..executors.grid_record import grid_execution, state_array

    world = result.world
    lay = world.layout
    cols, cell_m = lay.cols, float(lay.cell_m)
    agvs = world.agvs
    n = len(agvs)
    footprint = np.array([a.k for a in agvs], dtype=np.int64)
    pos, heading = states_poses(result.actual, footprint, cols, cell_m)
    ticks = len(pos)
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
    execution = grid_execution(state_array(result.actual, n, ticks),
                               [(p["agv"], p["tick"], p["states"]) for p in result.planned],
                               footprint, cols, lay.rows, state)
    return {
        "t": np.arange(ticks, dtype=np.float64) * float(world.scenario.tick_s),
        "x": pos[..., 0], "y": pos[..., 1], "heading": heading, "state": state,
        "loaded": loaded, "footprint": footprint, **execution,
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
