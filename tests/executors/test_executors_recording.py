"""The physics executor's pose recording: samples streamed to disk in chunks come back
unchanged, recording goes on after a read, and the temporary folder goes with its owner."""

from __future__ import annotations

import gc

import numpy as np
import pytest

from warerover_phys import scenario_from_dict
from warerover_phys.executors.physics import PhysicsExecutor
from warerover_phys.executors.recording import TrajectoryStore
from warerover_phys.sim import executor_setup, step_executor
from warerover_phys.world import World


def samples(n: int, count: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    for j in range(count):
        yield (0.05 * j, rng.normal(size=(n, 2)), rng.normal(size=n),
               rng.integers(0, 8, n).astype(np.int8), rng.random(n) < 0.5,
               (rng.random((n, 2)) * 2).astype(np.float32),
               (rng.integers(0, 8, n).astype(np.int8), rng.integers(-1, n, n).astype(np.int32),
                rng.integers(-1, 500, n).astype(np.int32)))


def expected(rows) -> dict[str, np.ndarray]:
    return {"t": np.array([r[0] for r in rows]),
            "x": np.stack([r[1][:, 0] for r in rows]), "y": np.stack([r[1][:, 1] for r in rows]),
            "heading": np.stack([r[2] for r in rows]), "state": np.stack([r[3] for r in rows]),
            "loaded": np.stack([r[4] for r in rows]), "shelf_m": np.stack([r[5] for r in rows]),
            "exec_state": np.stack([r[6][0] for r in rows]),
            "blocker": np.stack([r[6][1] for r in rows]),
            "plan_tick": np.stack([r[6][2] for r in rows])}


def assert_same(got: dict, want: dict) -> None:
    assert list(got) == list(want)
    for k, w in want.items():
        assert got[k].dtype == w.dtype and got[k].shape == w.shape, k
        assert got[k].tobytes() == w.tobytes(), k


@pytest.mark.parametrize("count", [0, 1, 6, 7, 19])
def test_samples_come_back_bit_identical_across_chunks(count):
    rows = list(samples(5, count))
    store = TrajectoryStore(5, chunk=6)
    for r in rows:
        store.append(*r)
    assert len(store) == count
    got = store.arrays()
    if count:
        assert_same(got, expected(rows))
    else:
        assert got["x"].shape == (0, 5) and got["t"].shape == (0,)
    # Short runs stay in memory; longer ones are memory maps of the files.
    assert (store.folder is not None) == (count >= 6)
    assert all(isinstance(v, np.memmap) == (count >= 6) for v in got.values())


def test_samples_without_execution_fields_read_as_standing_unblocked_unstarted():
    """A caller that gives no execution fields (an executor that knows none) gets standing,
    blocker -1 and plan tick -1 in every chunk, beside rows that gave them."""
    rows = list(samples(2, 5, seed=3))
    store = TrajectoryStore(2, chunk=2)
    for j, r in enumerate(rows):
        store.append(*(r[:6] if j % 2 else r))
    got = store.arrays()
    for j, r in enumerate(rows):
        want = ((0, 0), (-1, -1), (-1, -1)) if j % 2 else tuple(map(tuple, r[6]))
        assert tuple(tuple(got[k][j].tolist()) for k in
                     ("exec_state", "blocker", "plan_tick")) == want


def test_recording_goes_on_after_a_read():
    rows = list(samples(3, 20, seed=1))
    store = TrajectoryStore(3, chunk=4)
    for r in rows[:9]:
        store.append(*r)
    first = store.arrays()
    for r in rows[9:]:
        store.append(*r)
    assert_same(first, expected(rows[:9]))
    assert_same(store.arrays(), expected(rows))


def test_no_agvs():
    store = TrajectoryStore(0, chunk=2)
    for j in range(5):
        store.append(float(j), np.zeros((0, 2)), np.zeros(0), np.zeros(0, np.int8),
                     np.zeros(0, bool), np.zeros((0, 2)))
    got = store.arrays()
    assert got["t"].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert got["x"].shape == (5, 0) and got["loaded"].dtype == bool
    assert got["shelf_m"].shape == (5, 0, 2)


def test_folder_removed_when_the_store_is_collected():
    store = TrajectoryStore(2, chunk=2)
    for r in samples(2, 5):
        store.append(*r)
    folder = store.folder
    assert folder is not None and folder.is_dir() and folder.name.startswith("warerover-traj-")
    arrays = store.arrays()
    del store
    gc.collect()
    assert not folder.exists()
    # Mapped arrays stay readable after the files are gone (POSIX).
    assert arrays["t"].shape == (5,) and float(arrays["t"][-1]) == pytest.approx(0.2)


def test_physics_executor_streams_and_cleans_up():
    w = World.build(scenario_from_dict({
        "layout": {"grid": ["P...........R", "P.SS.........", "P............"]},
        "fleet": {"types": {"t": {"max_speed_mps": 1.0}}, "agvs": [{"type": "t", "count": 2}]},
        "executor": {"name": "physics", "trajectory_hz": 20.0}}))
    ex = PhysicsExecutor(w.scenario.executor)
    ex.bind(executor_setup(w))
    for _ in range(15):  # 15 ticks at 20 Hz: more than one chunk of samples
        step_executor(w, ex)
        w.tick += 1
    traj = ex.trajectory()
    t = 15 * ex.steps_per_tick // ex.acc._traj_every
    assert t > 256 and isinstance(traj["x"], np.memmap)
    assert traj["t"].shape == (t,) and traj["x"].shape == (t, 2)
    assert traj["state"].dtype == np.int8 and traj["loaded"].dtype == bool
    assert np.all(np.diff(traj["t"]) > 0)
    folder = ex.acc._traj.folder
    assert folder is not None and folder.is_dir()
    del ex
    gc.collect()
    assert not folder.exists()
