"""Train the ``learned`` planner's policy by imitation of the project's PIBT / LaCAM solutions.

Reproducible from ``--seed`` (one root ``SeedSequence``; one child per generated instance and
one for the training loop). Two back ends for the training steps (``--backend``):

- ``torch`` (the default when PyTorch is importable; ``pip install -e '.[train]'``):
  :mod:`train_torch`, autograd and ``torch.optim.Adam``, seeded, deterministic algorithms,
  one thread;
- ``numpy`` (the default without PyTorch): the gradients written out below. With
  ``--backend numpy`` the other defaults reproduce the shipped ``learned_v2.npz`` (feature
  set 2, two DAgger rounds): 3,006 s on the shared 2-core box at load 7-10
  (``learned_v2.json``).

Both read the same samples, draw the same held-out instances, shuffles, symmetries and
initial weights from the same numpy generator, and write the same ``.npz``; only the float
sums differ, so their weights are close, not equal. Inference never needs torch.

The first weights, ``learned_v1.npz``, were trained by the earlier version of this script,
the equivalent of ``--features 1 --dagger-rounds 1`` (not rerun with this version).

1. Instances: procedurally generated grids, never the MovingAI benchmark maps the table
   reports on: random maps (16-40 cells a side, 5-30 % obstacles, largest connected part
   kept) and warehouse-like maps (blocks of shelves separated by 1-2 cell aisles), with
   8-128 agents on distinct random starts and goals.
2. Expert: one-shot PIBT (with swap) of :mod:`warerover_phys.planning.pibt.reference`; where PIBT
   does not finish within its step limit, LaCAM (:mod:`warerover_phys.planning.lacam.reference`).
   Instances neither solves are skipped (counted).
3. Samples: at every step of the expert's solution, every agent's policy features
   (:func:`warerover_phys.planning.learned.policy.policy_features`, with PIBT's priorities replayed
   along the solution) labelled with the action the expert took;
   95 % of the "already on goal, waits" samples are dropped.
4. Training: cross-entropy, Adam, mini-batches, each batch under a random symmetry of the
   square (flips, transpose; actions permuted to match); 5 % of instances held out.
4b. DAgger (``--dagger-rounds``, default 2): the trained policy, behind its shield, drives
   new instances; every configuration it visits is labelled by one PIBT step from there;
   the samples join the data set and training goes on (half the learning rate).
5. Output: the weights as ``.npz`` (see :mod:`warerover_phys.planning.learned.policy`) and a JSON
   log next to it.

    # the shipped weights, written over the shipped file:
    PYTHONPATH=. .venv/bin/python tools/train_learned.py --backend numpy \
        --out warerover_phys/planning/weights/learned_v2.npz
    # default --out: tools/out/learned.npz (never the shipped file)
    PYTHONPATH=. .venv/bin/python tools/train_learned.py --instances 40 --epochs 2 --out /tmp/w.npz
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

# One BLAS thread: the same float sums on every machine (reproducible weights) and no thread
# thrashing on a shared 2-core box. Set before numpy loads; override from the shell.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from warerover_phys.planning.graph import UNREACHABLE  # noqa: E402  (also the off-grid column)
from warerover_phys.planning.lacam.reference import lacam  # noqa: E402
from warerover_phys.planning.learned.policy import (  # noqa: E402
    NUM_ACTIONS,
    WEIGHTS_VERSION,
    MLPPolicy,
    ObsGrid,
    actions_from_moves,
    policy_features,
)
from warerover_phys.planning.oneshot.core import grid_graph  # noqa: E402
from warerover_phys.planning.pibt.reference import (  # noqa: E402
    initial_priorities,
    pibt_oneshot,
    update_priorities,
)

# Label permutations of the square's symmetries (action order: wait, up, down, left, right).
FLIP_ROWS = np.array([0, 2, 1, 3, 4])
FLIP_COLS = np.array([0, 1, 2, 4, 3])
TRANSPOSE = np.array([0, 3, 4, 1, 2])


# ----------------------------------------------------------------------------- instances

def _largest_component(free: np.ndarray) -> np.ndarray:
    from scipy.ndimage import label
    lab, n = label(free)
    if n == 0:
        return free
    sizes = np.bincount(lab.ravel())
    sizes[0] = 0
    return lab == sizes.argmax()


def random_map(rng: np.random.Generator) -> np.ndarray:
    rows, cols = rng.integers(16, 41, size=2)
    density = rng.uniform(0.05, 0.30)
    obstacles = rng.random((rows, cols)) < density
    return ~_largest_component(~obstacles)


def warehouse_map(rng: np.random.Generator) -> np.ndarray:
    """Blocks of shelves (obstacles) with aisles, a free border band."""
    block_w, block_h = int(rng.integers(3, 11)), int(rng.integers(1, 3))
    aisle = int(rng.integers(1, 3))
    nx, ny = int(rng.integers(2, 6)), int(rng.integers(2, 7))
    border = int(rng.integers(2, 5))
    rows = 2 * border + ny * block_h + (ny - 1) * aisle
    cols = 2 * border + nx * block_w + (nx - 1) * aisle
    obstacles = np.zeros((rows, cols), dtype=bool)
    for by in range(ny):
        for bx in range(nx):
            r0 = border + by * (block_h + aisle)
            c0 = border + bx * (block_w + aisle)
            obstacles[r0:r0 + block_h, c0:c0 + block_w] = True
    return ~_largest_component(~obstacles)


def make_instance(rng: np.random.Generator):
    obstacles = random_map(rng) if rng.random() < 0.6 else warehouse_map(rng)
    free = np.flatnonzero(~obstacles.ravel())
    n = int(rng.integers(8, max(9, min(129, len(free) // 4))))
    cells = rng.permutation(free)
    cols = obstacles.shape[1]
    starts = [divmod(int(v), cols) for v in cells[:n]]
    goals = [divmod(int(v), cols) for v in rng.permutation(free)[:n]]
    return obstacles, starts, goals


def expert(obstacles, starts, goals, seed: int):
    graph = grid_graph(obstacles)
    paths, _ = pibt_oneshot(graph, starts, goals, time.monotonic() + 60, seed,
                            max_steps=4 * (graph.rows + graph.cols) + 50)
    if paths is not None:
        return graph, paths, "pibt"
    paths, _ = lacam(graph, starts, goals, time.monotonic() + 30, seed)
    return graph, paths, "lacam"


def encode(feats: np.ndarray, keep: np.ndarray, radius: int, version: int):
    """Compact storage of features of the agents in ``keep``: the spatial channels as int8
    ``round(x * r)`` (exact: every value is a multiple of 1 / r), shape ``(K, C, W, W)``,
    and the scalars as float32 ``(K, S)``."""
    w = 2 * radius + 1
    channels = 4 if version == 1 else 6
    f = feats[keep]
    spatial = f[:, :channels * w * w].reshape(len(f), channels, w, w)
    return np.rint(spatial * radius).astype(np.int8), f[:, channels * w * w:].copy()


def samples(graph, paths, goals, radius: int, rng: np.random.Generator, keep_idle: float,
            version: int):
    """(spatial int8, scalars, labels) of one solved instance; PIBT's priorities are
    replayed along the expert's solution (what a PIBT step depends on)."""
    grid = ObsGrid(~graph.enterable, radius)
    cols = graph.cols
    g = np.array([graph.node(c) for c in goals])
    dists = np.stack([np.append(graph.dist_to(c), UNREACHABLE) for c in goals])
    configs = np.array([[r * cols + c for r, c in p] for p in paths]).T  # (T+1, N)
    prio = initial_priorities(dists, configs[0].tolist())
    xs, ss, ys = [], [], []
    for t in range(len(configs) - 1):
        here, there = configs[t], configs[t + 1]
        labels = actions_from_moves(here, there, cols)
        idle = (here == g) & (labels == 0)
        keep = ~idle | (rng.random(len(here)) < keep_idle)
        if keep.any():
            feats = policy_features(grid, here, g, dists, prio, version=version)
            x, sc = encode(feats, keep, radius, version)
            xs.append(x)
            ss.append(sc)
            ys.append(labels[keep].astype(np.int8))
        prio = update_priorities(prio, there.tolist(), g.tolist())
    return np.concatenate(xs), np.concatenate(ss), np.concatenate(ys)


def build_dataset(root: np.random.SeedSequence, count: int, radius: int, keep_idle: float,
                  version: int):
    xs, ss, ys, group = [], [], [], []
    stats = {"pibt": 0, "lacam": 0, "unsolved": 0}
    t0 = time.perf_counter()
    for i, child in enumerate(root.spawn(count)):
        rng = np.random.default_rng(child)
        obstacles, starts, goals = make_instance(rng)
        graph, paths, who = expert(obstacles, starts, goals, int(rng.integers(2**31)))
        if paths is None:
            stats["unsolved"] += 1
            continue
        stats[who] += 1
        x, sc, y = samples(graph, paths, goals, radius, rng, keep_idle, version)
        xs.append(x)
        ss.append(sc)
        ys.append(y)
        group.append(np.full(len(y), i, dtype=np.int32))
        if (i + 1) % 25 == 0:
            print(f"  instance {i + 1}/{count}: {sum(len(a) for a in ys)} samples, "
                  f"{time.perf_counter() - t0:.0f} s", flush=True)
    return (np.concatenate(xs), np.concatenate(ss), np.concatenate(ys), np.concatenate(group),
            stats)


# ----------------------------------------------------------------------------- network

def init_params(rng: np.random.Generator, sizes: list[int]) -> dict[str, np.ndarray]:
    params = {}
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:], strict=True), start=1):
        params[f"W{i}"] = (rng.standard_normal((a, b)) * np.sqrt(2.0 / a)).astype(np.float32)
        params[f"b{i}"] = np.zeros(b, dtype=np.float32)
    return params


def forward_backward(p: dict, x: np.ndarray, y: np.ndarray):
    z1 = x @ p["W1"] + p["b1"]
    h1 = np.maximum(z1, 0)
    z2 = h1 @ p["W2"] + p["b2"]
    h2 = np.maximum(z2, 0)
    z3 = h2 @ p["W3"] + p["b3"]
    z3 = z3 - z3.max(axis=1, keepdims=True)
    e = np.exp(z3)
    prob = e / e.sum(axis=1, keepdims=True)
    n = len(y)
    loss = float(-np.log(prob[np.arange(n), y] + 1e-12).mean())
    d3 = prob
    d3[np.arange(n), y] -= 1.0
    d3 /= n
    grads = {"W3": h2.T @ d3, "b3": d3.sum(0)}
    d2 = (d3 @ p["W3"].T) * (z2 > 0)
    grads["W2"], grads["b2"] = h1.T @ d2, d2.sum(0)
    d1 = (d2 @ p["W2"].T) * (z1 > 0)
    grads["W1"], grads["b1"] = x.T @ d1, d1.sum(0)
    return loss, grads


def augment(x: np.ndarray, y: np.ndarray, code: int):
    """One of the 8 symmetries of the square on (B, C, W, W) observations and labels."""
    if code & 4:
        x, y = x.transpose(0, 1, 3, 2), TRANSPOSE[y]
    if code & 1:
        x, y = x[:, :, ::-1, :], FLIP_ROWS[y]
    if code & 2:
        x, y = x[:, :, :, ::-1], FLIP_COLS[y]
    return x, y


def batch_features(x8: np.ndarray, sc: np.ndarray, radius: int) -> np.ndarray:
    """Network input of stored samples: spatial / r, flattened, then the scalars."""
    x = np.ascontiguousarray(x8, dtype=np.float32).reshape(len(x8), -1) * np.float32(1 / radius)
    return np.concatenate([x, sc], axis=1) if sc.shape[1] else x


def accuracy(p: dict, x8: np.ndarray, sc: np.ndarray, y: np.ndarray, radius: int,
             version: int) -> float:
    policy = MLPPolicy(p, radius, version=version)
    hits = 0
    for i in range(0, len(y), 8192):
        xb = batch_features(x8[i:i + 8192], sc[i:i + 8192], radius)
        hits += int((policy.logits(xb).argmax(1) == y[i:i + 8192]).sum())
    return hits / max(1, len(y))


def dagger_dataset(root: np.random.SeedSequence, count: int, policy: MLPPolicy,
                   keep_idle: float, group0: int):
    """DAgger (Ross et al., AISTATS 2011) with a one-step PIBT expert: the current policy
    (behind its shield) drives new instances; at every configuration it visits, every agent
    is labelled with the move one PIBT step (with swap, the controller's priorities) would
    make from there."""
    from warerover_phys.planning.learned.planner import LearnedController
    from warerover_phys.planning.pibt.reference import pibt_step

    radius, version = policy.fov_radius, policy.version
    xs, ss, ys, group = [], [], [], []
    t0 = time.perf_counter()
    for i, child in enumerate(root.spawn(count)):
        rng = np.random.default_rng(child)
        obstacles, starts, goals = make_instance(rng)
        graph = grid_graph(obstacles)
        grid = ObsGrid(~graph.enterable, radius)
        s = [graph.node(c) for c in starts]
        g = [graph.node(c) for c in goals]
        ctrl = LearnedController(policy, graph, seed=int(rng.integers(2**31)))
        ctrl.reset(s, g)
        g_arr = np.array(g)
        dists2 = np.stack([np.append(d, UNREACHABLE) for d in ctrl.dists])
        config = s
        for _ in range(2 * (graph.rows + graph.cols)):
            if config == g:
                break
            tie = rng.random(graph.num_nodes) * 0.5
            best = pibt_step(graph, config, ctrl.dists, ctrl.prio, tie, goals=g)
            here = np.array(config)
            labels = actions_from_moves(here, best, graph.cols)
            keep = ~((here == g_arr) & (labels == 0)) | (rng.random(len(here)) < keep_idle)
            feats = policy_features(grid, here, g_arr, dists2, ctrl.prio, version=version)
            x, sc = encode(feats, keep, radius, version)
            xs.append(x)
            ss.append(sc)
            ys.append(labels[keep].astype(np.int8))
            group.append(np.full(int(keep.sum()), group0 + i, dtype=np.int32))
            config = ctrl.step(config)
        if (i + 1) % 25 == 0:
            print(f"  dagger instance {i + 1}/{count}: {sum(len(a) for a in ys)} samples, "
                  f"{time.perf_counter() - t0:.0f} s", flush=True)
    return np.concatenate(xs), np.concatenate(ss), np.concatenate(ys), np.concatenate(group)


def train(x8, sc, y, groups, *, rng, radius, version, hidden, epochs, batch, lr, init=None):
    held = np.unique(groups)
    held = set(rng.choice(held, size=max(1, len(held) // 20), replace=False).tolist())
    val = np.isin(groups, list(held))
    xt, yt, xv, yv = x8[~val], y[~val].astype(np.int64), x8[val], y[val].astype(np.int64)
    st, sv = sc[~val], sc[val]
    features = x8[0].size + sc.shape[1]
    p = init if init is not None else init_params(rng, [features, hidden, hidden // 2,
                                                         NUM_ACTIONS])
    m = {k: np.zeros_like(v) for k, v in p.items()}
    v = {k: np.zeros_like(v) for k, v in p.items()}
    b1, b2, eps = 0.9, 0.999, 1e-8
    steps_per_epoch = len(yt) // batch
    total = steps_per_epoch * epochs
    step = 0
    log = []
    for epoch in range(epochs):
        t0 = time.perf_counter()
        order = rng.permutation(len(yt))
        losses = []
        for s in range(steps_per_epoch):
            idx = np.sort(order[s * batch:(s + 1) * batch])
            xb, yb = augment(xt[idx], yt[idx], int(rng.integers(8)))
            xb = batch_features(xb, st[idx], radius)
            loss, grads = forward_backward(p, xb, yb)
            losses.append(loss)
            step += 1
            rate = lr * 0.5 * (1 + np.cos(np.pi * step / total))
            for k in p:
                m[k] = b1 * m[k] + (1 - b1) * grads[k]
                v[k] = b2 * v[k] + (1 - b2) * grads[k] ** 2
                mh = m[k] / (1 - b1 ** step)
                vh = v[k] / (1 - b2 ** step)
                p[k] -= (rate * mh / (np.sqrt(vh) + eps)).astype(np.float32)
        acc = accuracy(p, xv, sv, yv, radius, version)
        log.append({"epoch": epoch + 1, "loss": float(np.mean(losses)), "val_acc": acc,
                    "s": time.perf_counter() - t0})
        print(f"  epoch {epoch + 1}/{epochs}: loss {np.mean(losses):.4f}  "
              f"held-out accuracy {acc:.3f}  ({time.perf_counter() - t0:.0f} s)", flush=True)
    return p, log, {"train": int(len(yt)), "val": int(len(yv))}


def _trainer(choice: str):
    """The training function and the back end's name for ``--backend``."""
    if choice == "numpy":
        return train, "numpy"
    try:
        import train_torch
    except ImportError as err:
        if choice == "torch":
            print(f"error: --backend torch: PyTorch is not importable ({err}); "
                  "pip install -e '.[train]'", file=sys.stderr)
            raise SystemExit(2) from None
        return train, "numpy"
    return train_torch.train_torch, "torch"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--instances", type=int, default=1000)
    ap.add_argument("--radius", type=int, default=5, help="field-of-view radius (cells)")
    ap.add_argument("--features", type=int, default=WEIGHTS_VERSION, choices=(1, 2),
                    help="feature set (= weights version): 1 the observation only, 2 with "
                         "priorities, intentions and scalars")
    ap.add_argument("--hidden", type=int, default=256)
    ap.add_argument("--epochs", type=int, default=8)
    ap.add_argument("--batch", type=int, default=512)
    ap.add_argument("--lr", type=float, default=2e-3)
    ap.add_argument("--keep-idle", type=float, default=0.05,
                    help="share of 'on goal, waits' samples kept")
    ap.add_argument("--dagger-rounds", type=int, default=2)
    ap.add_argument("--dagger-instances", type=int, default=300)
    ap.add_argument("--dagger-epochs", type=int, default=4)
    ap.add_argument("--out", type=Path,
                    default=Path(__file__).resolve().parent / "out" / "learned.npz",
                    help="where the weights go (default tools/out/learned.npz; the shipped "
                         "file only when named)")
    ap.add_argument("--backend", choices=("auto", "torch", "numpy"), default="auto",
                    help="training steps in PyTorch (the [train] extra) or numpy; auto: torch "
                         "when importable (the shipped weights: numpy)")
    args = ap.parse_args()
    trainer, backend = _trainer(args.backend)
    t_start = time.perf_counter()
    root = np.random.SeedSequence(args.seed)
    data_seed, train_seed, *dagger_seeds = root.spawn(2 + args.dagger_rounds)
    print(f"generating {args.instances} instances and expert solutions (seed {args.seed})")
    x8, sc, y, groups, stats = build_dataset(data_seed, args.instances, args.radius,
                                             args.keep_idle, args.features)
    t_data = time.perf_counter() - t_start
    counts = np.bincount(y.astype(np.int64), minlength=NUM_ACTIONS).tolist()
    print(f"{len(y)} samples (actions wait/up/down/left/right: {counts}), experts {stats}, "
          f"{t_data:.0f} s")
    train_rng = np.random.default_rng(train_seed)
    if backend != "numpy":
        import train_torch
        train_torch.setup(int(train_seed.generate_state(1)[0]))
    print(f"training with {backend}")
    p, log, split = trainer(x8, sc, y, groups, rng=train_rng, radius=args.radius,
                          version=args.features, hidden=args.hidden, epochs=args.epochs,
                          batch=args.batch, lr=args.lr)
    for k, seed in enumerate(dagger_seeds):
        print(f"DAgger round {k + 1}: rolling out the policy on {args.dagger_instances} new "
              "instances")
        dx, ds, dy, dg = dagger_dataset(seed, args.dagger_instances,
                                        MLPPolicy(p, args.radius, version=args.features),
                                        args.keep_idle, int(groups.max()) + 1)
        print(f"  {len(dy)} new samples")
        x8, sc, y, groups = (np.concatenate([x8, dx]), np.concatenate([sc, ds]),
                             np.concatenate([y, dy]), np.concatenate([groups, dg]))
        p, more, split = trainer(x8, sc, y, groups, rng=train_rng, radius=args.radius,
                               version=args.features, hidden=args.hidden,
                               epochs=args.dagger_epochs,
                               batch=args.batch, lr=args.lr / 2, init=p)
        log += [{**e, "dagger_round": k + 1} for e in more]
    policy = MLPPolicy(p, args.radius, version=args.features)
    policy.save(args.out)
    wall = time.perf_counter() - t_start
    info = {"seed": args.seed, "args": {k: str(v) for k, v in vars(args).items()},
            "samples": split, "action_counts": counts, "experts": stats,
            "data_s": round(t_data, 1), "total_s": round(wall, 1), "epochs": log,
            "params": policy.num_params, "machine": platform.platform(),
            "unreachable": int(UNREACHABLE), "backend": backend}
    if backend != "numpy":
        import torch
        info["torch"] = torch.__version__
    args.out.with_suffix(".json").write_text(json.dumps(info, indent=2) + "\n")
    print(f"wrote {args.out} ({policy.num_params} parameters, "
          f"{args.out.stat().st_size / 1e3:.0f} kB) in {wall:.0f} s")


if __name__ == "__main__":
    main()
