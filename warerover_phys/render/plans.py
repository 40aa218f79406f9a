"""The committed plans of a recording as flat arrays: each AGV's path still ahead, from its
own progress in its plan, and the figures of a plan execution's heads-up line.

The path ahead of an AGV starts where the AGV is *in its plan* (the recorded ``plan_tick``:
the arrival tick of the move it drives, else of the last one it finished), never where the
clock says it should be: a robot running 100 s behind its plan gets the cells it still has
to drive, not a straight line to a cell far along (which crosses shelves). Recordings made
before ``plan_tick`` existed fall back to the plan point nearest to the body.

Numpy only; one vectorised pass over the fleet per frame (no Python per AGV).

>>> import numpy as np
>>> pts = np.array([[0.5, 0.5], [0.5, 0.5], [1.5, 0.5], [2.5, 0.5]])   # stand, then east
>>> idx = PlanIndex({0: [(0, pts)]}, 1)
>>> entry = idx.select(5.0)
>>> ahead = idx.ahead(entry, np.array([1]), np.array([0]), np.array([0.5]), np.array([0.5]), 4)
>>> ahead.agv.tolist(), ahead.points[0].tolist()
([0], [[0.5, 0.5], [0.5, 0.5], [1.5, 0.5], [2.5, 0.5], [2.5, 0.5], [2.5, 0.5]])
>>> idx.finish_tick(entry).tolist()
[3]
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

__all__ = ["PathSet", "PlanIndex", "PlanProgress", "plan_progress", "finish_times"]

_STRIDE = 1 << 32
"""Key of a plan: ``agv * _STRIDE + start tick`` (sorted, so a search finds the latest)."""
_DRIVING = 1
"""``exec_state`` code of a driving AGV (:data:`~warerover_phys.executors.recording.
EXEC_STATES`)."""
_FINISHED = 6


class PathSet(NamedTuple):
    """Paths ahead: ``agv`` (M,) ids and ``points`` (M, K, 2) metres, each row starting at
    the body (a row shorter than K repeats its last point)."""

    agv: np.ndarray
    points: np.ndarray


@dataclass(frozen=True)
class PlanProgress:
    """A plan execution at one time, for the heads-up line (seconds unless noted)."""

    finished: int
    """AGVs done with their plans."""
    agvs: int
    planned_makespan_s: float
    executed_makespan_s: float
    """The time of the last finish once every AGV is done, else the time so far."""
    done: bool
    """Every AGV has finished (``executed_makespan_s`` is final)."""
    lost_s: float
    """AGV-seconds lost so far: per AGV, how far it is behind the plan's time for the state
    it is on (finished: its finish minus its planned finish), never below zero."""


class PlanIndex:
    """Every committed plan ``(start tick, (L, 2) points)`` per AGV, as flat arrays."""

    def __init__(self, plans: dict[int, list[tuple[int, np.ndarray]]], n: int) -> None:
        rows = sorted((int(a), int(s), np.asarray(p, dtype=np.float64))
                      for a, entries in plans.items() if 0 <= int(a) < n
                      for s, p in entries if len(p))
        self.n = n
        self.agv = np.array([r[0] for r in rows], dtype=np.int64)
        self.start = np.array([r[1] for r in rows], dtype=np.int64)
        self.length = np.array([len(r[2]) for r in rows], dtype=np.int64)
        self.offset = np.concatenate([[0], np.cumsum(self.length)[:-1]]).astype(np.int64) \
            if rows else np.zeros(0, dtype=np.int64)
        self.key = self.agv * _STRIDE + self.start
        self.points = np.concatenate([r[2] for r in rows]) if rows else np.zeros((0, 2))
        # Per point, the last index (flat) of the run of equal points it is in: where the
        # plan has the AGV leave that spot.
        p = self.points
        change = np.ones(len(p), dtype=bool)
        if len(p) > 1:
            change[:-1] = (p[1:] != p[:-1]).any(axis=1)
        ends = self.offset + self.length - 1
        change[ends] = True
        run_end = np.flatnonzero(change)
        self.leave = run_end[np.searchsorted(run_end, np.arange(len(p)))] if len(p) else \
            np.zeros(0, dtype=np.int64)
        # Planned finish (relative index): the first point of the plan's last run (runs
        # never span two plans: each plan's end is a run end).
        pos = np.searchsorted(run_end, ends)
        first = np.where(pos > 0, run_end[np.maximum(pos - 1, 0)] + 1, 0)
        self._finish = np.maximum(first, self.offset) - self.offset
        self.facing = self._facing(run_end)
        """Per point, the heading (radians) of the next move, or of the last one at the
        plan's end (0 for a plan that never moves)."""

    def _facing(self, run_end: np.ndarray) -> np.ndarray:
        p = self.points
        if not len(p):
            return np.zeros(0)
        plan = np.repeat(np.arange(len(self.length)), self.length)
        end = (self.offset + self.length - 1)[plan]
        nxt = np.minimum(self.leave + 1, len(p) - 1)
        ahead = self.leave < end
        pos = np.searchsorted(run_end, self.leave)          # this point's run
        prev = np.where(pos > 0, run_end[np.maximum(pos - 1, 0)], -1)
        behind = prev >= self.offset[plan]
        d = np.where(ahead[:, None], p[nxt] - p, p - p[np.maximum(prev, 0)])
        return np.where(ahead | behind, np.arctan2(d[:, 1], d[:, 0]), 0.0)

    def __len__(self) -> int:
        return len(self.agv)

    def select(self, tick: float) -> np.ndarray:
        """(N,) index of each AGV's latest plan committed by ``tick`` (-1: none)."""
        ids = np.arange(self.n, dtype=np.int64)
        if len(self.key) == 0:
            return np.full(self.n, -1, dtype=np.int64)
        e = np.searchsorted(self.key, ids * _STRIDE + int(np.floor(tick + 1e-9)),
                            side="right") - 1
        ok = (e >= 0) & (self.agv[np.maximum(e, 0)] == ids)
        return np.where(ok, e, -1)

    def finish_tick(self, entry: np.ndarray) -> np.ndarray:
        """Planned finish tick (absolute) of each selected plan (-1 where none)."""
        e = np.maximum(entry, 0)
        return np.where(entry >= 0, self.start[e] + self._finish[e], -1) if len(self) else \
            np.full(len(entry), -1)

    def progress_index(self, entry: np.ndarray, plan_tick: np.ndarray | None,
                       x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """(N,) index into each AGV's plan where it is (-1 without a plan): its recorded
        ``plan_tick``, or (None: an older recording) the plan point nearest to the body."""
        e = np.maximum(entry, 0)
        has = entry >= 0
        if not len(self):
            return np.full(len(entry), -1)
        length = self.length[e]
        if plan_tick is not None:
            rel = np.clip(np.asarray(plan_tick, dtype=np.int64) - self.start[e], 0,
                          np.maximum(length - 1, 0))
            return np.where(has, rel, -1)
        out = np.full(len(entry), -1, dtype=np.int64)
        sel = np.flatnonzero(has)
        if len(sel) == 0:
            return out
        width = int(length[sel].max())
        k = np.arange(width)
        idx = self.offset[e[sel], None] + np.minimum(k[None, :], length[sel, None] - 1)
        d = (self.points[idx, 0] - x[sel, None]) ** 2 + (self.points[idx, 1] - y[sel, None]) ** 2
        out[sel] = d.argmin(axis=1)
        return out

    def ahead(self, entry: np.ndarray, rel: np.ndarray, exec_state: np.ndarray | None,
              x: np.ndarray, y: np.ndarray, horizon: int) -> PathSet:
        """The next ``horizon`` plan points after each AGV's progress ``rel``
        (:meth:`progress_index`), from its body. A standing AGV's plan points on its own
        cell (planned waits) collapse onto the body; AGVs with nothing ahead are left out."""
        sel = np.flatnonzero((entry >= 0) & (rel >= 0))
        if len(sel) == 0 or horizon <= 0:
            return PathSet(np.zeros(0, dtype=np.int64), np.zeros((0, 2, 2)))
        e = entry[sel]
        k = np.arange(horizon + 1)
        length = self.length[e]
        idx = self.offset[e, None] + np.minimum(rel[sel, None] + k[None, :], length[:, None] - 1)
        px, py = self.points[idx, 0], self.points[idx, 1]           # (M, H + 1) each
        bx, by = x[sel, None], y[sel, None]
        driving = exec_state[sel] == _DRIVING if exec_state is not None else \
            np.zeros(len(sel), dtype=bool)
        same = (px == px[:, :1]) & (py == py[:, :1])
        lead = np.logical_and.accumulate(same, axis=1) & ~driving[:, None]
        px, py = np.where(lead, bx, px), np.where(lead, by, py)
        keep = ((px != bx) | (py != by)).any(axis=1)
        out = np.empty((int(keep.sum()), horizon + 2, 2))
        out[:, 0, 0], out[:, 0, 1] = bx[keep, 0], by[keep, 0]
        out[:, 1:, 0], out[:, 1:, 1] = px[keep], py[keep]
        return PathSet(sel[keep], out)

    def pose_at(self, tick: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each AGV's planned pose at ``tick`` (fractional: between two plan points,
        linearly) in its latest plan committed by then: ``x``, ``y`` (metres), heading (the
        move it makes or made); NaN for an AGV without a plan."""
        entry = self.select(tick)
        out = np.full((3, self.n), np.nan)
        sel = np.flatnonzero(entry >= 0)
        if len(sel) == 0:
            return out[0], out[1], out[2]
        e = entry[sel]
        base = int(np.floor(tick + 1e-9))
        last = self.length[e] - 1
        rel = np.clip(base - self.start[e], 0, last)
        frac = np.where(base - self.start[e] < last, min(max(tick - base, 0.0), 1.0), 0.0)
        i0 = self.offset[e] + rel
        i1 = self.offset[e] + np.minimum(rel + 1, last)
        pos = self.points[i0] + frac[:, None] * (self.points[i1] - self.points[i0])
        out[0, sel], out[1, sel], out[2, sel] = pos[:, 0], pos[:, 1], self.facing[i0]
        return out[0], out[1], out[2]

    def due_tick(self, entry: np.ndarray, rel: np.ndarray,
                 exec_state: np.ndarray | None) -> np.ndarray:
        """(N,) plan tick by which each AGV should be past the state it is on: a driving
        AGV's arrival tick, a standing one's planned departure from its spot (the end of the
        plan's wait there). -1 without a plan."""
        has = (entry >= 0) & (rel >= 0)
        if not len(self):
            return np.full(len(entry), -1)
        e = np.maximum(entry, 0)
        flat = self.offset[e] + np.maximum(rel, 0)
        flat = np.minimum(flat, len(self.points) - 1)
        leave = self.leave[flat] - self.offset[e]
        driving = exec_state == _DRIVING if exec_state is not None else False
        due = np.where(driving, np.maximum(rel, 0), leave) + self.start[e]
        return np.where(has, due, -1)


def finish_times(t: np.ndarray, exec_state: np.ndarray) -> np.ndarray:
    """(N,) time each AGV entered its last ``finished`` run for good (inf: not finished at
    the end of the recording)."""
    fin = np.asarray(exec_state) == _FINISHED
    if fin.shape[0] == 0:
        return np.full(fin.shape[1], np.inf)
    rev = ~fin[::-1]
    any_not = rev.any(axis=0)
    last_not = fin.shape[0] - 1 - rev.argmax(axis=0)         # last sample not finished
    k = np.where(any_not, last_not + 1, 0)
    out = np.full(fin.shape[1], np.inf)
    ok = k < fin.shape[0]
    out[ok] = np.asarray(t)[k[ok]]
    return out


def plan_progress(index: PlanIndex, entry: np.ndarray, rel: np.ndarray,
                  exec_state: np.ndarray, time_s: float, tick_s: float,
                  finish_s: np.ndarray, planned_makespan_s: float) -> PlanProgress:
    """The heads-up figures of a plan execution at ``time_s`` (see :class:`PlanProgress`);
    ``finish_s``: :func:`finish_times` of the recording."""
    n = len(entry)
    fin = (np.asarray(exec_state) == _FINISHED) & (finish_s <= time_s + 1e-9)
    planned_finish = index.finish_tick(entry) * tick_s
    lost_done = np.maximum(0.0, finish_s - planned_finish)
    due = index.due_tick(entry, rel, exec_state) * tick_s
    lost_now = np.where(due >= 0, np.maximum(0.0, time_s - due), 0.0)
    lost = float(np.where(fin, lost_done, lost_now).sum())
    done = bool(fin.all()) if n else True
    executed = float(finish_s.max()) if done and n else float(time_s)
    return PlanProgress(finished=int(fin.sum()), agvs=n, planned_makespan_s=planned_makespan_s,
                        executed_makespan_s=executed, done=done, lost_s=lost)
