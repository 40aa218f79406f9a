"""The learned planner's policy: local observations, a small numpy network, a PIBT shield.

Everything here is numpy only (nothing imports torch); the Gymnasium / PettingZoo
environments (:mod:`warerover_phys.envs`) and the ``learned`` planner
(:mod:`warerover_phys.planning.learned.planner`) share these functions, so an episode stepped through
the environment with the shielded policy moves exactly as the planner does.

Observation (POGEMA / DHC style): per agent a ``(4, 2r+1, 2r+1)`` float32 window centred on
the agent (``r`` = field-of-view radius, 5 by default), rows and columns as on the grid:

0. obstacles: 1 where the agent may not stand (obstacle, shelf for a loaded AGV, outside
   the grid);
1. other AGVs: 1 where another agent stands;
2. goal: 1 on the goal cell, or where the goal's direction leaves the window (the goal
   clipped to the window's border, as POGEMA draws it);
3. distance-to-goal heuristic: ``clip((d(cell) - d(here)) / r, -1, 1)`` with ``d`` the exact
   shortest-path distance to the agent's goal; 1 where ``d`` is unreachable or off-grid.

Actions: ``0`` wait, ``1`` up (row - 1), ``2`` down (row + 1), ``3`` left (col - 1),
``4`` right (col + 1), POGEMA's order.

Shield: the network's logits rank each agent's five actions; :func:`shield_step` is PIBT
(Okumura et al., AIJ 2022) with that ranking in place of PIBT's distance order. Agents
choose in priority order; an agent that wants a cell held by a lower-priority agent pushes it
(recursively); a move that would swap two agents, enter a taken cell or a cell from which the
goal is unreachable is skipped. The result is always a valid next configuration (no vertex
or swap conflicts), whatever the network says.

Policy features (what the network reads; :func:`policy_features`). Version 1 weights read
the observation above, flattened (``F = 4 (2r+1)^2``). Version 2 weights read it plus what a
PIBT step depends on and the observation lacks (``F = 6 (2r+1)^2 + 4``):

4. others' priority: at each other agent's cell, +1 if its PIBT priority is higher than
   this agent's, -1 if lower;
5. others' intentions: at the cell each other agent would enter going greedily towards its
   goal (its lowest-distance neighbour, or its own cell), +1 if the highest-priority agent
   aiming there outranks this agent, -1 if not, 0 where nobody aims (or only itself);

and four scalars: steps off the goal since the last arrival (``min(int(prio), 32) / 32``),
the priority's fractional part (initial distance order), distance to goal
(``min(d, 64) / 64``), and 1 if on the goal.

Weights file (``.npz``): ``W1 (F, H1)``, ``b1 (H1,)``, ``W2 (H1, H2)``, ``b2 (H2,)``,
``W3 (H2, 5)``, ``b3 (5,)``, ``fov_radius ()`` and ``version ()`` (1 or 2, the feature set).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ...errors import ScenarioError
from ..graph import UNREACHABLE

__all__ = ["ACTIONS", "NUM_ACTIONS", "NUM_CHANNELS", "DEFAULT_WEIGHTS", "WeightsError",
           "ObsGrid", "observe", "policy_features", "num_features", "MLPPolicy", "action_targets", "shield_step",
           "actions_from_moves"]

ACTIONS = np.array([[0, 0], [-1, 0], [1, 0], [0, -1], [0, 1]], dtype=np.int64)
"""(d_row, d_col) per action: wait, up, down, left, right."""
NUM_ACTIONS = 5
NUM_CHANNELS = 4
DEFAULT_WEIGHTS = Path(__file__).parent.parent / "weights" / "learned_v2.npz"
WEIGHTS_VERSION = 2
"""The newest weights format (feature set); every version up to it loads."""
EXTRA_CHANNELS = 2
"""Spatial channels feature set 2 adds to the observation (priorities, intentions)."""
NUM_SCALARS = 4
"""Scalars feature set 2 appends (see the module doc)."""


class WeightsError(ScenarioError):
    """A weights file that is missing, truncated or of the wrong shape (names file and
    field; the CLI prints it on one line and exits 2)."""


class ObsGrid:
    """What observations need of one grid: padded blocked masks, one per agent class.

    ``blocked`` is a ``(classes, rows, cols)`` bool array (class 0: unloaded AGVs; the
    planner adds class 1 for loaded AGVs, which shelves block too).
    """

    def __init__(self, blocked: np.ndarray, fov_radius: int) -> None:
        blocked = np.asarray(blocked, dtype=bool)
        if blocked.ndim == 2:
            blocked = blocked[None]
        self.rows, self.cols = blocked.shape[1:]
        self.r = r = int(fov_radius)
        self.padded_cols = self.cols + 2 * r
        padded = np.pad(blocked, ((0, 0), (r, r), (r, r)), constant_values=True)
        self.blocked_flat = padded.reshape(len(blocked), -1).astype(np.float32)
        """Per class, the padded grid's blocked mask, flattened (1.0 = blocked)."""
        nodes = np.full((self.rows + 2 * r, self.padded_cols), self.rows * self.cols,
                        dtype=np.int64)
        nodes[r:r + self.rows, r:r + self.cols] = np.arange(self.rows * self.cols).reshape(
            self.rows, self.cols)
        self.node_flat = nodes.ravel()
        """Padded flat index -> grid node (``rows * cols`` off the grid)."""
        o = np.arange(-r, r + 1)
        self.window = (o[:, None] * self.padded_cols + o[None, :]).ravel()
        """Padded flat offsets of the window's cells, row by row."""

    @property
    def width(self) -> int:
        return 2 * self.r + 1


def observe(grid: ObsGrid, positions: np.ndarray, goals: np.ndarray,
            dists: np.ndarray | Sequence[np.ndarray], classes: np.ndarray | None = None,
            ) -> np.ndarray:
    """Observations of every agent, ``(N, 4, W, W)`` float32 (see the module doc).

    ``positions`` and ``goals`` are flat nodes (``row * cols + col``); ``dists[i]`` is agent
    ``i``'s flat distance-to-goal table: a sequence of 1-D arrays, or a 2-D array (with one
    extra last column holding ``UNREACHABLE``, read for cells off the grid).
    """
    positions = np.asarray(positions, dtype=np.int64)
    goals = np.asarray(goals, dtype=np.int64)
    n = len(positions)
    r, w, cols = grid.r, grid.width, grid.cols
    out = np.empty((n, NUM_CHANNELS, w * w), dtype=np.float32)
    if n == 0:
        return out.reshape(n, NUM_CHANNELS, w, w)
    pr, pc = np.divmod(positions, cols)
    base = (pr + r) * grid.padded_cols + (pc + r)
    idx = base[:, None] + grid.window  # (N, W*W) padded flat cells of each window
    if classes is None:
        out[:, 0] = grid.blocked_flat[0][idx]
    else:
        out[:, 0] = grid.blocked_flat[np.asarray(classes, np.int64)[:, None], idx]
    occ = np.zeros(grid.node_flat.shape, dtype=np.float32)
    occ[base] = 1.0
    out[:, 1] = occ[idx]
    centre = (w * w) // 2
    out[:, 1, centre] = 0.0
    gr, gc = np.divmod(goals, cols)
    out[:, 2] = 0.0
    out[np.arange(n), 2, (np.clip(gr - pr, -r, r) + r) * w + np.clip(gc - pc, -r, r) + r] = 1.0
    node = grid.node_flat[idx]
    if isinstance(dists, np.ndarray) and dists.ndim == 2:
        d = dists[np.arange(n)[:, None], node]
    else:
        last = grid.rows * grid.cols - 1
        d = np.stack([np.asarray(t)[np.minimum(v, last)] for t, v in zip(dists, node, strict=True)])
        d[node > last] = UNREACHABLE
    here = d[:, centre:centre + 1]
    rel = np.clip((d - here).astype(np.float32) * np.float32(1.0 / r), -1.0, 1.0)
    rel[(d >= UNREACHABLE) | (here >= UNREACHABLE)] = 1.0
    out[:, 3] = rel
    return out.reshape(n, NUM_CHANNELS, w, w)


def num_features(version: int, fov_radius: int) -> int:
    """Length of the feature vector the network of weights ``version`` reads."""
    area = (2 * fov_radius + 1) ** 2
    if version == 1:
        return NUM_CHANNELS * area
    return (NUM_CHANNELS + EXTRA_CHANNELS) * area + NUM_SCALARS


def _dist_at(dists, agents: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """``dists[agents[k]][nodes[k, j]]`` for a 2-D table or a sequence of 1-D tables
    (``nodes`` must lie on the grid)."""
    if isinstance(dists, np.ndarray) and dists.ndim == 2:
        return dists[agents[:, None], nodes]
    return np.stack([np.asarray(dists[i])[v] for i, v in zip(agents, nodes, strict=True)])


def greedy_next(grid: ObsGrid, positions: np.ndarray, dists) -> np.ndarray:
    """Each agent's greedy next node: its neighbour (or its own cell) nearest its goal,
    the first in action order on ties."""
    positions = np.asarray(positions, dtype=np.int64)
    n = len(positions)
    r, c = np.divmod(positions, grid.cols)
    nr, nc = r[:, None] + ACTIONS[None, :, 0], c[:, None] + ACTIONS[None, :, 1]
    inside = (nr >= 0) & (nr < grid.rows) & (nc >= 0) & (nc < grid.cols)
    nodes = np.where(inside, nr * grid.cols + nc, positions[:, None])
    d = _dist_at(dists, np.arange(n), nodes).astype(np.int64)
    d[~inside] = UNREACHABLE
    return nodes[np.arange(n), d.argmin(axis=1)]


def policy_features(grid: ObsGrid, positions: np.ndarray, goals: np.ndarray, dists,
                    prio: Sequence[float], classes: np.ndarray | None = None,
                    version: int = WEIGHTS_VERSION) -> np.ndarray:
    """``(N, F)`` float32 features of weights ``version`` (see the module doc);
    ``prio`` are the agents' PIBT priorities (unused by version 1)."""
    positions = np.asarray(positions, dtype=np.int64)
    obs = observe(grid, positions, goals, dists, classes)
    n = len(positions)
    if version == 1:
        return obs.reshape(n, -1)
    r, w, cols = grid.r, grid.width, grid.cols
    area = w * w
    out = np.zeros((n, num_features(version, r)), dtype=np.float32)
    out[:, :NUM_CHANNELS * area] = obs.reshape(n, -1)
    if n == 0:
        return out
    p = np.asarray(prio, dtype=np.float64)
    pr, pc = np.divmod(positions, cols)
    base = (pr + r) * grid.padded_cols + (pc + r)
    idx = base[:, None] + grid.window
    here = p[:, None]
    at = np.full(grid.node_flat.shape, np.nan)  # priority of the agent on each cell
    at[base] = p
    win = at[idx]
    rel = np.where(np.isnan(win), 0.0, np.sign(win - here))
    rel[:, area // 2] = 0.0
    o = NUM_CHANNELS * area
    out[:, o:o + area] = rel
    g = greedy_next(grid, positions, dists)
    gr, gc = np.divmod(g, cols)
    aim = np.full(grid.node_flat.shape, -np.inf)  # highest priority aiming at each cell
    np.maximum.at(aim, (gr + r) * grid.padded_cols + (gc + r), p)
    win = aim[idx]
    rel = np.where(np.isinf(win), 0.0, np.sign(win - here))
    out[:, o + area:o + 2 * area] = rel
    s = o + 2 * area
    whole = np.floor(p)
    d_here = _dist_at(dists, np.arange(n), positions[:, None])[:, 0].astype(np.float64)
    out[:, s] = np.minimum(whole, 32.0) / 32.0
    out[:, s + 1] = p - whole
    out[:, s + 2] = np.minimum(d_here, 64.0) / 64.0
    out[:, s + 3] = positions == np.asarray(goals, dtype=np.int64)
    return out


def _weights_error(message: str, file: str, field: str | None = None, value=ScenarioError._MISSING):
    return WeightsError(message, file=file, field=field, value=value)


class MLPPolicy:
    """A three-layer perceptron over the flattened observation: ``obs -> 5 logits``.

    >>> policy = MLPPolicy.load()          # the shipped weights
    >>> policy.fov_radius
    5
    """

    LAYERS = (("W1", "b1"), ("W2", "b2"), ("W3", "b3"))

    def __init__(self, params: dict[str, np.ndarray], fov_radius: int, source: str = "<memory>",
                 version: int = 1):
        self.params = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in params.items()}
        self.fov_radius = int(fov_radius)
        self.source = source
        self.version = int(version)
        """Weights format = feature set the network reads (1 or 2; see the module doc)."""
        self._check(source)

    def _check(self, file: str) -> None:
        p = self.params
        for w, b in self.LAYERS:
            for name, ndim in ((w, 2), (b, 1)):
                if name not in p:
                    raise _weights_error("field missing from the weights file", file, name)
                if p[name].ndim != ndim:
                    raise _weights_error(f"expected a {ndim}-D array", file, name,
                                         tuple(p[name].shape))
                if not np.isfinite(p[name]).all():
                    raise _weights_error("non-finite values", file, name)
        prev = num_features(self.version, self.fov_radius)
        for w, b in self.LAYERS:
            rows, cols = p[w].shape
            if rows != prev:
                raise _weights_error(f"expected {prev} input rows (fov_radius "
                                     f"{self.fov_radius})", file, w, tuple(p[w].shape))
            if p[b].shape != (cols,):
                raise _weights_error(f"expected shape ({cols},)", file, b, tuple(p[b].shape))
            prev = cols
        if prev != NUM_ACTIONS:
            raise _weights_error(f"expected {NUM_ACTIONS} outputs", file, "W3",
                                 tuple(p["W3"].shape))

    @classmethod
    def load(cls, path: str | os.PathLike[str] | None = None) -> MLPPolicy:
        """Load a weights file (default: the shipped ``learned_v2.npz``); a
        :class:`WeightsError` naming the file and field if it is missing, truncated or of
        the wrong shape."""
        path = Path(path) if path is not None else DEFAULT_WEIGHTS
        file = str(path)
        from ...inputs import describe, load_npz

        if describe(path) == "missing":
            raise _weights_error("weights file not found", file)
        try:
            params = load_npz(path, "weights", 256 * 2**20)
        except ScenarioError as err:
            raise _weights_error(f"not a readable .npz weights file ({err.message})",
                                 file) from None
        for name in ("fov_radius", "version"):
            if name not in params:
                raise _weights_error("field missing from the weights file", file, name)
        version = int(params.pop("version"))
        if not 1 <= version <= WEIGHTS_VERSION:
            raise _weights_error(f"unsupported weights version (this code reads 1.."
                                 f"{WEIGHTS_VERSION})", file, "version", version)
        radius = int(params.pop("fov_radius"))
        if not 1 <= radius <= 32:
            raise _weights_error("fov_radius must be in 1..32", file, "fov_radius", radius)
        return cls(params, radius, file, version)

    def save(self, path: str | os.PathLike[str]) -> None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, fov_radius=np.int64(self.fov_radius),
                            version=np.int64(self.version), **self.params)

    def features(self, grid: ObsGrid, positions, goals, dists, prio,
                 classes: np.ndarray | None = None) -> np.ndarray:
        """The ``(N, F)`` features this network reads (:func:`policy_features`)."""
        return policy_features(grid, positions, goals, dists, prio, classes, self.version)

    def logits(self, obs: np.ndarray) -> np.ndarray:
        """``(N, 5)`` action logits for ``(N, F)`` features (version 1: also ``(N, 4, W,
        W)`` observations)."""
        p = self.params
        x = obs.reshape(len(obs), -1).astype(np.float32, copy=False)
        h = np.maximum(x @ p["W1"] + p["b1"], 0.0)
        h = np.maximum(h @ p["W2"] + p["b2"], 0.0)
        return h @ p["W3"] + p["b3"]

    @property
    def num_params(self) -> int:
        return int(sum(v.size for v in self.params.values()))


def action_targets(positions: np.ndarray, cols: int) -> np.ndarray:
    """``(N, 5)`` flat target node of each action (may lie off-grid: check with a graph)."""
    steps = ACTIONS[:, 0] * cols + ACTIONS[:, 1]
    return np.asarray(positions, dtype=np.int64)[:, None] + steps[None, :]


def actions_from_moves(config: Sequence[int], nxt: Sequence[int], cols: int) -> np.ndarray:
    """The action index that takes each agent from ``config`` to ``nxt``."""
    a, b = np.asarray(config, np.int64), np.asarray(nxt, np.int64)
    dr, dc = b // cols - a // cols, b % cols - a % cols
    out = np.zeros(len(a), dtype=np.int64)
    out[dr == -1] = 1
    out[dr == 1] = 2
    out[dc == -1] = 3
    out[dc == 1] = 4
    return out


def shield_step(neighbors: Sequence[Sequence[tuple[int, ...]]], config: Sequence[int],
                dists: Sequence[np.ndarray], prio: Sequence[float], logits: np.ndarray,
                cols: int, forced: Sequence[tuple[int, int]] = (), guide: int | None = None,
                ) -> list[int]:
    """PIBT over the policy's preferences: the next node of every agent (always valid).

    ``neighbors[i]`` is agent ``i``'s neighbour table (its motion graph's, per node);
    ``forced`` pins (agent, node) pairs first (e.g. AGVs working in place). Agent ``guide``
    (if given) ranks its moves by distance to its goal (the policy only breaks ties), as
    plain PIBT does: with the highest-priority agent guided, the shield keeps PIBT's
    guarantee that this agent reaches its goal, so a policy that prefers to wait cannot
    stall the whole fleet.
    """
    n = len(config)
    nxt = [-1] * n
    occ_now = {v: i for i, v in enumerate(config)}
    occ_next: dict[int, int] = {}
    for i, v in forced:
        nxt[i] = v
        occ_next[v] = i
    targets = action_targets(np.asarray(config, dtype=np.int64), cols).tolist()
    ranks = np.argsort(-np.asarray(logits, dtype=np.float64), axis=1, kind="stable").tolist()

    def candidates(i: int) -> list[int]:
        here = config[i]
        near = neighbors[i][here]
        d = dists[i]
        out = []
        for a in ranks[i]:
            v = targets[i][a]
            if a == 0 or (v in near and d[v] < UNREACHABLE):
                out.append(v)
        if i == guide:
            out.sort(key=lambda v: d[v])  # stable: the policy's order breaks ties
        return out

    def push(i: int) -> bool:
        here = config[i]
        for v in candidates(i):
            if v in occ_next:
                continue
            k = occ_now.get(v)
            if k is not None and k != i and nxt[k] == here:
                continue  # would swap places with an agent already moving into our cell
            nxt[i] = v
            occ_next[v] = i
            if k is not None and k != i and nxt[k] == -1 and not push(k):
                continue
            return True
        nxt[i] = here
        occ_next[here] = i
        return False

    order = sorted(range(n), key=lambda i: (-prio[i], i))
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 4 * n + 1000))
    try:
        for i in order:
            if nxt[i] == -1:
                push(i)
    finally:
        sys.setrecursionlimit(limit)
    return nxt
