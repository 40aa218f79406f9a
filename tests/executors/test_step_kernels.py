"""The compiled per-step accounting (:mod:`warerover_phys.executors.step_kernels`) against
its numpy reference: the same figures bit for bit.

- the limit monitor: peaks, ratios (with limits changed mid-run), lateral speeds,
  violations and their events, over random pose sequences in which most AGVs stand still;
- the clearance monitor: minimum, its time, and the neighbour list (the same pairs as the
  k-d tree's), with shelves picked up and put down;
- the delay shares and cause labels (with blocker look-ups) over random fleet states;
- a physics episode run with both engines: every metric, trajectory array and cause count.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from warerover_phys.executors import accounting
from warerover_phys.executors.causes import CauseRecorder
from warerover_phys.executors.measured import ClearanceMonitor, LimitMonitor
from warerover_phys.executors.step_kernels import near_pairs

seeds = st.integers(0, 2**32 - 1)


def poses(rng: np.random.Generator, n: int, steps: int, share: float, jump: float):
    """A pose sequence: each step a random share of AGVs moves (the rest keep their pose
    exactly), on a grid 1.1 m apart to start with."""
    side = max(1, int(math.ceil(math.sqrt(n))))
    pos = np.column_stack([np.arange(n) % side * 1.1, np.arange(n) // side * 1.1]) + 0.0
    ang = np.zeros(n)
    for _ in range(steps):
        moving = rng.random(n) < share
        pos = pos + moving[:, None] * rng.normal(0, jump, (n, 2))
        ang = ang + moving * rng.normal(0, 4 * jump, n)
        yield pos.copy(), ang.copy()


# --------------------------------------------------------------------------- limits

@settings(max_examples=40, deadline=None)
@given(seeds, st.integers(1, 14), st.floats(0.0, 0.6), st.sampled_from([0.02, 0.05, 0.1]),
       st.floats(0.005, 0.15))
def test_limit_monitor_kernel_is_the_numpy_reference(seed, n, share, dt, jump):
    rng = np.random.default_rng(seed)
    lim = {k: rng.uniform(0.5, 2.0, n) for k in ("v", "a", "w")}
    mons = [LimitMonitor(lim["v"], lim["a"], lim["w"], engine=e) for e in ("numpy", "numba")]
    events = ([], [])
    for s, (pos, ang) in enumerate(poses(rng, n, 60, share, jump)):
        if s in (20, 41):  # a payload: a new acceleration (or turn-rate) limit
            kind = "accel" if s == 20 else "turn_rate"
            new = rng.uniform(0.3, 2.0, n)
            for m in mons:
                m.set_limit(kind, new)
        t = s * dt
        for m, ev in zip(mons, events, strict=True):
            ev.extend(m.measure(pos, ang, t))
            assert m.measure(pos, ang, t) == []  # once per time
    ref, nb = mons
    assert events[0] == events[1]
    assert ref.violations == nb.violations == len(events[0])
    for kind in LimitMonitor.KINDS:
        assert np.array_equal(ref.peak[kind], nb.peak[kind]), kind
        assert np.array_equal(ref.peak_ratio(kind), nb.peak_ratio(kind)), kind
    assert np.array_equal(ref.lateral, nb.lateral)
    assert ref.ratios() == nb.ratios()


def test_limit_kernel_reports_violations_like_the_reference():
    """A case with violations for sure (the property test may draw few)."""
    rng = np.random.default_rng(3)
    n = 6
    one = np.ones(n)
    mons = [LimitMonitor(one, one, one, engine=e) for e in ("numpy", "numba")]
    out = ([], [])
    for s, (pos, ang) in enumerate(poses(rng, n, 40, 0.5, 0.12)):
        for m, ev in zip(mons, out, strict=True):
            ev.extend(m.measure(pos, ang, s * 0.05))
    assert out[0] == out[1] and len(out[0]) > 5
    assert {e[1]["kind"] for e in out[0]} == {"speed", "accel", "turn_rate"}


# --------------------------------------------------------------------------- clearance

@settings(max_examples=40, deadline=None)
@given(seeds, st.integers(2, 40), st.floats(0.05, 1.0), st.floats(0.01, 0.3))
def test_clearance_kernel_is_the_numpy_reference(seed, n, share, jump):
    rng = np.random.default_rng(seed)
    half = rng.uniform(0.2, 0.45, (n, 2))
    mons = [ClearanceMonitor(half, engine=e) for e in ("numpy", "numba")]
    for s, (pos, ang) in enumerate(poses(rng, n, 50, share, jump)):
        if s % 17 == 5:  # some AGVs pick up or put down shelves
            shelf = np.where(rng.random(n)[:, None] < 0.3, 0.5, 0.0) * np.ones((n, 2))
            for m in mons:
                m.set_shelves(shelf)
        for m in mons:
            m.measure(pos, ang, s * 0.05)
        ref, nb = mons
        assert nb.min_m == ref.min_m and nb.at_s == ref.at_s, s
        if ref._built_at is not None and nb._built_at is not None and (
                np.array_equal(ref._built_at, nb._built_at)):
            assert np.array_equal(_lexsorted(ref._pairs), nb._pairs)


def _lexsorted(p: np.ndarray) -> np.ndarray:
    return p[np.lexsort((p[:, 1], p[:, 0]))]


@settings(max_examples=60, deadline=None)
@given(seeds, st.integers(2, 300), st.floats(1.0, 60.0), st.floats(0.0, 1.4))
def test_near_pairs_are_the_kd_tree_pairs(seed, n, span, horizon):
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(seed)
    pos = rng.uniform(-span / 2, span / 2, (n, 2))
    radius = rng.uniform(0.2, 0.7, n)
    reach = 2 * float(radius.max()) + horizon
    got = near_pairs(pos, radius, horizon, reach)
    ref = cKDTree(pos).query_pairs(reach, output_type="ndarray").reshape(-1, 2)
    gap = np.linalg.norm(pos[ref[:, 0]] - pos[ref[:, 1]], axis=1) - radius[ref].sum(axis=1)
    assert np.array_equal(got, _lexsorted(ref[gap < horizon]))


# --------------------------------------------------------------------------- shares, causes

class _Graph:
    """Stands in for the action graph in the blocker look-ups: AGV ``i``'s next action
    enters cell ``i``, whose head at the time ``now`` is drawn from ``table``."""

    def __init__(self, table: np.ndarray) -> None:
        self.table, self.now = table, 0

    def next_action(self, i: int):
        return SimpleNamespace(enters=(i,)) if self.table[self.now, i] != -2 else None

    def head(self, c: int):
        h = int(self.table[self.now, c])
        return None if h < 0 else h

    def blockers(self, agvs):
        out = []
        for i in agvs:
            nxt = self.next_action(i)
            h = None if nxt is None else self.head(nxt.enters[0])
            out.append(-1 if h is None or h == i else h)
        return out


def _fleet(rng: np.random.Generator, n: int, dt: float):
    return SimpleNamespace(n=n, dt=dt, tick_s=0.5, sim_s=0.0,
                           mode=np.zeros(n, dtype=np.int8), waiting=np.zeros(n, dtype=bool),
                           pending=np.zeros(n, dtype=bool), failed=np.zeros(n, dtype=bool),
                           has_next=np.zeros(n, dtype=bool), hold_until=np.zeros(n),
                           last_finish=np.zeros(n))


@settings(max_examples=40, deadline=None)
@given(seeds, st.integers(1, 30), st.integers(1, 7), st.sampled_from([0.02, 0.05]))
def test_shares_and_cause_labels_kernel_is_the_numpy_reference(seed, n, refresh, dt):
    rng = np.random.default_rng(seed)
    steps = 80
    graph = _Graph(rng.integers(-2, n, (steps, n)))
    fleets = [_fleet(rng, n, dt) for _ in range(2)]
    recs = [CauseRecorder(f, graph, refresh=refresh) for f in fleets]
    sums = [[np.zeros(n) for _ in range(4)] for _ in range(2)]
    active = [0, 0]
    for s in range(steps):
        graph.now = s
        draw = {"mode": rng.integers(0, 3, n).astype(np.int8),
                "waiting": rng.random(n) < 0.4, "pending": rng.random(n) < 0.3,
                "failed": rng.random(n) < 0.05, "has_next": rng.random(n) < 0.5,
                "hold_until": (s + rng.integers(-2, 3, n)) * dt,
                "last_finish": (s + rng.integers(-3, 1, n)) * dt}
        injected = rng.random(n) < 0.2
        for k, (f, rec) in enumerate(zip(fleets, recs, strict=True)):
            for name, v in draw.items():
                setattr(f, name, v.copy())
            f.sim_s = (s + 1) * dt
            if k == 0:
                dep, inj, turn, held = sums[0]
                busy = (f.mode != 0) | f.waiting
                dep += f.waiting * dt
                inj += (injected & (busy | f.pending)) * dt
                turn += (f.mode == 1) * dt
                active[0] += int(np.count_nonzero(f.mode != 0))
                held += ((injected | f.failed) & (f.mode == 2)) * dt
                rec.step(injected)
            else:
                active[1] += rec.step_with_shares(injected, *sums[1])
        if s % 9 == 4:  # an action finishes: its interval's counts are logged
            i = int(rng.integers(n))
            for rec in recs:
                rec.action_begun(i, SimpleNamespace(seq=s, src=0, dst=1, tick=s, ticks=2))
                rec.action_done(i)
    assert active[0] == active[1]
    for a, b in zip(*sums, strict=True):
        assert np.array_equal(a, b)
    ref, nb = (r.log() for r in recs)
    assert ref.blockers == nb.blockers
    for field in ("agv", "seq", "start_step", "finish_step", "counts"):
        assert np.array_equal(getattr(ref, field), getattr(nb, field)), field
    assert np.array_equal(recs[0]._cur, recs[1]._cur)


# --------------------------------------------------------------------------- an episode

def test_a_physics_episode_is_the_same_with_either_engine(monkeypatch):
    from warerover_phys import load_scenario
    from warerover_phys.sim import run_episode

    runs = {}
    for engine, least in (("numpy", 10**9), ("numba", 0)):
        monkeypatch.setattr(accounting, "ENGINE_MIN_AGVS", least)
        sc = load_scenario("layouts/paper_homogeneous.yaml",
                           [("executor.name", "physics"), ("max_ticks", 40),
                            ("executor.trajectory_hz", 10.0)])
        runs[engine] = run_episode(sc, seed=1)
    a, b = runs["numpy"], runs["numba"]
    timing = ("wall", "real_time", "ct_", "_ms", "_per_s")
    keys = [k for k in a.metrics if not any(t in k for t in timing)]
    assert {k: a.metrics[k] for k in keys} == {k: b.metrics[k] for k in keys}
    assert a.metrics["actions_executed"] > 0 and a.metrics["min_clearance_m"] is not None
    assert a.trajectory.keys() == b.trajectory.keys()
    for k in a.trajectory:
        assert np.array_equal(np.asarray(a.trajectory[k]), np.asarray(b.trajectory[k])), k
    assert a.events == b.events
