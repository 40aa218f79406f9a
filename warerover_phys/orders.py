"""Order streams: which SKU is wanted at which station, and when.

An :class:`OrderStream` turns an :class:`~warerover_phys.config.OrdersSpec` into orders, one
tick at a time. The five patterns follow WareRover:

``oneshot``
    ``count`` orders, all at tick 0.
``constant``
    ``batch`` orders at every tick ``t`` with ``t % every_ticks == 0``.
``wave``
    A batch every ``every_ticks`` of ``round(base * m(t))`` orders, the multiplier ``m(t)``
    moving between ``min_mult`` and ``max_mult`` over ``cycle_ticks`` (sine or square).
``hotspot``
    A batch every ``every_ticks`` of ``int(scale * P)`` orders, ``P`` classical Pareto(alpha)
    with minimum 1; a hot ``hot_fraction`` of each size class's SKUs gets ``hot_share`` of
    the picks.
``burst``
    ``base`` orders every ``every_ticks``; at each tick with no burst running a burst starts
    with probability ``start_prob`` and adds ``burst_orders`` orders at its start and every
    ``burst_every_ticks`` after, for ``burst_ticks`` ticks.

Streaming patterns only produce orders in ticks ``[0, duration_ticks)``.

Each order first draws its size class (``P(size 2) = large_fraction`` when given, else each
class in proportion to its number of SKUs), then a SKU of that class, then a station,
uniformly (among the stations ``stations_by_size`` lists for its class, when given). Every random number comes from the generator handed in, in a fixed order, so the
same seed gives the same orders.

>>> import numpy as np
>>> from warerover_phys.config import OrdersSpec
>>> stream = OrderStream(OrdersSpec(pattern="oneshot"), [1, 1, 2], 2, np.random.default_rng(0))
>>> len(stream.arrivals(0)), stream.arrivals(1), stream.exhausted(0)
(20, [], True)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .config import OrdersSpec

__all__ = ["Order", "OrderStream"]

_LARGE = 2
"""The size class ``OrdersSpec.large_fraction`` refers to."""

HOTSPOT_MAX_FACTOR = 1000.0
"""A hotspot batch is at most this many times ``scale`` (a Pareto draw beyond it, probability
10^-6 at alpha 2, is cut there): batch sizes stay finite for any alpha."""


@dataclass(frozen=True, slots=True)
class Order:
    """One order: bring a container of SKU ``sku`` (size class ``size``) to ``station``."""

    id: int
    """0, 1, 2, ... in arrival order."""
    tick: int
    """Arrival tick."""
    sku: int
    station: int
    """Index into the layout's stations."""
    size: int
    """Container size class the order needs (``sku_sizes[sku]``)."""
    errands: tuple[int, ...] = ()
    """An errand task (``orders.pattern: errands``, :mod:`~warerover_phys.problems.errands`): the
    cells (nodes ``row * cols + col``) its AGV visits in order; ``sku`` and ``station`` are
    then -1. Empty for a shelf order."""
    for_agv: int | None = None
    """The AGV an errand task is released for (``assign: roundrobin``), else None."""


class OrderStream:
    """The orders of one episode, handed out tick by tick.

    Call :meth:`arrivals` once per tick with ticks 0, 1, 2, ... in order. ``rng`` is used
    for every draw (and, for ``hotspot``, for the hot set at construction).
    """

    def __init__(self, spec: OrdersSpec, sku_sizes: Sequence[int], num_stations: int,
                 rng: np.random.Generator) -> None:
        sizes = [_as_int(s, "sku size") for s in sku_sizes]
        if not sizes:
            raise ValueError("order stream needs at least one SKU (sku_sizes is empty)")
        bad = [s for s in sizes if s < 1]
        if bad:
            raise ValueError(f"SKU size classes must be >= 1 (got {bad[0]})")
        num_stations = _as_int(num_stations, "num_stations")
        if num_stations < 1:
            raise ValueError(f"order stream needs num_stations >= 1 (got {num_stations})")
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng must be a numpy.random.Generator (got {type(rng).__name__})")

        self.spec = spec
        self.num_stations = num_stations
        self._sizes = tuple(sizes)
        self._rng = rng
        self._next_id = 0
        self._next_tick = 0
        self._burst_start: int | None = None
        self._last_order_tick = -1

        classes = sorted(set(sizes))
        self._classes = np.array(classes, dtype=np.int64)
        self._class_skus = [np.array([i for i, s in enumerate(sizes) if s == c], dtype=np.int64)
                            for c in classes]
        counts = np.array([len(s) for s in self._class_skus], dtype=float)
        probs = counts / counts.sum()
        lf = spec.large_fraction
        if lf is not None and len(classes) > 1 and _LARGE in classes:
            large = classes.index(_LARGE)
            rest = counts.copy()
            rest[large] = 0.0
            probs = (1.0 - lf) * rest / rest.sum()
            probs[large] = lf
        cum = np.cumsum(probs)
        cum[-1] = 1.0
        self._class_cum = cum

        if spec.pattern == "hotspot":
            hs = spec.hotspot
            self._hot: list[np.ndarray] = []
            self._cold: list[np.ndarray] = []
            for skus in self._class_skus:
                perm = rng.permutation(skus)
                n_hot = max(1, math.ceil(hs.hot_fraction * len(perm) - 1e-9))
                self._hot.append(perm[:n_hot])
                self._cold.append(perm[n_hot:])

        for size, pool in (spec.stations_by_size or {}).items():
            bad = [s for s in pool if s >= num_stations]
            if bad:
                raise ValueError(f"stations_by_size[{size}] names station {bad[0]}, but there "
                                 f"are {num_stations} (indices 0..{num_stations - 1})")
        self._last_tick = self._last_possible_tick()

    # ------------------------------------------------------------------ public

    def arrivals(self, tick: int) -> list[Order]:
        """The orders arriving at ``tick`` (ticks must be asked 0, 1, 2, ... in order)."""
        if tick != self._next_tick:
            raise ValueError(f"arrivals() must be called for ticks 0, 1, 2, ... in order: "
                             f"expected tick {self._next_tick}, got {tick}")
        self._next_tick += 1
        n = self._batch_size(tick)
        if n <= 0:
            return []
        self._last_order_tick = tick
        return self._draw_orders(tick, n)

    def exhausted(self, tick: int) -> bool:
        """True when no order will arrive at any tick after ``tick``.

        Any tick may be asked; for ``burst`` the answer uses what the ticks simulated so far
        decided (a tick not simulated yet may still start a burst). For ``hotspot`` with
        ``scale < 1`` (batches that may be empty) the answer is conservative: True from the
        last batch tick on.
        """
        if tick >= self._last_tick:
            return True
        if self.spec.pattern != "burst":
            return False
        return self._burst_exhausted(tick)

    # ------------------------------------------------------------------ sizes

    def _batch_size(self, t: int) -> int:
        """Number of orders at tick ``t``; draws from the rng where the pattern is random."""
        spec = self.spec
        pattern = spec.pattern
        if pattern == "oneshot":
            return spec.oneshot.count if t == 0 else 0
        if t < 0 or t >= spec.duration_ticks:
            return 0
        if pattern == "constant":
            c = spec.constant
            return c.batch if t % c.every_ticks == 0 else 0
        if pattern == "wave":
            return self._wave_size(t) if t % spec.wave.every_ticks == 0 else 0
        if pattern == "hotspot":
            h = spec.hotspot
            if t % h.every_ticks != 0:
                return 0
            draw = min(self._rng.pareto(h.alpha) + 1.0, HOTSPOT_MAX_FACTOR)   # finite
            return int(draw * h.scale)
        # burst
        b = spec.burst
        if not self._burst_running(t) and self._rng.random() < b.start_prob:
            self._burst_start = t
        n = b.base if t % b.every_ticks == 0 else 0
        if self._burst_running(t) and (t - self._burst_start) % b.burst_every_ticks == 0:
            n += b.burst_orders
        return n

    def _wave_size(self, t: int) -> int:
        w = self.spec.wave
        if w.shape == "sine":
            phase = 0.5 + 0.5 * math.sin(2.0 * math.pi * t / w.cycle_ticks)
            mult = w.min_mult + (w.max_mult - w.min_mult) * phase
        else:
            mult = w.max_mult if 2 * (t % w.cycle_ticks) < w.cycle_ticks else w.min_mult
        return round(w.base * mult)

    def _burst_running(self, t: int) -> bool:
        s = self._burst_start
        return s is not None and s <= t < s + self.spec.burst.burst_ticks

    # ------------------------------------------------------------------ exhaustion

    def _last_possible_tick(self) -> int:
        """Last tick at which an order may arrive (-1: none ever)."""
        spec = self.spec
        if spec.pattern == "oneshot":
            return 0
        d = spec.duration_ticks
        if spec.pattern == "burst":
            return d - 1 if spec.burst.start_prob > 0 else _last_multiple(spec.burst.every_ticks, d)
        if spec.pattern == "constant":
            return _last_multiple(spec.constant.every_ticks, d)
        if spec.pattern == "hotspot":
            return _last_multiple(spec.hotspot.every_ticks, d)
        every = spec.wave.every_ticks
        t = _last_multiple(every, d)
        while t >= 0 and self._wave_size(t) <= 0:
            t -= every
        return max(t, -1)

    def _burst_exhausted(self, tick: int) -> bool:
        b = self.spec.burst
        d = self.spec.duration_ticks
        if self._last_order_tick > tick or _last_multiple(b.every_ticks, d) > tick:
            return False
        if b.start_prob == 0:
            return True
        first_unseen = self._next_tick
        if first_unseen >= d:
            return True
        # Unless the running burst covers every tick still to simulate, a new one may start
        # at duration_ticks - 1 > tick.
        s = self._burst_start
        if s is None or s + b.burst_ticks < d:
            return False
        start = max(tick + 1, first_unseen)
        k = -(-(start - s) // b.burst_every_ticks)
        return s + k * b.burst_every_ticks >= d

    # ------------------------------------------------------------------ drawing

    def _draw_orders(self, tick: int, n: int) -> list[Order]:
        """``n`` orders at ``tick``: draw size classes, then SKUs, then stations."""
        rng = self._rng
        cls = np.searchsorted(self._class_cum, rng.random(n), side="right")
        if self.spec.pattern == "hotspot":
            skus = self._draw_hot_skus(cls)
        else:
            counts = np.array([len(self._class_skus[c]) for c in cls], dtype=np.int64)
            idx = rng.integers(0, counts)
            skus = [int(self._class_skus[c][i]) for c, i in zip(cls, idx, strict=True)]
        by_size = self.spec.stations_by_size
        if by_size:
            sizes = self._sizes
            pools = [by_size.get(sizes[s]) or range(self.num_stations) for s in skus]
            idx = rng.integers(0, np.array([len(p) for p in pools], dtype=np.int64))
            stations = [int(p[i]) for p, i in zip(pools, idx.tolist(), strict=True)]
        else:
            stations = rng.integers(0, self.num_stations, size=n).tolist()
        first = self._next_id
        self._next_id += n
        sizes = self._sizes
        return [Order(first + k, tick, sku, st, sizes[sku])
                for k, (sku, st) in enumerate(zip(skus, stations, strict=True))]

    def _draw_hot_skus(self, cls: np.ndarray) -> list[int]:
        rng = self._rng
        n = len(cls)
        hot = rng.random(n) < self.spec.hotspot.hot_share
        pools = [(self._hot[c] if h or len(self._cold[c]) == 0 else self._cold[c])
                 for c, h in zip(cls, hot, strict=True)]
        idx = rng.integers(0, np.array([len(p) for p in pools], dtype=np.int64))
        return [int(p[i]) for p, i in zip(pools, idx, strict=True)]


def _last_multiple(every: int, duration: int) -> int:
    """Largest multiple of ``every`` below ``duration``."""
    return ((duration - 1) // every) * every


def _as_int(value: object, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{what} must be an integer (got {value!r})")
    return int(value)
