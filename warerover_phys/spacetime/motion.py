"""Timed plans: per agent, timed poses ``(x_m, y_m, heading_rad, t_s)`` moved between by
linear interpolation, with the body rectangle and, where it carries one, a shelf outline.

This is the input of the space-time validator (:func:`warerover_phys.spacetime.validate_spacetime`).
Converters build it from the project's unit-time plans (:func:`from_plan`), from timed
schedules of cells (:func:`from_schedule`: a list of ``(cell, t_s)`` or ``(cell, heading,
t_s)`` per agent, the shape duration-aware plans will have) and from an executed run's
``trajectories.npz`` (:func:`from_trajectory`, :func:`load_trajectory_file`).

Conventions (the project's): ``x = (col + k / 2) * cell_m`` and ``y = (row + k / 2) * cell_m``
for a ``k x k`` AGV anchored at its top-left cell ``(row, col)``; headings in radians,
``0 = +x``, ``pi / 2 = +y`` (south, y grows downward); plan heading numbers ``0..3`` (E, S,
W, N) are ``number * pi / 2``. A body is a ``length x width`` rectangle centred on
``(x, y)``, length along the heading. A carried shelf is a rectangle centred on the same
point with its sides along the grid (``shelf_m[k] = (extent along x, extent along y)``; 0 =
no shelf); it does not turn with the drive unit.

Between two samples the agent moves on a straight line at constant speed and turns at a
constant rate by the shorter way round (a difference of exactly pi turns by +pi). Before
its first sample an agent is absent; after its last one it stays where it is until the end
of the plan (the last sample of any agent), as in :class:`warerover_phys.plans.model.Plan`.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ScenarioError

__all__ = ["AgentMotion", "TimedPlan", "SpacetimeInputError", "from_plan", "from_schedule",
           "from_trajectory", "load_trajectory_file", "DEFAULT_BODY_M"]

DEFAULT_BODY_M = (0.7, 0.7)
"""Body length and width (m) when none is given: the default AGV type's."""


class SpacetimeInputError(ScenarioError):
    """A timed plan or trajectory that cannot be checked; names the file, field and value."""


def _fail(message: str, field: str, value, source: str | None) -> SpacetimeInputError:
    return SpacetimeInputError(message, file=source, field=field, value=value)


@dataclass(frozen=True, eq=False)
class AgentMotion:
    """One agent's timed poses.

    ``t_s`` (K,) strictly increasing seconds; ``x_m``, ``y_m`` (K,) body centre;
    ``heading_rad`` (K,); ``body_m`` (length, width); ``shelf_m`` (K, 2) carried-shelf
    extents along x and y per sample (0 = none), or None.

    >>> m = AgentMotion.from_samples([(0.5, 0.5, 0.0, 0.0), (1.5, 0.5, 0.0, 1.0)])
    >>> m.t_s.tolist(), m.body_m
    ([0.0, 1.0], (0.7, 0.7))
    """

    t_s: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    heading_rad: np.ndarray
    body_m: tuple[float, float] = DEFAULT_BODY_M
    shelf_m: np.ndarray | None = None

    @classmethod
    def from_samples(cls, samples: Iterable[Sequence[float]],
                     body_m: Sequence[float] = DEFAULT_BODY_M,
                     shelf_m: Sequence[Sequence[float]] | None = None) -> AgentMotion:
        """From ``(x_m, y_m, heading_rad, t_s)`` tuples."""
        arr = np.asarray(list(samples), dtype=float).reshape(-1, 4)
        return cls(arr[:, 3], arr[:, 0], arr[:, 1], arr[:, 2],
                   (float(body_m[0]), float(body_m[1])),
                   None if shelf_m is None else np.asarray(shelf_m, dtype=float))

    def check(self, where: str = "agent", source: str | None = None) -> None:
        """Raise :class:`SpacetimeInputError` naming ``where`` and the field on bad values."""
        n = len(self.t_s)
        if n == 0:
            raise _fail("no samples", f"{where}.t_s", [], source)
        for name in ("t_s", "x_m", "y_m", "heading_rad"):
            v = getattr(self, name)
            if v.shape != (n,):
                raise _fail(f"expected shape ({n},)", f"{where}.{name}", v.shape, source)
            bad = np.flatnonzero(~np.isfinite(v))
            if len(bad):
                raise _fail(f"not finite at sample {int(bad[0])}", f"{where}.{name}",
                            float(v[bad[0]]), source)
        steps = np.diff(self.t_s)
        bad = np.flatnonzero(steps <= 0)
        if len(bad):
            k = int(bad[0])
            raise _fail(f"times must increase strictly (sample {k + 1} after {k})",
                        f"{where}.t_s", float(self.t_s[k + 1]), source)
        length, width = self.body_m
        if not (math.isfinite(length) and math.isfinite(width) and length > 0 and width > 0):
            raise _fail("length and width must be positive and finite", f"{where}.body_m",
                        self.body_m, source)
        if self.shelf_m is not None:
            s = self.shelf_m
            if s.shape != (n, 2):
                raise _fail(f"expected shape ({n}, 2)", f"{where}.shelf_m", s.shape, source)
            bad = np.flatnonzero(~np.isfinite(s).all(axis=1) | (s < 0).any(axis=1))
            if len(bad):
                raise _fail(f"not finite or negative at sample {int(bad[0])}",
                            f"{where}.shelf_m", s[bad[0]].tolist(), source)


@dataclass(frozen=True, eq=False)
class TimedPlan:
    """Timed poses of every agent, keyed by agent id (see the module docstring).

    ``cell_m`` (optional) lets conflicts name a cell; ``source`` names the file the plan came
    from in error messages."""

    agents: Mapping[int, AgentMotion]
    cell_m: float | None = None
    source: str | None = None

    def __post_init__(self) -> None:
        for aid, m in self.agents.items():
            m.check(f"agents[{aid}]", self.source)

    @property
    def end_s(self) -> float:
        """The last sample time of any agent (agents hold their last pose until then)."""
        return max((float(m.t_s[-1]) for m in self.agents.values()), default=0.0)

    @property
    def samples(self) -> int:
        return sum(len(m.t_s) for m in self.agents.values())


def _footprint(value, i: int) -> int:
    """One agent's footprint from an int for all, a mapping or a sequence by agent."""
    if value is None:
        return 1
    if isinstance(value, Mapping):
        return int(value.get(i, 1))
    if isinstance(value, int | np.integer):
        return int(value)
    return int(value[i])


def _body(value, i: int, cell_m: float) -> tuple[float, float]:
    """One agent's body from a pair for all, a mapping or a sequence of pairs by agent."""
    if value is None:
        return (DEFAULT_BODY_M[0] * cell_m, DEFAULT_BODY_M[1] * cell_m)
    if isinstance(value, Mapping):
        if i not in value:
            return (DEFAULT_BODY_M[0] * cell_m, DEFAULT_BODY_M[1] * cell_m)
        value = value[i]
    elif len(value) and isinstance(value[0], Sequence | np.ndarray):
        value = value[i]
    return (float(value[0]), float(value[1]))


def from_plan(plan, *, cell_m: float = 1.0, tick_s: float = 1.0,
              footprints: Mapping[int, int] | Sequence[int] | int | None = None,
              body_m: Mapping[int, Sequence[float]] | Sequence | None = None,
              start_s: float = 0.0) -> TimedPlan:
    """A unit-time :class:`~warerover_phys.plans.model.Plan` (a cell per timestep) as a timed
    plan: sample ``t`` at ``start_s + t * tick_s``, body centred on the footprint.

    ``footprints``: side of each agent's square footprint in cells (one int for all, a
    sequence or a mapping by agent index; default 1). ``body_m``: ``(length, width)`` for all
    or per agent (default 0.7 x 0.7 m scaled by ``cell_m``). Headings: the plan's (0..3 x
    pi / 2) where it has them, else 0 (an omnidirectional reading: the body does not turn).

    >>> from warerover_phys.plans.model import Plan
    >>> tp = from_plan(Plan(paths=(((0, 0), (0, 1)),)), cell_m=2.0)
    >>> tp.agents[0].x_m.tolist(), tp.agents[0].y_m.tolist()
    ([1.0, 3.0], [1.0, 1.0])
    """
    agents = {}
    for i, path in enumerate(plan.paths):
        k = _footprint(footprints, i)
        body = _body(body_m, i, cell_m)
        cells = np.asarray(path, dtype=float).reshape(-1, 2)
        heads = (np.asarray(plan.headings[i], dtype=float) * (math.pi / 2)
                 if plan.headings is not None else np.zeros(len(cells)))
        agents[i] = AgentMotion(start_s + np.arange(len(cells)) * tick_s,
                                (cells[:, 1] + k / 2) * cell_m, (cells[:, 0] + k / 2) * cell_m,
                                heads, body)
    return TimedPlan(agents, cell_m=cell_m)


def from_schedule(schedules: Mapping[int, Sequence[tuple]], *, cell_m: float = 1.0,
                  footprints: Mapping[int, int] | int | None = None,
                  body_m: Mapping[int, Sequence[float]] | Sequence[float] | None = None,
                  source: str | None = None) -> TimedPlan:
    """Timed schedules of cells: per agent id a list of ``(cell, t_s)`` or ``(cell,
    heading, t_s)`` (``cell = (row, col)``, ``heading`` 0..3 as in plans, ``t_s`` seconds),
    the agent moving in a straight line between consecutive entries. This is the form a
    duration-aware plan takes (each action: where it ends and when).

    >>> tp = from_schedule({7: [((0, 0), 0.0), ((0, 3), 2.5)]})
    >>> tp.agents[7].x_m.tolist(), tp.agents[7].t_s.tolist()
    ([0.5, 3.5], [0.0, 2.5])
    """
    agents = {}
    for aid, entries in schedules.items():
        k = _footprint(footprints, aid)
        body = _body(body_m, aid, cell_m)
        xs, ys, hs, ts = [], [], [], []
        for j, entry in enumerate(entries):
            if len(entry) == 2:
                cell, t = entry
                h = 0
            elif len(entry) == 3:
                cell, h, t = entry
            else:
                raise _fail("expected (cell, t_s) or (cell, heading, t_s)",
                            f"schedules[{aid}][{j}]", entry, source)
            if len(cell) != 2:
                raise _fail("expected a cell (row, col)", f"schedules[{aid}][{j}]", entry,
                            source)
            r, c = cell
            xs.append((c + k / 2) * cell_m)
            ys.append((r + k / 2) * cell_m)
            hs.append(float(h) * math.pi / 2)
            ts.append(float(t))
        agents[aid] = AgentMotion(np.asarray(ts), np.asarray(xs, dtype=float),
                                  np.asarray(ys, dtype=float), np.asarray(hs), body)
    return TimedPlan(agents, cell_m=cell_m, source=source)


_REQUIRED = ("t", "x", "y", "heading", "body_m")


def from_trajectory(traj: Mapping[str, np.ndarray], source: str = "trajectories.npz",
                    shelves: bool = True) -> TimedPlan:
    """An executed run's ``trajectories.npz`` arrays as a timed plan: ``t`` (T,), ``x``,
    ``y``, ``heading`` (T, N), ``body_m`` (N, 2), ``shelf_m`` (T, N, 2; optional: grid runs
    have none; ``shelves=False`` leaves shelves out), ``cell_m`` (optional)."""
    for key in _REQUIRED:
        if key not in traj:
            raise _fail("missing field", key, sorted(traj), source)
    try:
        t = np.asarray(traj["t"], dtype=float)
        x, y, h = (np.asarray(traj[k], dtype=float) for k in ("x", "y", "heading"))
        body = np.asarray(traj["body_m"], dtype=float)
    except (TypeError, ValueError) as err:
        raise _fail(f"not numeric ({err})", "t/x/y/heading/body_m", None, source) from None
    if t.ndim != 1 or len(t) == 0:
        raise _fail("expected a non-empty 1-D array of sample times", "t", t.shape, source)
    samples = len(t)
    if x.ndim != 2 or x.shape[0] != samples:
        raise _fail(f"expected shape ({samples}, N)", "x", x.shape, source)
    n = x.shape[1]
    for key, arr in (("y", y), ("heading", h)):
        if arr.shape != (samples, n):
            raise _fail(f"expected shape ({samples}, {n}) like x", key, arr.shape, source)
    if body.shape != (n, 2):
        raise _fail(f"expected shape ({n}, 2)", "body_m", body.shape, source)
    shelf = None
    if shelves and "shelf_m" in traj:
        shelf = np.asarray(traj["shelf_m"], dtype=float)
        if shelf.shape != (samples, n, 2):
            raise _fail(f"expected shape ({samples}, {n}, 2)", "shelf_m", shelf.shape, source)
    bad = np.flatnonzero(~np.isfinite(t))
    if len(bad):
        raise _fail(f"not finite at sample {int(bad[0])}", "t", float(t[bad[0]]), source)
    bad = np.flatnonzero(np.diff(t) <= 0)
    if len(bad):
        k = int(bad[0]) + 1
        raise _fail(f"sample times must increase strictly (sample {k})", "t", float(t[k]),
                    source)
    for key, arr in (("x", x), ("y", y), ("heading", h)):
        bad = np.argwhere(~np.isfinite(arr))
        if len(bad):
            s, a = (int(v) for v in bad[0])
            raise _fail(f"not finite at sample {s}, AGV {a}", key, float(arr[s, a]), source)
    bad = np.flatnonzero(~(np.isfinite(body) & (body > 0)).all(axis=1))
    if len(bad):
        raise _fail(f"AGV {int(bad[0])}: length and width must be positive", "body_m",
                    body[bad[0]].tolist(), source)
    if shelf is not None:
        bad = np.argwhere(~(np.isfinite(shelf) & (shelf >= 0)).all(axis=2))
        if len(bad):
            s, a = (int(v) for v in bad[0])
            raise _fail(f"not finite or negative at sample {s}, AGV {a}", "shelf_m",
                        shelf[s, a].tolist(), source)
    cell_m = None
    if "cell_m" in traj:
        try:
            cell_m = float(np.asarray(traj["cell_m"]))
        except (TypeError, ValueError):
            raise _fail("expected a number", "cell_m", traj["cell_m"], source) from None
        if not (math.isfinite(cell_m) and cell_m > 0):
            raise _fail("must be positive", "cell_m", cell_m, source)
    agents = {a: AgentMotion(t, x[:, a], y[:, a], h[:, a], (float(body[a, 0]),
                                                             float(body[a, 1])),
                             None if shelf is None else shelf[:, a])
              for a in range(n)}
    return TimedPlan(agents, cell_m=cell_m, source=source)


def load_trajectory_file(path: str | Path, shelves: bool = True) -> TimedPlan:
    """Read ``trajectories.npz`` (or a run folder holding one) into a timed plan; every
    problem is a :class:`SpacetimeInputError` naming the file."""
    p = Path(path)
    if p.is_dir():
        p = p / "trajectories.npz"
    from ..inputs import check_regular_file, load_npz
    from ..util.atomic import check_set

    try:
        check_regular_file(p, "trajectory")
        check_set(p.parent)  # a half-written or mixed run folder is refused
        traj = load_npz(p, "trajectory")
    except ScenarioError as err:
        raise SpacetimeInputError(err.message, file=str(p)) from None
    except zlib.error as err:
        raise SpacetimeInputError(f"cannot read trajectories ({err})", file=str(p)) from None
    return from_trajectory(traj, str(p), shelves=shelves)
