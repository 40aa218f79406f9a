"""The compiled start of a physics step (``step_kernels.step_prelude``) gives bit for bit
what the numpy expressions it replaced give."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from warerover_phys.executors.control import OFF_REFERENCE_M
from warerover_phys.executors.delays import held
from warerover_phys.executors.fleet_state import DRIVE, FleetState
from warerover_phys.executors.step_kernels import step_prelude


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 40), seed=st.integers(0, 2 ** 32 - 1))
def test_step_prelude_equals_numpy(n, seed):
    rng = np.random.default_rng(seed)
    fs = FleetState(cols=10, cell_m=1.0, tick_s=1.0, dt=0.02, k=np.ones(n, dtype=int),
                    vmax=np.ones(n), amax=np.ones(n), wmax=np.ones(n),
                    omni=np.zeros(n, dtype=bool), origin=rng.uniform(0, 10, (n, 2)))
    fs.mode = rng.integers(0, 3, n).astype(np.int8)
    fs.direction = rng.choice([-1.0, 0.0, 1.0], (n, 2))
    fs.s_ref = rng.uniform(0, 3, n)
    fs.hold_xy = rng.uniform(0, 10, (n, 2))
    t = 5.0
    fs.delayed_until = np.where(rng.random(n) < 0.3, rng.uniform(4, 6, n), 0.0)
    fs.failed = rng.random(n) < 0.1
    contact_until = np.where(rng.random(n) < 0.2, rng.uniform(4, 6, n), 0.0)
    # Bodies near their reference points, some more than OFF_REFERENCE_M behind.
    pos = fs.ref_xy() - fs.direction * rng.uniform(-0.1, 0.1, n)[:, None]
    injected, delayed = np.empty(n, dtype=bool), np.empty(n, dtype=bool)
    off, ref0 = np.empty(n, dtype=bool), np.empty((n, 2))
    step_prelude(pos, fs.mode, fs.s_ref, fs.origin, fs.direction, fs.hold_xy,
                 fs.delayed_until, fs.failed, contact_until, t, 0.02, OFF_REFERENCE_M,
                 injected, delayed, off, ref0)
    want_inj = held(fs.delayed_until, t, 0.02)
    want_off = (fs.mode == DRIVE) & (fs.s_ref - fs.along(pos) > OFF_REFERENCE_M)
    want_delayed = want_inj | fs.failed | (contact_until > t) | want_off
    assert (injected == want_inj).all() and (off == want_off).all()
    assert (delayed == want_delayed).all()
    assert ref0.tobytes() == fs.ref_xy().tobytes()


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 40), seed=st.integers(0, 2 ** 32 - 1))
def test_settled_equals_numpy(n, seed):
    from warerover_phys.executors.control import wrap
    from warerover_phys.executors.physics import PARK_EPS_M, PARK_EPS_RAD, PARK_SPEED
    from warerover_phys.executors.step_kernels import settled

    rng = np.random.default_rng(seed)

    def small(scale, *shape):  # values around the thresholds, some exactly zero
        x = rng.uniform(-2 * scale, 2 * scale, shape)
        return np.where(rng.random(shape) < 0.3, 0.0, x)

    mode = rng.integers(0, 3, n).astype(np.int8)
    parked = rng.random(n) < 0.3
    hold = rng.uniform(0, 10, (n, 2))
    pos = hold + small(PARK_EPS_M, n, 2)
    vel, w = small(PARK_SPEED, n, 2), small(PARK_SPEED, n)
    heading = rng.uniform(-7, 7, n)
    ang = heading + small(PARK_EPS_RAD, n) + rng.choice([0, 2 * np.pi, -2 * np.pi], n)
    speed = np.where(rng.random(n) < 0.8, 0.0, 0.1)
    out = np.zeros(n, dtype=np.int64)
    k = settled(mode, parked, hold, pos, vel, w, heading, ang, speed, PARK_EPS_M,
                PARK_SPEED, PARK_EPS_RAD, out)
    err = hold - pos
    want = ((mode == 0) & ~parked & (np.einsum("ij,ij->i", err, err) < PARK_EPS_M ** 2)
            & (np.einsum("ij,ij->i", vel, vel) < PARK_SPEED ** 2)
            & (np.abs(w) < PARK_SPEED) & (np.abs(wrap(heading - ang)) < PARK_EPS_RAD)
            & (speed == 0.0))
    assert out[:k].tolist() == np.flatnonzero(want).tolist()
