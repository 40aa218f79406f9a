"""The whole closed loop of a scenario as a PettingZoo parallel environment.

:class:`WarehouseLoopEnv` runs a scenario's episode (orders, the scheduler, multi-stage
tasks with their work in place, faults, the scenario's executor: grid or physics) through
:class:`~warerover_phys.sim.Simulation`, with the agents in the planner's place: every tick
each AGV (agent ``agv_i``) picks one of five actions, ``0`` wait, ``1`` up, ``2`` down,
``3`` left, ``4`` right (row, col), and the loop commits the joint move as that tick's plan,
as it commits a step planner's (``pibt``, ``learned``). The loop stays the only writer of the
world: the environment hands it a :class:`~warerover_phys.planning.base.PlanResult` through
:meth:`Simulation.finish_tick <warerover_phys.sim.Simulation.finish_tick>`.

Rules of one step, on the planning request the loop made for the tick
(:attr:`WarehouseLoopEnv.request`):

- an AGV the loop holds (working in place, failed, no goal: ``infos[agent]["hold"]``)
  waits whatever it asked;
- a move that leaves its motion graph (off the grid, into an obstacle; a loaded AGV into
  another shelf) is cancelled;
- conflicting moves are cancelled, repeatedly until none is left: two AGVs entering one
  cell (both wait), an AGV entering the cell of one that stays, two AGVs swapping cells.
  Following an AGV that leaves, and moving round a cycle, are kept (as from ``pibt``; the
  executor orders them).

Observations: each agent's ``(4, 2r+1, 2r+1)`` window of
:func:`~warerover_phys.planning.learned.policy.observe` (obstacles for its class: a loaded AGV's
shelves block it; other AGVs; its goal's direction; its distance-to-goal heuristic), for the
goal the loop gives it this tick. ``infos[agent]``: ``goal`` (cell), ``hold``, ``loaded``,
``priority`` (ticks it has chased its goal, as the loop ranks step planners' AGVs; 0 held),
``state`` (the AGV's task state), ``blocked`` (it asked to move and stays).

Rewards (per agent per step, :class:`LoopConfig`): ``order_reward`` (1.0) to every agent for
each order completed that tick (the team's throughput), ``step_penalty`` (-0.01) for an agent
that has somewhere to go and is not holding, ``blocked_penalty`` (-0.05) when its move was
cancelled. The episode terminates when every order is done and is truncated at the
scenario's ``max_ticks``.

Any step planner can drive it: :class:`PlannerDriver` asks a planner (``learned``, ``pibt``
or a plug-in with ``replans_all``) for the request the environment shows and returns its
joint move as actions, so the episode is the one ``warerover run`` gives with that planner
and seed (tested), and a planner's actions are expert labels for imitation.

Scope: fleets of 1x1 AGVs that move one cell per tick, without ``planner.rotations`` (as the
``learned`` planner); anything else raises ``ValueError``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..planning.base import PlanResult
from ..planning.learned.policy import ACTIONS, NUM_ACTIONS, ObsGrid, actions_from_moves, observe
from ..planning.paths import TimedPath
from .deps import require

require("pettingzoo")

from gymnasium import spaces  # noqa: E402
from pettingzoo import ParallelEnv  # noqa: E402

if TYPE_CHECKING:
    from ..config import Scenario
    from ..planning.base import PlanRequest

__all__ = ["LoopConfig", "WarehouseLoopEnv", "PlannerDriver", "loop_env", "resolve_moves"]


@dataclass(frozen=True)
class LoopConfig:
    """Settings of a :class:`WarehouseLoopEnv` (``ValueError`` on bad values)."""

    fov_radius: int = 5
    """Observation window radius, cells."""
    order_reward: float = 1.0
    step_penalty: float = -0.01
    blocked_penalty: float = -0.05

    def __post_init__(self) -> None:
        if not 1 <= self.fov_radius <= 32:
            raise ValueError(f"fov_radius must be in 1..32 (got {self.fov_radius})")


class _ActionPlanner:
    """The planner the loop calls: the joint move the environment set for this tick."""

    name = "env-actions"
    replans_all = True

    def plan(self, request: PlanRequest) -> PlanResult:  # pragma: no cover - not called
        raise RuntimeError("the environment plans through Simulation.finish_tick")


def resolve_moves(start: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``target`` with conflicting moves cancelled (each cancelled AGV stays on ``start``),
    until none is left: two AGVs entering one cell, entering the cell of an AGV that stays,
    swapping cells. Following and cycles are kept."""
    start = np.asarray(start, dtype=np.int64)
    target = np.asarray(target, dtype=np.int64).copy()
    idx = {int(v): i for i, v in enumerate(start)}
    while True:
        moving = target != start
        count: dict[int, int] = {}
        for v in target.tolist():
            count[v] = count.get(v, 0) + 1
        bad = np.zeros(len(start), dtype=bool)
        for i in np.flatnonzero(moving):
            v = int(target[i])
            j = idx.get(v)
            if count[v] > 1 or (j is not None and (target[j] == start[j]
                                                  or target[j] == start[i])):
                bad[i] = True
        if not bad.any():
            return target
        target[bad] = start[bad]


class WarehouseLoopEnv(ParallelEnv):
    """A scenario's closed loop with the AGVs as agents (see the module doc)."""

    metadata = {"name": "warerover_loop_v0", "render_modes": [], "is_parallelizable": True}

    def __init__(self, scenario: Scenario | str | Path, config: LoopConfig | None = None,
                 render_mode: str | None = None) -> None:
        from ..config import Scenario, load_scenario
        from ..sim import Simulation

        if render_mode is not None:
            raise ValueError(f"render_mode: this environment renders nothing (got "
                             f"{render_mode!r}); use warerover run --video")
        sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
        self.scenario = sc
        self.config = config or LoopConfig()
        self.render_mode = None
        if sc.planner.rotations:
            raise ValueError("WarehouseLoopEnv: planner.rotations is not supported "
                             "(headings and turn actions: warerover_phys.envs.parallel_env)")
        probe = Simulation(sc, planner=_ActionPlanner())
        odd = sorted({a.id for a in probe.world.agvs if a.k != 1 or a.ticks_per_move != 1})
        if odd:
            raise ValueError(f"WarehouseLoopEnv drives 1x1 AGVs that move one cell per tick "
                             f"only; AGVs {odd[:8]} of {sc.name!r} are larger or slower")
        n = len(probe.world.agvs)
        self.possible_agents = [f"agv_{i}" for i in range(n)]
        self.agents: list[str] = []
        g1, g2 = probe.world.graphs.get(1, False), probe.world.graphs.get(1, True)
        self._grid = ObsGrid(np.stack([~g1.valid, ~g2.valid]), self.config.fov_radius)
        w = 2 * self.config.fov_radius + 1
        self._obs_space = spaces.Box(-1.0, 1.0, (4, w, w), dtype=np.float32)
        self._act_space = spaces.Discrete(NUM_ACTIONS)
        self.sim = None
        """The :class:`~warerover_phys.sim.Simulation` of the current episode (read it; do
        not write it)."""
        self.request: PlanRequest | None = None
        """The loop's planning request for the coming step (every AGV, in id order)."""
        self._seed = int(sc.seed)
        """The seed of the next reset (a reset without one repeats the last)."""

    def observation_space(self, agent: str) -> spaces.Box:
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Discrete:
        return self._act_space

    # ------------------------------------------------------------------------ episode

    def reset(self, seed: int | None = None, options: dict | None = None):
        """A new episode of the scenario with ``seed`` (default: the scenario's seed; a
        reset without a seed repeats the last episode's seed, as ``warerover run``)."""
        from ..sim import Simulation

        if seed is not None:
            self._seed = int(seed)
        self.sim = Simulation(self.scenario, self._seed, planner=_ActionPlanner())
        self.agents = list(self.possible_agents)
        self._begin()
        blocked = np.zeros(len(self.possible_agents), dtype=bool)
        return self._observations(), self._infos(blocked)

    def _begin(self) -> None:
        """Run the loop up to the planning of the next tick (ticks nobody needs planning
        in pass on their own)."""
        sim = self.sim
        self.request = None
        while not sim.done:
            req = sim.begin_tick()
            if req is not None:
                self.request = req
                return
            sim.finish_tick(None)

    def step(self, actions: dict[str, int]):
        if not self.agents or self.request is None:
            raise RuntimeError("step() after the episode ended: call reset()")
        names = self.possible_agents
        arr = np.array([int(actions.get(a, 0)) for a in names], dtype=np.int64)
        if arr.min(initial=0) < 0 or arr.max(initial=0) >= NUM_ACTIONS:
            raise ValueError(f"actions must be in 0..{NUM_ACTIONS - 1}, got {actions!r}")
        sim, req = self.sim, self.request
        done_before = len(sim.world.completed_tick)
        result, blocked = self._joint_move(req, arr)
        sim.finish_tick(result)
        self._begin()
        orders = len(sim.world.completed_tick) - done_before
        cfg = self.config
        active = self._active(req)
        rewards = (cfg.order_reward * orders + cfg.step_penalty * active
                   + cfg.blocked_penalty * blocked)
        terminated = sim.world.all_done()
        truncated = not terminated and sim.done
        out = (self._observations(), {a: float(r) for a, r in zip(names, rewards, strict=True)},
               {a: terminated for a in names}, {a: truncated for a in names},
               self._infos(blocked))
        if terminated or truncated:
            self.agents = []
        return out

    def _active(self, req: PlanRequest) -> np.ndarray:
        return np.array([not a.hold and a.start != a.goal for a in req.agents], dtype=bool)

    def _joint_move(self, req: PlanRequest, actions: np.ndarray) -> tuple[PlanResult,
                                                                           np.ndarray]:
        graphs = req.graphs
        start = np.array([a.start for a in req.agents], dtype=np.int64)
        target = start.copy()
        for i, a in enumerate(req.agents):
            if a.hold or actions[i] == 0:
                continue
            g = graphs.get(1, a.loaded)
            r, c = g.cell(a.start)
            dr, dc = ACTIONS[actions[i]]
            nr, nc = r + int(dr), c + int(dc)
            if 0 <= nr < g.rows and 0 <= nc < g.cols and g.node((nr, nc)) in g.neighbors[a.start]:
                target[i] = g.node((nr, nc))
        target = resolve_moves(start, target)
        blocked = (actions != 0) & (target == start)
        result = PlanResult()
        for a, here, there in zip(req.agents, start.tolist(), target.tolist(), strict=True):
            states = ((here, here),) if here == there else ((here, here), (there, there))
            result.paths[a.agv] = TimedPath(a.agv, req.tick, states)
        return result, blocked

    def _observations(self) -> dict[str, np.ndarray]:
        req = self.request
        if req is None:  # the episode ended: the last observation is the final poses'
            w = 2 * self.config.fov_radius + 1
            return {a: np.zeros((4, w, w), dtype=np.float32) for a in self.possible_agents}
        g1, g2 = req.graphs.get(1, False), req.graphs.get(1, True)
        config = np.array([a.start for a in req.agents], dtype=np.int64)
        goals = np.array([a.goal for a in req.agents], dtype=np.int64)
        dists = [(g2 if a.loaded else g1).dist_to(g1.cell(a.goal)) for a in req.agents]
        classes = np.array([int(a.loaded) for a in req.agents], dtype=np.int64)
        obs = observe(self._grid, config, goals, dists, classes)
        return dict(zip(self.possible_agents, obs, strict=True))

    def _infos(self, blocked: np.ndarray) -> dict[str, dict]:
        req, sim = self.request, self.sim
        out = {}
        for i, name in enumerate(self.possible_agents):
            agv = sim.world.agvs[i]
            info = {"blocked": bool(blocked[i]), "state": agv.state.name,
                    "loaded": bool(agv.loaded)}
            if req is not None:
                a = req.agents[i]
                cell = req.graphs.get(1, False).cell(a.goal)
                info.update(goal=(int(cell[0]), int(cell[1])), hold=bool(a.hold),
                            priority=float(a.priority[0]) if a.priority else 0.0)
            out[name] = info
        return out

    def state(self) -> np.ndarray:
        """Global state: ``(3, rows, cols)`` float32: obstacles, AGVs, goals (this tick's)."""
        g = self.sim.world.graphs.get(1, False)
        out = np.zeros((3, g.rows, g.cols), dtype=np.float32)
        out[0] = ~g.valid
        if self.request is not None:
            for a in self.request.agents:
                out[1].flat[a.start] = 1.0
                out[2].flat[a.goal] = 1.0
        return out

    def render(self):
        return None

    def close(self) -> None:
        pass

    def paths(self) -> dict[int, list[tuple[int, int]]]:
        """Executed state per tick per AGV, from tick 0 (as ``EpisodeResult.actual``)."""
        return {k: list(v) for k, v in self.sim.actual.items()}


class PlannerDriver:
    """A step planner choosing every agent's action in a :class:`WarehouseLoopEnv`: it plans
    the request the environment shows, and its joint move becomes the actions (a
    ``learned`` or ``pibt`` expert for imitation; the episode is ``warerover run``'s with
    that planner and seed)."""

    def __init__(self, env: WarehouseLoopEnv, planner: str = "learned", **fields) -> None:
        from ..config import PlannerSpec
        from ..planning import make_planner

        self.env = env
        spec = PlannerSpec.model_validate(
            {**env.scenario.planner.model_dump(), "name": planner, **fields})
        self.planner = make_planner(spec)
        if not self.planner.replans_all:
            raise ValueError(f"planner {planner!r} is not a step planner (replans_all): "
                             "it cannot choose one move per tick")

    def actions(self) -> dict[str, int]:
        """The planner's move for every agent, for the environment's current request."""
        req = self.env.request
        if req is None:
            return {}
        result = self.planner.plan(req)
        config = [a.start for a in req.agents]
        nxt = []
        for a in req.agents:
            path = result.paths.get(a.agv)
            nxt.append(path.states[1][0] if path is not None and len(path.states) > 1
                       else a.start)
        acts = actions_from_moves(config, nxt, req.graphs.get(1, False).cols)
        return dict(zip(self.env.possible_agents, acts.tolist(), strict=True))


def loop_env(scenario: Scenario | str | Path, **config) -> WarehouseLoopEnv:
    """A :class:`WarehouseLoopEnv`; keyword arguments are :class:`LoopConfig` fields."""
    return WarehouseLoopEnv(scenario, LoopConfig(**config))
