"""PyTorch back end of ``tools/train_learned.py`` (``--backend torch``; needs the ``[train]``
extra: ``pip install -e '.[train]'``).

The same network as the numpy path and as :class:`warerover_phys.planning.policy.MLPPolicy`
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

import time

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F
from train_learned import accuracy, augment, batch_features, init_params

from warerover_phys.planning.policy import NUM_ACTIONS

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
