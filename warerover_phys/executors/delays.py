"""Random delays of the physics executor (``executor.delays``), and their foresight.

:func:`delay_draws` is one tick's draws: the follower
(:meth:`~.follow.PlanFollower.draw_delays`) starts a delay for an AGV whose draw says so
and that no delay holds now. The draws do not depend on what the AGVs do, so the delays
to come are known to whoever holds a copy of the generator:
:class:`DelayForesight` replays them, for the clairvoyant estimates of the reorderer
(``executor.reorder_estimates: clairvoyant``, :mod:`.reorder`), a bound on what better
estimates could win. No real fleet knows its delays ahead.

A delay of ``k`` ticks holds an AGV for ``k x tick_s`` seconds: the physics steps that
start before its end, by more than half a step (:func:`held`). The executor's clock is a
sum of ``dt_s`` steps, a few 1e-14 s off a tick's multiple after a while; compared
exactly, a delay often ended a few 1e-14 s after the clock's tick, held its AGV one step
more and let no new delay start on that tick (until 2026-11-29: on one seed's draws,
400 AGVs, 700 ticks, bernoulli 0.1, 1 to 10 ticks, 13,794 of 18,774 ends, and 18,523
delays started instead of 19,406).
"""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..config import DelaySpec

__all__ = ["delay_draws", "held", "DelayForesight"]


def held(until: np.ndarray | float, t: float, dt: float) -> np.ndarray | bool:
    """Whether a delay that ends at ``until`` holds its AGV in the physics step that
    starts at ``t`` (length ``dt``): it ends more than half a step later. A delay that
    ends at a tick's time holds its AGV exactly until that tick's first step, whatever
    the clock's rounding; a new delay may start on that tick."""
    return until > t + 0.5 * dt


def delay_draws(rng: np.random.Generator, d: DelaySpec, n: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """One tick's draws of delays ``d`` for ``n`` AGVs: per AGV whether a delay would
    start (probability ``prob``; Poisson: at least one event at rate ``prob``) and its
    length in ticks (uniform on ``[min_ticks, max_ticks]``, or normal, rounded and
    clipped to them)."""
    if d.model == "bernoulli":
        events = rng.random(n) < d.prob
    else:
        events = rng.poisson(d.prob, n) > 0
    if d.duration == "uniform":
        ticks = rng.integers(d.min_ticks, d.max_ticks + 1, n)
    else:
        ticks = np.clip(np.rint(rng.normal(d.mean_ticks, d.std_ticks, n)),
                        d.min_ticks, d.max_ticks)
    return events, ticks


class DelayForesight:
    """The delays each AGV will have: replays :func:`delay_draws` on a copy of the
    executor's generator, taken before the tick whose simulated time is ``t0_s``, one
    draw a tick (``tick_s``) as the executor makes them, its clock advanced as the
    executor's is (``steps_per_tick`` additions of ``dt_s``, and :func:`held` on it).
    Drawn ahead in chunks as far as it is asked about."""

    CHUNK = 512
    """Ticks drawn at a time."""

    def __init__(self, rng: np.random.Generator, d: DelaySpec, n: int, *, t0_s: float,
                 tick_s: float, dt_s: float) -> None:
        self._rng = copy.deepcopy(rng)
        self._d, self._n = d, n
        self._dt, self._tick = float(dt_s), float(tick_s)
        self._steps = max(1, round(tick_s / dt_s))
        self._t = float(t0_s)
        """The clock at the next tick to draw."""
        self._until = np.zeros(n)
        self._iv: list[list[tuple[float, float]]] = [[] for _ in range(n)]
        self._arrays: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._first = True

    @property
    def horizon_s(self) -> float:
        """Drawn up to here (simulated seconds)."""
        return self._t

    def _draw(self) -> None:
        for _ in range(self.CHUNK):
            if not self._first:
                for _ in range(self._steps):
                    self._t = self._t + self._dt
            self._first = False
            events, ticks = delay_draws(self._rng, self._d, self._n)
            start = events & ~held(self._until, self._t, self._dt)
            self._until[start] = self._t + ticks[start] * self._tick
            for a in np.flatnonzero(start).tolist():
                self._iv[a].append((self._t, float(self._until[a])))
        self._arrays.clear()

    def intervals(self, a: int) -> list[tuple[float, float]]:
        """AGV ``a``'s delays drawn so far, ``(start, end)`` in simulated seconds."""
        return list(self._iv[a])

    def _of(self, a: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Starts, cumulative held time before each (and in all), and each start's
        free time (time not held since 0)."""
        got = self._arrays.get(a)
        if got is None:
            iv = np.asarray(self._iv[a], dtype=float).reshape(-1, 2)
            held = np.concatenate([[0.0], np.cumsum(iv[:, 1] - iv[:, 0])])
            got = self._arrays[a] = (iv[:, 0], held, iv[:, 0] - held[:-1])
        return got

    def _free(self, a: int, t: float) -> float:
        """Seconds of ``[0, t]`` in which AGV ``a`` is not held."""
        s, held, _ = self._of(a)
        k = int(np.searchsorted(s, t, "right")) - 1
        if k < 0:
            return t
        return t - held[k] - min(t - s[k], held[k + 1] - held[k])

    def after(self, a: int, t0: float, d: float) -> float:
        """When AGV ``a``, free to go at ``t0``, has had ``d`` seconds not held by a
        delay (it stands while one holds it)."""
        while self._t < t0 + d:
            self._draw()
        while True:
            s, held, free_at = self._of(a)
            g = self._free(a, t0) + d
            k = int(np.searchsorted(free_at, g, "left"))  # delays that start before
            out = max(t0, g + float(held[k]))  # (t0 may be within a delay)
            if out <= self._t:
                return out
            self._draw()
