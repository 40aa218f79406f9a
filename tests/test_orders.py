"""Order streams: patterns, SKU / size / station draws, determinism and exhaustion."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from warerover_phys.config import OrdersSpec
from warerover_phys.orders import Order, OrderStream

MIXED = [1] * 20 + [2] * 5


def make(pattern: str = "oneshot", sku_sizes=MIXED, stations: int = 4, seed: int = 0,
         **fields) -> OrderStream:
    spec = OrdersSpec.model_validate({"pattern": pattern, **fields})
    return OrderStream(spec, sku_sizes, stations, np.random.default_rng(seed))


def run(stream: OrderStream, ticks: int) -> list[Order]:
    orders: list[Order] = []
    for t in range(ticks):
        got = stream.arrivals(t)
        assert all(o.tick == t for o in got)
        orders.extend(got)
    return orders


def per_tick(orders: list[Order]) -> Counter[int]:
    return Counter(o.tick for o in orders)


def hot_share(orders: list[Order], num_skus: int, fraction: float = 0.2) -> float:
    counts = Counter(o.sku for o in orders)
    top = sorted((counts.get(s, 0) for s in range(num_skus)), reverse=True)
    return sum(top[: round(fraction * num_skus)]) / len(orders)


# ------------------------------------------------------------------ determinism


@pytest.mark.parametrize("pattern", ["oneshot", "constant", "wave", "hotspot", "burst"])
def test_same_seed_same_orders_different_seed_different(pattern):
    a = run(make(pattern, seed=7), 400)
    b = run(make(pattern, seed=7), 400)
    c = run(make(pattern, seed=8), 400)
    assert a and a == b
    assert a != c


# ------------------------------------------------------------------ patterns


def test_oneshot_all_orders_at_tick_zero():
    stream = make("oneshot", oneshot={"count": 37})
    first = stream.arrivals(0)
    assert len(first) == 37
    assert [o.id for o in first] == list(range(37))
    assert all(stream.arrivals(t) == [] for t in range(1, 50))
    assert stream.exhausted(0)
    assert stream.exhausted(10)


def test_constant_exact_counts_at_exact_ticks():
    stream = make("constant", duration_ticks=100, constant={"batch": 7, "every_ticks": 13})
    orders = run(stream, 150)
    assert per_tick(orders) == {t: 7 for t in range(0, 100, 13)}
    assert [o.id for o in orders] == list(range(len(orders)))
    assert not stream.exhausted(90)
    assert stream.exhausted(91)


def test_constant_exhausted_is_false_until_last_batch():
    stream = make("constant", duration_ticks=100, constant={"batch": 2, "every_ticks": 10})
    for t in range(120):
        stream.arrivals(t)
        assert stream.exhausted(t) == (t >= 90), t


def test_wave_square_alternates_between_max_and_min():
    wave = {"base": 10, "min_mult": 0.3, "max_mult": 3.0, "cycle_ticks": 80,
            "every_ticks": 20, "shape": "square"}
    orders = run(make("wave", duration_ticks=400, wave=wave), 400)
    sizes = per_tick(orders)
    expected = {t: (30 if t % 80 < 40 else 3) for t in range(0, 400, 20)}
    assert sizes == expected


def test_wave_sine_follows_the_multiplier():
    wave = {"base": 10, "min_mult": 0.3, "max_mult": 3.0, "cycle_ticks": 80,
            "every_ticks": 1, "shape": "sine"}
    orders = run(make("wave", duration_ticks=160, wave=wave), 160)
    sizes = [per_tick(orders)[t] for t in range(160)]
    assert max(sizes) == 30 and min(sizes) == 3
    assert sizes[20] == sizes[100] == 30      # quarter cycle: sin = 1
    assert sizes[60] == sizes[140] == 3       # three quarters: sin = -1
    for t, n in enumerate(sizes):
        mult = 0.3 + 2.7 * (0.5 + 0.5 * math.sin(2 * math.pi * t / 80))
        assert abs(n - 10 * mult) <= 0.5 + 1e-9, t
    # A sine passes through many sizes; a square wave only two.
    assert len(set(sizes)) > 10
    assert sizes[:80] == sizes[80:]
    assert sizes[20:41] == sorted(sizes[20:41], reverse=True)


def test_wave_exhausted_skips_trailing_empty_batches():
    wave = {"base": 10, "min_mult": 0.0, "max_mult": 2.0, "cycle_ticks": 80,
            "every_ticks": 20, "shape": "square"}
    stream = make("wave", duration_ticks=80, wave=wave)
    orders = run(stream, 100)
    assert per_tick(orders) == {0: 20, 20: 20}
    assert not stream.exhausted(19)
    assert stream.exhausted(20)


def test_hotspot_hot_fifth_of_skus_gets_eighty_percent():
    sizes = [1] * 50 + [2] * 50
    stream = make("hotspot", sku_sizes=sizes, duration_ticks=2000,
                  hotspot={"every_ticks": 1})
    orders = run(stream, 2000)
    assert len(orders) > 20_000
    assert hot_share(orders, 100) == pytest.approx(0.8, abs=0.03)
    # Per size class: the hot set is 10 SKUs of each class.
    for cls in (1, 2):
        mine = [o for o in orders if o.size == cls]
        top = Counter(o.sku for o in mine).most_common(10)
        assert sum(n for _, n in top) / len(mine) == pytest.approx(0.8, abs=0.03)
        assert all(sizes[s] == cls for s, _ in top)
    # The hot set is fixed for the whole episode.
    half = len(orders) // 2
    first = {s for s, _ in Counter(o.sku for o in orders[:half]).most_common(20)}
    second = {s for s, _ in Counter(o.sku for o in orders[half:]).most_common(20)}
    assert first == second


def test_non_hotspot_patterns_pick_skus_uniformly():
    orders = make("oneshot", sku_sizes=[1] * 100, oneshot={"count": 20_000}).arrivals(0)
    assert hot_share(orders, 100) == pytest.approx(0.2, abs=0.03)


def test_hotspot_batch_sizes_are_classical_pareto():
    alpha, scale = 3.0, 10.0
    stream = make("hotspot", sku_sizes=[1], stations=1, duration_ticks=8000,
                  hotspot={"alpha": alpha, "scale": scale, "every_ticks": 1})
    batches = list(per_tick(run(stream, 8000)).values())
    assert len(batches) == 8000
    assert min(batches) == int(scale)      # classical Pareto: minimum is scale, not 0
    pareto_mean = scale * alpha / (alpha - 1)
    # int() truncates, taking ~0.5 off the mean.
    assert np.mean(batches) == pytest.approx(pareto_mean - 0.5, abs=0.4)


def test_hotspot_batches_only_every_ticks():
    stream = make("hotspot", duration_ticks=300, hotspot={"every_ticks": 30})
    ticks = set(per_tick(run(stream, 400)))
    assert ticks == set(range(0, 300, 30))
    assert not stream.exhausted(269)
    assert stream.exhausted(270)


def _burst_count_always_on(duration, base, every, burst_orders, burst_every, burst_ticks):
    total = 0
    for t in range(duration):
        if t % every == 0:
            total += base
        if (t % burst_ticks) % burst_every == 0:   # bursts back to back from tick 0
            total += burst_orders
    return total


def test_burst_start_prob_zero_gives_only_base():
    burst = {"base": 6, "every_ticks": 25, "start_prob": 0.0}
    stream = make("burst", duration_ticks=300, burst=burst)
    orders = run(stream, 400)
    assert per_tick(orders) == {t: 6 for t in range(0, 300, 25)}
    assert not stream.exhausted(274)
    assert stream.exhausted(275)


def test_burst_start_prob_one_bursts_back_to_back():
    burst = {"base": 6, "every_ticks": 25, "start_prob": 1.0, "burst_orders": 9,
             "burst_every_ticks": 5, "burst_ticks": 12}
    orders = run(make("burst", duration_ticks=300, burst=burst), 400)
    assert len(orders) == _burst_count_always_on(300, 6, 25, 9, 5, 12)
    counts = per_tick(orders)
    assert counts[0] == 6 + 9 and counts[5] == 9 and counts[10] == 9
    assert counts[12] == 9          # the next burst starts the tick the last one ended
    assert 11 not in counts and 15 not in counts and max(counts) < 300


def test_burst_exhausted_when_last_burst_has_no_batch_left():
    stream = make("burst", duration_ticks=400, burst={"start_prob": 1.0})
    for t in range(400):
        stream.arrivals(t)
        # Bursts at 0, 20, ..., 380 with batches every 5 ticks: last batch at 395.
        assert stream.exhausted(t) == (t >= 395), t
    # Asking about an earlier tick after the fact still counts the orders that came since.
    assert not stream.exhausted(390)
    assert not stream.exhausted(-1)


@pytest.mark.parametrize(("duration", "burst_ticks", "burst_every"), [
    (400, 20, 7), (401, 20, 7), (402, 20, 7), (399, 20, 7), (100, 30, 4), (97, 1, 1),
    (50, 60, 9),
])
def test_burst_always_on_exhausted_exactly_after_last_order(duration, burst_ticks, burst_every):
    # With start_prob 1 the stream is known in advance: exhausted(t) iff no order after t.
    burst = {"every_ticks": 1000, "start_prob": 1.0, "burst_ticks": burst_ticks,
             "burst_every_ticks": burst_every}
    stream = make("burst", duration_ticks=duration, burst=burst)
    answers, last = [], 0
    for t in range(duration + 10):
        if stream.arrivals(t):
            last = t
        answers.append(stream.exhausted(t))
    assert answers == [t >= last for t in range(duration + 10)]


def test_burst_not_exhausted_while_a_burst_may_still_start():
    # One-tick bursts never cover the end, so a burst may start at any tick up to 399.
    stream = make("burst", duration_ticks=400, burst={"start_prob": 0.3, "burst_ticks": 1})
    assert run(stream, 398)
    assert not stream.exhausted(397)
    stream.arrivals(398)
    assert not stream.exhausted(398)
    stream.arrivals(399)
    assert stream.exhausted(399)


def test_burst_exhausted_right_after_last_batch_of_a_burst_that_runs_to_the_end():
    # A burst lasting the whole episode covers every tick after its start, so no other can
    # start: exhausted() turns True exactly at its last batch.
    burst = {"every_ticks": 1000, "start_prob": 0.3, "burst_ticks": 400,
             "burst_every_ticks": 7}
    for seed in range(10):
        stream = make("burst", duration_ticks=400, seed=seed, burst=burst)
        answers, last = [], 0
        for t in range(410):
            if stream.arrivals(t):
                last = t
            answers.append(stream.exhausted(t))
        assert last > 390
        assert answers == [t >= last for t in range(410)]


def test_burst_default_total_over_long_horizon():
    duration = 10_000
    b = OrdersSpec().burst
    orders = run(make("burst", duration_ticks=duration), duration)
    # Renewal: idle ticks before a start ~ Geometric (mean (1-p)/p), then burst_ticks.
    cycle = (1 - b.start_prob) / b.start_prob + b.burst_ticks
    per_burst = b.burst_orders * math.ceil(b.burst_ticks / b.burst_every_ticks)
    expected = duration / b.every_ticks * b.base + duration / cycle * per_burst
    assert len(orders) == pytest.approx(expected, rel=0.12)


# ------------------------------------------------------------------ order fields


def test_large_fraction_sets_share_of_size_two():
    orders = make("oneshot", large_fraction=0.3, oneshot={"count": 20_000}).arrivals(0)
    assert all(o.size == MIXED[o.sku] for o in orders)
    share = sum(o.size == 2 for o in orders) / len(orders)
    assert share == pytest.approx(0.3, abs=0.02)
    # Within a class, SKUs are uniform: 20 size-1 SKUs share ~70% of 20000 orders.
    small = Counter(o.sku for o in orders if o.size == 1)
    assert set(small) == set(range(20))
    assert all(abs(n - 700) < 130 for n in small.values())


def test_default_size_share_follows_sku_counts():
    orders = make("oneshot", oneshot={"count": 20_000}).arrivals(0)
    share = sum(o.size == 2 for o in orders) / len(orders)
    assert share == pytest.approx(5 / 25, abs=0.02)


@pytest.mark.parametrize(("fraction", "sizes", "expect"), [
    (1.0, MIXED, {2}),
    (0.0, MIXED, {1}),
    (0.7, [1, 1, 1], {1}),     # only one class exists: use it
    (0.0, [2, 2], {2}),
])
def test_large_fraction_edge_cases(fraction, sizes, expect):
    orders = make("oneshot", sku_sizes=sizes, large_fraction=fraction,
                  oneshot={"count": 500}).arrivals(0)
    assert {o.size for o in orders} == expect
    assert all(o.size == sizes[o.sku] for o in orders)


def test_stations_in_range_and_uniform():
    orders = make("oneshot", stations=5, oneshot={"count": 20_000}).arrivals(0)
    counts = Counter(o.station for o in orders)
    assert set(counts) == set(range(5))
    assert all(abs(n - 4000) < 250 for n in counts.values())


def test_ids_consecutive_across_ticks():
    orders = run(make("burst", burst={"start_prob": 0.2}), 400)
    assert len(orders) > 100
    assert [o.id for o in orders] == list(range(len(orders)))
    assert [o.tick for o in orders] == sorted(o.tick for o in orders)


def test_order_is_frozen():
    order = make("oneshot").arrivals(0)[0]
    with pytest.raises(AttributeError):
        order.sku = 3  # type: ignore[misc]
    assert all(type(v) is int for v in (order.id, order.tick, order.sku, order.station,
                                        order.size))


# ------------------------------------------------------------------ validation


@pytest.mark.parametrize(("sizes", "stations", "match"), [
    ([], 2, "SKU"),
    ([1, 2], 0, "num_stations"),
    ([1, 0], 2, "size"),
])
def test_bad_inputs_raise_value_error(sizes, stations, match):
    with pytest.raises(ValueError, match=match):
        OrderStream(OrdersSpec(), sizes, stations, np.random.default_rng(0))


def test_ticks_must_be_asked_in_order():
    stream = make("constant")
    stream.arrivals(0)
    with pytest.raises(ValueError, match="in order"):
        stream.arrivals(2)
    with pytest.raises(ValueError, match="in order"):
        stream.arrivals(0)


# ------------------------------------------------------------------ property


@st.composite
def specs(draw):
    duration = draw(st.integers(1, 120))
    lo = draw(st.floats(0.0, 2.0))
    return {
        "pattern": draw(st.sampled_from(["oneshot", "constant", "wave", "hotspot", "burst"])),
        "duration_ticks": duration,
        "large_fraction": draw(st.none() | st.floats(0.0, 1.0)),
        "oneshot": {"count": draw(st.integers(1, 60))},
        "constant": {"batch": draw(st.integers(1, 20)), "every_ticks": draw(st.integers(1, 40))},
        "wave": {"base": draw(st.integers(1, 15)), "min_mult": lo,
                 "max_mult": lo + draw(st.floats(0.0, 2.0)),
                 "cycle_ticks": draw(st.integers(1, 100)),
                 "every_ticks": draw(st.integers(1, 30)),
                 "shape": draw(st.sampled_from(["sine", "square"]))},
        "hotspot": {"alpha": draw(st.floats(1.5, 5.0)), "scale": draw(st.floats(0.5, 15.0)),
                    "every_ticks": draw(st.integers(1, 30)),
                    "hot_fraction": draw(st.floats(0.05, 0.95)),
                    "hot_share": draw(st.floats(0.05, 0.95))},
        "burst": {"base": draw(st.integers(1, 10)), "every_ticks": draw(st.integers(1, 40)),
                  "start_prob": draw(st.floats(0.0, 1.0)),
                  "burst_orders": draw(st.integers(1, 15)),
                  "burst_every_ticks": draw(st.integers(1, 10)),
                  "burst_ticks": draw(st.integers(1, 30))},
    }


@settings(max_examples=60, deadline=None)
@given(data=specs(), sizes=st.lists(st.integers(1, 3), min_size=1, max_size=30),
       stations=st.integers(1, 6), seed=st.integers(0, 2**32 - 1))
def test_every_order_is_valid(data, sizes, stations, seed):
    spec = OrdersSpec.model_validate(data)
    stream = OrderStream(spec, sizes, stations, np.random.default_rng(seed))
    orders: list[Order] = []
    exhausted_at = None
    for t in range(spec.duration_ticks + 5):
        got = stream.arrivals(t)
        if exhausted_at is not None:
            assert got == [], "orders arrived after exhausted()"
        for o in got:
            assert o.tick == t
            assert 0 <= o.sku < len(sizes)
            assert o.size == sizes[o.sku]
            assert 0 <= o.station < stations
        orders.extend(got)
        if stream.exhausted(t):
            exhausted_at = t if exhausted_at is None else exhausted_at
        else:
            assert exhausted_at is None, "exhausted() went back to False"
    assert exhausted_at is not None and exhausted_at <= max(0, spec.duration_ticks - 1)
    assert [o.id for o in orders] == list(range(len(orders)))
