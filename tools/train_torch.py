"""PyTorch back end of ``tools/train_learned.py`` (``--backend torch``; needs the ``[train]``
extra: ``pip install -e '.[train]'``).

The same network as the numpy path and as :class:`warerover_phys.planning.learned.policy.MLPPolicy`
(``F -> H -> H/2 -> 5``, ReLU; parameters ``W1 (F, H1)``, ``b1``, ... in the weights file's
layout, so ``x @ W + b`` as at run time), the same data (the caller's samples, the same
held-out instances, shuffles and symmetries drawn from the same numpy generator), the same
loss (cross-entropy, batch mean), the same optimiser (Adam, betas 0.9 / 0.999, eps 1e-8) and
the same cosine learning-rate schedule. The initial weights come from the numpy generator
too (``init_params``), so a torch run starts where the numpy run with that seed starts;
the float sums differ (torch's kernels), so the trained weights are close, not equal.

Reproducible from the seed: :func:`setup` sets ``torch.manual_seed``, one intra-op and one
inter-op thread and ``torch.use_deterministic_algorithms(True)``; nothing in training draws
from torch's generator anyway. CPU only.

Output: a plain ``dict[str, np.ndarray]`` (float32) that ``MLPPolicy(params, radius,
version=...)`` takes and ``MLPPolicy.save`` writes as the ``.npz`` that ``MLPPolicy.load``
reads: no torch at run time.
"""

from __future__ import annotations

import json
import os
import time

# One BLAS thread for numpy too (as train_learned.py), set before numpy loads.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402
from torch import nn  # noqa: E402
from torch.nn import functional as F  # noqa: E402
from train_learned import accuracy, augment, batch_features, init_params  # noqa: E402

from warerover_phys.planning.learned.policy import NUM_ACTIONS  # noqa: E402

__all__ = ["TorchMLP", "setup", "train_torch", "loss_and_grads"]

_SET_UP = False


def setup(seed: int) -> None:
    """Seed torch and make it deterministic and single-threaded (call before training)."""
    global _SET_UP
    torch.manual_seed(int(seed))
    torch.use_deterministic_algorithms(True)
    torch.set_num_threads(1)
    if not _SET_UP:
        try:  # may be set once per process only, before any inter-op work
            torch.set_num_interop_threads(1)
        except RuntimeError:
            pass
        _SET_UP = True


class TorchMLP(nn.Module):
    """``relu(relu(x @ W1 + b1) @ W2 + b2) @ W3 + b3``: :class:`MLPPolicy`'s network."""

    NAMES = ("W1", "b1", "W2", "b2", "W3", "b3")

    def __init__(self, params: dict[str, np.ndarray]) -> None:
        super().__init__()
        for k in self.NAMES:
            setattr(self, k, nn.Parameter(torch.tensor(np.asarray(params[k], np.float32))))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = torch.relu(x @ self.W1 + self.b1)
        h = torch.relu(h @ self.W2 + self.b2)
        return h @ self.W3 + self.b3

    def export(self) -> dict[str, np.ndarray]:
        """The parameters as float32 numpy arrays, in the weights file's layout."""
        return {k: getattr(self, k).detach().cpu().numpy().astype(np.float32, copy=True)
                for k in self.NAMES}


def loss_and_grads(params: dict[str, np.ndarray], x: np.ndarray, y: np.ndarray):
    """Batch-mean cross-entropy and its gradients by autograd (numpy in, numpy out): the
    counterpart of ``train_learned.forward_backward``, for tests."""
    model = TorchMLP(params)
    loss = F.cross_entropy(model(torch.from_numpy(np.ascontiguousarray(x, np.float32))),
                           torch.from_numpy(np.asarray(y, np.int64)))
    loss.backward()
    return loss.item(), {k: getattr(model, k).grad.numpy().copy() for k in TorchMLP.NAMES}


def train_torch(x8, sc, y, groups, *, rng, radius, version, hidden, epochs, batch, lr,
                init=None):
    """``train_learned.train`` with torch doing the forward, backward and Adam steps; same
    arguments and return value (numpy parameters, per-epoch log, split sizes)."""
    held = np.unique(groups)
    held = set(rng.choice(held, size=max(1, len(held) // 20), replace=False).tolist())
    val = np.isin(groups, list(held))
    xt, yt, xv, yv = x8[~val], y[~val].astype(np.int64), x8[val], y[val].astype(np.int64)
    st, sv = sc[~val], sc[val]
    features = x8[0].size + sc.shape[1]
    p = init if init is not None else init_params(rng, [features, hidden, hidden // 2,
                                                         NUM_ACTIONS])
    model = TorchMLP(p)
    opt = torch.optim.Adam(model.parameters(), lr=lr, betas=(0.9, 0.999), eps=1e-8,
                           foreach=False)
    steps_per_epoch = len(yt) // batch
    total = steps_per_epoch * epochs
    step = 0
    log = []
    for epoch in range(epochs):
        t0 = time.perf_counter()
        order = rng.permutation(len(yt))
        losses = []
        model.train()
        for s in range(steps_per_epoch):
            idx = np.sort(order[s * batch:(s + 1) * batch])
            xb, yb = augment(xt[idx], yt[idx], int(rng.integers(8)))
            xb = torch.from_numpy(batch_features(xb, st[idx], radius))
            loss = F.cross_entropy(model(xb), torch.from_numpy(np.ascontiguousarray(yb)))
            opt.zero_grad(set_to_none=True)
            loss.backward()
            step += 1
            for group in opt.param_groups:
                group["lr"] = lr * 0.5 * (1 + np.cos(np.pi * step / total))
            opt.step()
            losses.append(loss.item())
        p = model.export()
        acc = accuracy(p, xv, sv, yv, radius, version)  # numpy inference, as at run time
        log.append({"epoch": epoch + 1, "loss": float(np.mean(losses)) if losses else None,
                    "val_acc": acc, "s": time.perf_counter() - t0})
        print(f"  epoch {epoch + 1}/{epochs} (torch): loss {np.mean(losses):.4f}  "
              f"held-out accuracy {acc:.3f}  ({time.perf_counter() - t0:.0f} s)", flush=True)
    return model.export(), log, {"train": int(len(yt)), "val": int(len(yv))}


def bench(samples: int, hidden: int, batch: int, seed: int = 0) -> dict:
    """CPU and wall seconds of one training epoch of each back end on ``samples`` synthetic
    feature-set-2 samples (random int8 spatial channels, scalars and labels: the timing of
    the full-size network, not a trained one)."""
    import train_learned as tl

    rng = np.random.default_rng(seed)
    x8 = rng.integers(-5, 6, (samples, 6, 11, 11), dtype=np.int8)
    sc = rng.random((samples, 4), dtype=np.float32)
    y = rng.integers(0, NUM_ACTIONS, samples).astype(np.int8)
    groups = rng.integers(0, 100, samples).astype(np.int32)
    out = {}
    for name, fn in (("numpy", tl.train), ("torch", train_torch)):
        setup(seed)
        c0, w0 = time.process_time(), time.perf_counter()
        _, _, split = fn(x8, sc, y, groups, rng=np.random.default_rng(seed), radius=5,
                         version=2, hidden=hidden, epochs=1, batch=batch, lr=2e-3)
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        steps = split["train"] // batch
        out[name] = {"cpu_s": round(cpu, 2), "wall_s": round(wall, 2), "steps": steps,
                     "cpu_ms_per_step": round(1e3 * cpu / steps, 2)}
    return out


def compare(weights: list[str], agents: list[int], seed: int = 0) -> list[dict]:
    """One-shot SoC / lower bound of the ``learned`` planner with each weights file on the
    test data's MovingAI instances (``random-32-32-10``, ``warehouse-10-20-10-2-1``,
    scenario 1, first ``agents``), every solution checked by the validator."""
    from pathlib import Path

    from learned_table import _soc

    from warerover_phys.planning.learned.planner import learned_oneshot
    from warerover_phys.planning.learned.policy import MLPPolicy
    from warerover_phys.planning.oneshot.core import grid_graph
    from warerover_phys.problems.movingai import read_map, read_scen
    from warerover_phys.validate import validate_states

    data = Path(__file__).resolve().parents[1] / "tests" / "data"
    rows = []
    for name in ("random-32-32-10", "warehouse-10-20-10-2-1"):
        m = read_map(data / f"{name}.map")
        scen = read_scen(data / f"{name}-random-1.scen")
        graph = grid_graph(m.obstacles)
        for n in agents:
            starts, goals = [a.start for a in scen[:n]], [a.goal for a in scen[:n]]
            lb = sum(graph.distance(a, b) for a, b in zip(starts, goals, strict=True))
            for w in weights:
                paths, stats = learned_oneshot(graph, starts, goals, time.monotonic() + 300,
                                               seed=seed, policy=MLPPolicy.load(w))
                row = {"map": name, "agents": n, "weights": w,
                       "fallback_steps": stats["fallback_steps"]}
                if paths is None:
                    row["status"] = "fail"
                else:
                    states = {i: [(r * m.cols + c,) * 2 for r, c in q]
                              for i, q in enumerate(paths)}
                    ok = not validate_states(states, m.obstacles, max_conflicts=1)
                    soc, makespan = _soc(paths, goals)
                    row.update(status="ok" if ok else "invalid", soc_lb=round(soc / lb, 3),
                               makespan=makespan)
                rows.append(row)
                print(json.dumps(row), flush=True)
    return rows


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description="time one epoch of each training back end "
                                 "(or compare weights: --compare)")
    ap.add_argument("--samples", type=int, default=51_200)
    ap.add_argument("--hidden", type=int, default=256)
    ap.add_argument("--batch", type=int, default=512)
    ap.add_argument("--compare", nargs="+", metavar="NPZ",
                    help="instead: one-shot SoC / LB of the learned planner with these weights")
    ap.add_argument("--agents", type=int, nargs="+", default=[50, 100])
    a = ap.parse_args()
    if a.compare:
        compare(a.compare, a.agents)
    else:
        print(json.dumps({"load": os.getloadavg(), **bench(a.samples, a.hidden, a.batch)}))
