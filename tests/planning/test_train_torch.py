"""PyTorch training of the ``learned`` policy (``tools/train_torch.py``, ``train_learned.py
--backend torch``). Needs the ``[train]`` extra: every torch test skips where torch is not
importable (CI); the one test that checks the clear error without torch runs only there."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from warerover_phys.planning.learned.planner import learned_oneshot
from warerover_phys.planning.learned.policy import (
    DEFAULT_WEIGHTS,
    MLPPolicy,
    num_features,
)
from warerover_phys.planning.oneshot.core import grid_graph
from warerover_phys.problems.movingai import read_map, read_scen
from warerover_phys.validate import validate_states

ROOT = Path(__file__).resolve().parents[2]
TOOLS = ROOT / "tools"
DATA = ROOT / "tests" / "data"
HAVE_TORCH = importlib.util.find_spec("torch") is not None


@pytest.fixture(scope="module")
def tt():
    """The ``train_torch`` and ``train_learned`` tool modules (skips without torch)."""
    pytest.importorskip("torch")
    sys.path.insert(0, str(TOOLS))
    try:
        import train_learned
        import train_torch
    finally:
        sys.path.remove(str(TOOLS))
    return train_torch, train_learned


@pytest.fixture(scope="module")
def tiny_data(tt):
    """Samples of two generated instances solved by the expert (seed 5), feature set 2."""
    _, tl = tt
    x8, sc, y, groups, stats = tl.build_dataset(np.random.SeedSequence(5), 2, 5, 0.05, 2)
    assert stats["unsolved"] == 0 and len(y) > 500
    return x8, sc, y, groups


def _random_observations(tl, rng: np.random.Generator, n: int) -> np.ndarray:
    """Feature-set-2 features of ``n`` agents on random distinct cells of a generated map,
    random goals and random PIBT priorities (what the network reads at run time)."""
    from warerover_phys.planning.graph import UNREACHABLE
    from warerover_phys.planning.learned.policy import ObsGrid, policy_features

    obstacles, _, _ = tl.make_instance(rng)
    graph = grid_graph(obstacles)
    free = np.flatnonzero(~obstacles.ravel())
    n = min(n, len(free))
    here, goals = rng.choice(free, n, replace=False), rng.choice(free, n, replace=False)
    dists = np.stack([np.append(graph.dist_to(divmod(int(g), graph.cols)), UNREACHABLE)
                      for g in goals])
    prio = rng.integers(0, 40, n) + rng.random(n)
    return policy_features(ObsGrid(obstacles, 5), here, goals, dists, prio, version=2)


def test_torch_forward_equals_numpy_policy(tt):
    """The torch network's logits equal MLPPolicy's numpy ones within 1e-5 (relative
    beyond |logit| 1), on random
    observations (agents on random cells of generated maps), for the shipped weights and
    random weights."""
    train_torch, tl = tt
    import torch

    rng = np.random.default_rng(3)
    x = np.concatenate([_random_observations(tl, rng, 100) for _ in range(4)])
    assert len(x) > 100 and x.shape[1] == num_features(2, 5)
    random_p = tl.init_params(rng, [num_features(2, 5), 64, 32, 5])
    for k in random_p:  # non-zero biases too
        random_p[k] += rng.normal(0, 0.1, random_p[k].shape).astype(np.float32)
    for policy in (MLPPolicy.load(), MLPPolicy(random_p, 5, version=2)):
        with torch.no_grad():
            got = train_torch.TorchMLP(policy.params)(torch.from_numpy(x)).numpy()
        want = policy.logits(x)
        assert got.shape == want.shape == (len(x), 5)
        # float32 with another summation order: 1e-5 absolute up to |logit| 1, relative
        # beyond (logits reach ~30, where one float32 step is 2e-6)
        err = np.abs(got - want) / np.maximum(1.0, np.abs(want))
        assert err.max() <= 1e-5, err.max()
        top2 = np.sort(want, axis=1)[:, -2:]
        clear = top2[:, 1] - top2[:, 0] > 1e-3
        assert (got.argmax(1) == want.argmax(1))[clear].all()  # the same preferred action
        assert np.abs(want).max() > 1  # not a trivially small output


def test_torch_gradients_equal_the_numpy_backward(tt, tiny_data):
    """Autograd's loss and gradients equal the numpy path's hand-written backward pass on a
    real batch, so both back ends minimise the same thing."""
    train_torch, tl = tt
    x8, sc, y, _ = tiny_data
    rng = np.random.default_rng(0)
    p = tl.init_params(rng, [x8[0].size + sc.shape[1], 32, 16, 5])
    xb = tl.batch_features(x8[:256], sc[:256], 5)
    yb = y[:256].astype(np.int64)
    loss_t, grads_t = train_torch.loss_and_grads(p, xb, yb)
    loss_n, grads_n = tl.forward_backward({k: v.copy() for k, v in p.items()}, xb, yb)
    assert loss_t == pytest.approx(loss_n, rel=1e-5)
    for k in grads_n:
        scale = float(np.abs(grads_n[k]).max()) + 1e-12
        np.testing.assert_allclose(grads_t[k], grads_n[k], rtol=0, atol=1e-5 * scale)


def _train(tt, data, seed: int):
    train_torch, tl = tt
    x8, sc, y, groups = data
    seq = np.random.SeedSequence(seed)
    train_torch.setup(int(seq.generate_state(1)[0]))
    p, log, split = train_torch.train_torch(
        x8, sc, y, groups, rng=np.random.default_rng(seq), radius=5, version=2, hidden=16,
        epochs=2, batch=128, lr=2e-3)
    assert split["train"] > 0 and split["val"] > 0 and len(log) == 2
    return p


def test_tiny_torch_training_is_reproducible_from_its_seed(tt, tiny_data):
    """Two tiny runs with seed 0 give identical weights; seed 1 other weights; the
    weights moved away from their initial values."""
    a, b, c = _train(tt, tiny_data, 0), _train(tt, tiny_data, 0), _train(tt, tiny_data, 1)
    assert sorted(a) == sorted(b) == ["W1", "W2", "W3", "b1", "b2", "b3"]
    assert all(a[k].dtype == np.float32 and np.array_equal(a[k], b[k]) for k in a)
    assert not np.array_equal(a["W1"], c["W1"])
    assert np.abs(a["b1"]).max() > 0  # trained: the biases start at zero


def test_exported_weights_load_and_plan_without_conflicts(tt, tiny_data, tmp_path):
    """The torch-trained weights, saved as .npz, load through MLPPolicy.load and the
    learned planner solves a small one-shot MovingAI instance; the validator finds no
    conflict."""
    p = _train(tt, tiny_data, 0)
    out = tmp_path / "torch.npz"
    MLPPolicy(p, 5, version=2).save(out)
    policy = MLPPolicy.load(out)
    assert policy.version == 2 and policy.fov_radius == 5
    assert all(np.array_equal(policy.params[k], p[k]) for k in p)
    m = read_map(DATA / "random-32-32-10.map")
    scen = read_scen(DATA / "random-32-32-10-random-1.scen")[:12]
    paths, stats = learned_oneshot(grid_graph(m.obstacles), [a.start for a in scen],
                                   [a.goal for a in scen], time.monotonic() + 60, seed=0,
                                   policy=policy)
    assert paths is not None, stats
    assert [q[-1] for q in paths] == [a.goal for a in scen]
    states = {i: [(r * m.cols + c,) * 2 for r, c in q] for i, q in enumerate(paths)}
    assert validate_states(states, m.obstacles) == []


def _script(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, str(TOOLS / "train_learned.py"), *args],
                          capture_output=True, text=True, env=env, timeout=300)


def test_script_backend_torch_writes_loadable_weights(tt, tmp_path):
    """``train_learned.py --backend torch`` (tiny: 2 instances, one DAgger round of one
    instance) writes .npz weights MLPPolicy.load reads and a log naming the back end; the
    shipped weights are not touched."""
    before = DEFAULT_WEIGHTS.stat().st_mtime_ns
    out = tmp_path / "w.npz"
    proc = _script("--backend", "torch", "--seed", "0", "--instances", "2", "--epochs", "1",
                   "--hidden", "16", "--batch", "256", "--dagger-rounds", "1",
                   "--dagger-instances", "1", "--dagger-epochs", "1", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "training with torch" in proc.stdout
    assert MLPPolicy.load(out).params["W1"].shape == (num_features(2, 5), 16)
    info = json.loads(out.with_suffix(".json").read_text())
    assert info["backend"] == "torch" and info["torch"]
    assert DEFAULT_WEIGHTS.stat().st_mtime_ns == before


@pytest.mark.skipif(HAVE_TORCH, reason="checks the error where torch is not installed")
def test_backend_torch_without_torch_exits_2_with_one_line(tmp_path):
    proc = _script("--backend", "torch", "--out", str(tmp_path / "w.npz"))
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0
    assert "PyTorch is not importable" in proc.stderr and "[train]" in proc.stderr
    assert not (tmp_path / "w.npz").exists()
