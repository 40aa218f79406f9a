"""The ``learned`` planner: an imitation-learned policy behind a PIBT shield.

A small network (:class:`~warerover_phys.planning.learned.policy.MLPPolicy`, numpy only) was trained
by ``tools/train_learned.py`` to imitate the project's own PIBT / LaCAM solutions from local
observations (:func:`~warerover_phys.planning.learned.policy.observe`). Each tick it ranks every
AGV's five actions; :func:`~warerover_phys.planning.learned.policy.shield_step` (PIBT over those
rankings) turns the rankings into one valid joint move, so plans never conflict.

Like :class:`~warerover_phys.planning.pibt.planner.PIBTPlanner` it is a step planner
(``replans_all``): every tick every AGV gets a two-state path (now, next). Priorities come
from the loop (ticks since the AGV got its goal); AGVs working in place are held. Loaded
AGVs see shelves as obstacles and move on their own motion graph. Liveness fallback: a
tick on which some AGV has chased its goal for more than ``fallback_age`` ticks is planned
by plain PIBT with swap (counted as a budget hit). Rotations (``planner.rotations``) raise
:class:`PlanningError`. Fleets with larger or slower AGVs are planned by one footprint-aware
PIBT step (as ``pibt``) in which the 1x1 one-cell-per-tick AGVs rank their moves by the
policy and the others by distance (the policy was trained on 1x1 AGVs only).

The weights default to the shipped ``weights/learned_v2.npz`` (feature set 2; the first
weights, ``learned_v1.npz``, feature set 1, still load); another file can be given as
``LearnedPlanner(weights=PATH)`` or, from the command line, in the environment variable
``WAREROVER_LEARNED_WEIGHTS``. A missing, truncated or misshapen file raises
:class:`~warerover_phys.planning.learned.policy.WeightsError` (the CLI prints one line, exits 2).

One-shot MAPF (every agent from its start to its goal, MovingAI instances) runs through
:func:`learned_oneshot`, the same policy and shield with PIBT's priority updates.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from ...errors import PlanningError
from ..base import AgentRequest, PlanRequest, PlanResult, TimedPath
from ..graph import MotionGraph
from ..pibt.planner import uniform_fleet
from ..pibt.reference import _to_paths, initial_priorities, pibt_step, update_priorities
from .policy import ACTIONS, MLPPolicy, ObsGrid, shield_step

__all__ = ["LearnedPlanner", "learned_oneshot", "LearnedController", "WEIGHTS_ENV"]

WEIGHTS_ENV = "WAREROVER_LEARNED_WEIGHTS"
Cell = tuple[int, int]


@lru_cache(maxsize=8)
def _load(path: str | None) -> MLPPolicy:
    return MLPPolicy.load(path)


def load_policy(weights: str | os.PathLike[str] | None = None) -> MLPPolicy:
    """The policy in ``weights``, else in ``$WAREROVER_LEARNED_WEIGHTS``, else the shipped
    one (files are read once per process)."""
    path = weights if weights is not None else os.environ.get(WEIGHTS_ENV) or None
    return _load(None if path is None else str(path))


def policy_step(policy: MLPPolicy, grid: ObsGrid, neighbors: Sequence[Sequence[tuple[int, ...]]],
                config: Sequence[int], goals: Sequence[int], dists, prio: Sequence[float],
                classes: np.ndarray | None = None, forced: Sequence[tuple[int, int]] = (),
                ) -> list[int]:
    """One shielded step of the policy: observe, rank actions, resolve with PIBT. The
    highest-priority agent off its goal (not held) is guided by distance (see
    :func:`~warerover_phys.planning.learned.policy.shield_step`)."""
    logits = policy.logits(policy.features(grid, np.asarray(config), np.asarray(goals), dists,
                                           prio, classes))
    pinned = {i for i, _ in forced}
    off = [i for i in range(len(config)) if config[i] != goals[i] and i not in pinned]
    guide = max(off, key=lambda i: (prio[i], -i)) if off else None
    return shield_step(neighbors, config, dists, prio, logits, grid.cols, forced, guide)


def _blocked(graph: MotionGraph) -> np.ndarray:
    """Cells the obstacle channel marks: where the AGV may not stand on its way (shelf homes
    a loaded AGV may enter only to put its shelf back count as blocked)."""
    return ~graph.valid


class LearnedPlanner:
    """Step planner: the learned policy, shielded by PIBT (see the module doc)."""

    name = "learned"
    replans_all = True
    """The loop must send every AGV every tick."""

    def __init__(self, spec: object = None, *, weights: str | os.PathLike[str] | None = None,
                 fallback_age: int | None = None, **_: object) -> None:
        self.policy = load_policy(weights)
        self.fallback_age = fallback_age
        """Liveness fallback: a tick on which some AGV has had its goal for more than this
        many ticks (default ``2 * (rows + cols)``) is planned by plain PIBT with swap
        instead (counted in ``PlanResult.budget_hits``)."""

    def plan(self, request: PlanRequest) -> PlanResult:
        agents: list[AgentRequest] = sorted(request.agents, key=lambda a: a.agv)
        result = PlanResult()
        if not agents:
            return result
        if any(a.turn_ticks is not None for a in agents):
            raise PlanningError("the learned planner does not plan rotations "
                                "(planner.rotations: true): use astar, pibt or lacam")
        if not uniform_fleet(agents):
            return self._plan_mixed(request, agents)
        graphs = request.graphs
        unloaded, loaded = graphs.get(1, False), graphs.get(1, True)
        grid = _obs_grid(unloaded, loaded, self.policy.fov_radius)
        config = [a.start for a in agents]
        goals = [a.goal for a in agents]
        neighbors = [(loaded if a.loaded else unloaded).neighbors for a in agents]
        dists = [(loaded if a.loaded else unloaded).dist_to(unloaded.cell(a.goal))
                 for a in agents]
        classes = np.array([1 if a.loaded else 0 for a in agents], dtype=np.int64)
        prio = [float(a.priority[0]) if a.priority else 0.0 for a in agents]
        held = [(i, a.start) for i, a in enumerate(agents) if a.hold]
        limit = (2 * (unloaded.rows + unloaded.cols) if self.fallback_age is None
                 else self.fallback_age)
        stale = any(p > limit and not a.hold and a.start != a.goal
                    for p, a in zip(prio, agents, strict=True))
        nxt = None
        if stale:
            rng = request.rng if request.rng is not None else np.random.default_rng(0)
            tie = rng.random(unloaded.num_nodes) * 0.5
            nxt = pibt_step(unloaded, config, dists, prio, tie, forced=held, goals=goals,
                            tables=neighbors)
            result.budget_hits += 1
        if nxt is None:
            nxt = policy_step(self.policy, grid, neighbors, config, goals, dists, prio,
                              classes, held)
        res = request.reservations  # private scratch: the loop commits the returned paths
        for a, here, there in zip(agents, config, nxt, strict=True):
            states = ((here, here),) if here == there else ((here, here), (there, there))
            path = TimedPath(a.agv, request.tick, states)
            res.commit(path, 1)
            result.paths[a.agv] = path
        return result


    def _plan_mixed(self, request: PlanRequest, agents: list[AgentRequest]) -> PlanResult:
        """A fleet of mixed sizes or speeds: one footprint-aware PIBT step
        (:func:`~warerover_phys.planning.pibt.planner.footprint_plan`, as ``pibt``) in which
        every 1x1 AGV that moves a cell per tick and stands ranks its moves by the policy
        (``Mover.prefer``); larger and slower AGVs rank theirs by distance, as the policy was
        trained on 1x1 AGVs only. The policy sees every AGV on its anchor cell. The liveness
        fallback plans the tick with no policy ranking."""
        from ..pibt.planner import footprint_plan

        unloaded = request.graphs.get(1, False)
        prio = [float(a.priority[0]) if a.priority else 0.0 for a in agents]
        limit = (2 * (unloaded.rows + unloaded.cols) if self.fallback_age is None
                 else self.fallback_age)
        if any(p > limit and not a.hold and a.start != a.goal
               for p, a in zip(prio, agents, strict=True)):
            result = footprint_plan(request, agents)
            result.budget_hits += 1
            return result

        def rank(movers, poses, prio, held):
            return self._ranked(request, agents, movers, poses, prio, held)

        return footprint_plan(request, agents, rank=rank)

    def _ranked(self, request: PlanRequest, agents: list[AgentRequest], movers: list,
                poses: list, prio: list[float], held: dict[int, int]) -> list:
        """``movers`` with the policy's ranking of moves for the standing 1x1 AGVs that move
        a cell per tick (``Mover.prefer``: minus the logit of each move's action)."""
        from dataclasses import replace

        small = [i for i, mv in enumerate(movers)
                 if mv.k == 1 and mv.m == 1 and mv.rot is None and not mv.turns
                 and poses[i][2] == 0 and i not in held]
        if not small:
            return movers
        unloaded, loaded = request.graphs.get(1, False), request.graphs.get(1, True)
        grid = _obs_grid(unloaded, loaded, self.policy.fov_radius)
        config = np.array([p[1] for p in poses], dtype=np.int64)
        goals = np.array([a.goal for a in agents], dtype=np.int64)
        dists = [mv.dist if mv.k == 1 else unloaded.dist_to(unloaded.cell(a.goal))
                 for a, mv in zip(agents, movers, strict=True)]
        classes = np.array([1 if a.loaded else 0 for a in agents], dtype=np.int64)
        logits = self.policy.logits(self.policy.features(grid, config, goals, dists, prio,
                                                         classes))
        rows, cols = unloaded.rows, unloaded.cols
        out = list(movers)
        for i in small:
            here = int(config[i])
            r, c = divmod(here, cols)
            pref = {here: -float(logits[i, 0])}
            for act, (dr, dc) in enumerate(ACTIONS.tolist()[1:], start=1):
                v = (r + dr) * cols + (c + dc)
                if 0 <= r + dr < rows and 0 <= c + dc < cols and v in movers[i].neighbors[here]:
                    pref[v] = -float(logits[i, act])
            out[i] = replace(movers[i], prefer=pref)
        return out


_GRIDS: dict[tuple[int, int, int], tuple[MotionGraph, MotionGraph, ObsGrid]] = {}


def _obs_grid(unloaded: MotionGraph, loaded: MotionGraph, radius: int) -> ObsGrid:
    """Observation masks of a layout (unloaded class 0, loaded class 1), built once per
    pair of graphs (the cache holds the graphs, so their ids stay theirs)."""
    key = (id(unloaded), id(loaded), radius)
    hit = _GRIDS.get(key)
    if hit is not None and hit[0] is unloaded and hit[1] is loaded:
        return hit[2]
    if len(_GRIDS) >= 16:
        _GRIDS.clear()
    grid = ObsGrid(np.stack([_blocked(unloaded), _blocked(loaded)]), radius)
    _GRIDS[key] = (unloaded, loaded, grid)
    return grid


def learned_oneshot(graph: MotionGraph, starts: Sequence[Cell], goals: Sequence[Cell],
                    deadline: float, seed: int = 0, max_steps: int | None = None,
                    policy: MLPPolicy | None = None,
                    ) -> tuple[list[list[Cell]] | None, dict]:
    """Shielded policy until every agent stands on its goal (None when ``max_steps`` or the
    deadline passes first). ``seed`` seeds the liveness fallback's tie-breaks (see
    :class:`LearnedController`); the same seed gives the same paths."""
    policy = policy or load_policy()
    ctrl = LearnedController(policy, graph, seed=seed)
    s = [graph.node(c) for c in starts]
    g = [graph.node(c) for c in goals]
    ctrl.reset(s, g)
    configs = [s]
    max_steps = max_steps or 20 * (graph.rows + graph.cols) + 1000
    while configs[-1] != g:
        if len(configs) > max_steps or time.monotonic() > deadline:
            return None, {"steps": len(configs) - 1, "fallback_steps": ctrl.fallback_steps}
        configs.append(ctrl.step(configs[-1]))
    return _to_paths(graph, configs), {"steps": len(configs) - 1,
                                       "fallback_steps": ctrl.fallback_steps}


class LearnedController:
    """The shielded policy driving every agent of a one-shot episode, step by step; used by
    :func:`learned_oneshot` and by the environments (so both move the same way).

    Priorities follow PIBT: initially by distance to goal (farther first, in [0, 1)), +1 for
    each step an agent is off its goal, back to the fractional part when it arrives.

    Liveness fallback: PIBT without swap (which is what the shield is) can cycle forever
    when two agents must pass each other in a corridor or a dead end. The controller keeps
    the lowest sum of distances to goals seen so far; after ``patience`` steps without a
    new lowest, it takes plain PIBT steps (with swap, ties drawn from the seeded
    generator) until one is reached, then hands back to the policy. The best sum falls by
    at least one each time, so the fallback can only run a bounded number of times per
    episode. ``fallback_steps`` counts those steps.
    """

    def __init__(self, policy: MLPPolicy, graph: MotionGraph, patience: int = 16,
                 seed: int = 0) -> None:
        self.policy = policy
        self.graph = graph
        self.patience = patience
        self.seed = seed
        self.grid = ObsGrid(_blocked(graph), policy.fov_radius)
        self.goals: list[int] = []
        self.dists: list[np.ndarray] = []
        self.prio: list[float] = []
        self.rng = np.random.default_rng(seed)
        self.best = 0
        self.stall = 0
        self.fallback_steps = 0

    def reset(self, starts: Sequence[int], goals: Sequence[int]) -> None:
        graph = self.graph
        self.goals = [int(v) for v in goals]
        self.dists = [graph.dist_to(graph.cell(v)) for v in self.goals]
        self.prio = initial_priorities(self.dists, [int(v) for v in starts])
        self.rng = np.random.default_rng(self.seed)
        self.best = self._total([int(v) for v in starts])
        self.stall = 0
        self.fallback_steps = 0

    def _total(self, config: Sequence[int]) -> int:
        return int(sum(int(d[v]) for d, v in zip(self.dists, config, strict=True)))

    def set_goal(self, agent: int, goal: int) -> None:
        """Lifelong use: a new goal for ``agent`` (its priority restarts)."""
        self.goals[agent] = int(goal)
        self.dists[agent] = self.graph.dist_to(self.graph.cell(goal))
        self.prio[agent] = self.prio[agent] - int(self.prio[agent])
        self.best = 1 << 62  # goals moved: the next step sets a new lowest
        self.stall = 0

    def step(self, config: Sequence[int]) -> list[int]:
        """The next configuration from ``config`` (flat nodes); updates priorities."""
        config = [int(v) for v in config]
        if self.stall >= self.patience:
            tie = self.rng.random(self.graph.num_nodes) * 0.5
            nxt = pibt_step(self.graph, config, self.dists, self.prio, tie,
                            goals=self.goals, swap=True)
            self.fallback_steps += 1
        else:
            tables = [self.graph.neighbors] * len(config)
            nxt = policy_step(self.policy, self.grid, tables, config, self.goals, self.dists,
                              self.prio)
        total = self._total(nxt)
        if total < self.best:
            self.best, self.stall = total, 0
        else:
            self.stall += 1
        self.prio = update_priorities(self.prio, nxt, self.goals)
        return nxt
