"""The grid MAPF world behind the environments: numpy arrays indexed by agent slot.

:class:`GridMAPF` holds positions, goals and distance tables of ``N`` agents on an obstacle
grid and steps them all at once (no dicts, no spaces: the PettingZoo and Gymnasium classes
wrap it). It draws nothing itself: every random choice comes from the generator passed to
:meth:`GridMAPF.reset`.

Rules of one step (all agents at once, the ideal grid executor's semantics):

- actions ``0`` wait, ``1`` up, ``2`` down, ``3`` left, ``4`` right (row, col);
- a move off the grid or onto an obstacle is cancelled (the agent waits);
- conflicting moves are cancelled, repeatedly until none is left: several agents entering
  one cell (all of them wait; an agent that waits keeps its cell), two agents swapping cells
  (both wait). Following (entering a cell its agent leaves in the same step) and rotations
  are allowed, as in the MAPF definition the validator checks.

Rewards (per agent per step, defaults of :class:`EnvConfig`): ``+goal_reward`` (1.0) for
stepping onto its goal, ``-goal_reward`` for stepping off it (so waiting on and off the goal
earns nothing), ``step_penalty`` (-0.01) for ending the step off its goal, and
``blocked_penalty`` (-0.05) when its move was cancelled.

Episodes: one-shot (default) ends (``terminated``) when every agent stands on its goal;
lifelong (``lifelong=True``) gives an agent a new random goal the step it arrives and never
terminates. Both are truncated after ``max_steps`` steps.

Rotations (``EnvConfig.rotations``, or a scenario whose ``planner.rotations`` is true):
every agent has a heading (``0`` east, ``1`` south, ``2`` west, ``3`` north, as
:func:`~warerover_phys.validate.validate_headings`), drawn at random at reset, and four
actions: ``0`` wait, ``1`` forward (one cell along the heading, the only way to move),
``2`` turn left, ``3`` turn right (a quarter turn in place, one step). Forward moves go
through the rules above (a cancelled forward move is ``blocked``); the observation gets a
fifth channel, 1 on the cell ahead of the agent (its heading). Trajectories and headings
pass the validator's rotation checks with one-step quarter turns. On a real executor (see
below) a turn is a committed plan that stands on the agent's cell and changes its heading
(``TimedPath.headings``; the executor gets ``turn_in_place: true`` to follow it): the body
turns at its turn rate, so a quarter turn takes the motion model's time (0.63 s, within one
step, for the default AGV; ``turn_ticks`` steps for a slower one), and the agent keeps its
heading and counts as ``turning`` (its actions wait) until the report's body angle faces
the new heading. Bodies start facing east (the executor's start pose), not at random; the
AGV must have a differential drive whose turn in place stays within its cell.

Executors (``EnvConfig.executor``). With ``"grid"`` (the default) the rules above *are* the
step: every move they keep happens. With ``"physics"`` or any other executor the registry
knows (a built-in name, an entry point, ``package.module:ClassName``, or an
:class:`~warerover_phys.config.ExecutorSpec` for its settings), the rules only turn the joint
action into the intended next cells; those are handed to a real executor through its
Protocol (:mod:`warerover_phys.executors.base`) as one-move committed plans, one tick
(``tick_s`` = 1 s, 1 m cells) per step, and the executor's :class:`StepReport` decides what
happened:

- an agent standing at ``a`` (state ``(a, a)``) is at ``a``;
- an agent moving from ``a`` to ``b`` (state ``(a, b)``) is *in transit*: it occupies both
  cells, observations show it at ``a``, and its actions are treated as wait until it stands
  again (``info["in_transit"]``). No other agent may enter ``b`` meanwhile (following it out
  of ``a`` is allowed; the executor orders it);
- rotations (agents moving round a cycle, each into the cell the next one leaves) are
  cancelled too: a real executor has no order for them;
- ``blocked`` (and its penalty): the agent asked to move (with rotations: forward) and
  still stands on its cell after the step, whether the rules cancelled the move or the
  executor did not start it (waiting for a cell, turning towards the move);
- rewards and termination use the executor's states: an agent is on its goal only while it
  stands there.

Each reset builds and binds a fresh executor; its random generator is drawn from the
episode's, so one seed gives one episode on any executor. The default AGV is a 1x1,
0.7 m, 1 m/s differential-drive body (``EnvConfig.agv_type`` to change it); on ``physics``
such an AGV needs about two steps per cell.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

from ..planning.graph import UNREACHABLE, MotionGraph
from ..planning.learned.policy import ACTIONS, NUM_ACTIONS, NUM_CHANNELS, ObsGrid, observe
from ..planning.oneshot.core import grid_graph
from .actions import (  # noqa: F401
    HEADING_MOVE,
    HEADING_STEP,
    MOVE_HEADING,
    NUM_ROT_ACTIONS,
    TURN,
    LearnedDriver,
    rotation_actions,
)
from .instance import (  # noqa: F401
    ALIGN_RAD,
    TICK_S,
    EnvConfig,
    Instance,
    default_agv,
)
from .view import (  # noqa: F401
    render_ansi,
    render_rgb,
)

if TYPE_CHECKING:
    from ..executors.base import StepReport

__all__ = ["EnvConfig", "GridMAPF", "Instance"]


class GridMAPF:
    """``N`` agents on a grid, stepped together (see the module doc)."""

    def __init__(self, instance: Instance, config: EnvConfig = EnvConfig()) -> None:  # noqa: B008
        self.instance = instance
        self.config = config
        obstacles = np.asarray(instance.obstacles, dtype=bool)
        self.graph: MotionGraph = grid_graph(obstacles)
        self.rows, self.cols = obstacles.shape
        self.free = ~obstacles
        self.obs_grid = ObsGrid(obstacles, config.fov_radius)
        n = config.num_agents
        self.rotations = bool(config.rotations or instance.rotations)
        """Headings and turn actions (see the module doc)."""
        if self.rotations and config.executor_spec is not None:
            from ..planning.sweep import agv_sweeps

            if agv_sweeps([config.agv_type or default_agv()], 1.0):
                raise ValueError(f"rotations on {config.executor_spec.name!r}: the AGV's turn "
                                 "in place sweeps beyond its cell (a smaller body, please)")
        self.heading = np.zeros(n, dtype=np.int64)
        """Each agent's heading (rotations only): 0 east, 1 south, 2 west, 3 north (on a
        real executor: the last one its body was reported facing)."""
        self.turn_to = self.heading
        """Rotations on a real executor: the heading each agent is turning to (its
        ``heading`` when it is not turning)."""
        if instance.starts is not None:
            if len(instance.starts) != n or instance.goals is None or len(instance.goals) != n:
                raise ValueError(f"instance {instance.name!r} fixes "
                                 f"{len(instance.starts)} agents, config asks for {n}")
        # The largest connected part of the free cells: where random starts/goals are drawn.
        free_nodes = np.flatnonzero(self.free.ravel())
        if len(free_nodes) == 0:
            raise ValueError(f"instance {instance.name!r} has no free cell")
        best = None
        seen = np.zeros(self.rows * self.cols, dtype=bool)
        for v in free_nodes:
            if seen[v]:
                continue
            part = self.graph.dist_to(self.graph.cell(int(v))) < UNREACHABLE
            seen |= part
            if best is None or part.sum() > best.sum():
                best = part
            if best.sum() * 2 > len(free_nodes):
                break
        self.sample_nodes = np.flatnonzero(best)
        if instance.starts is None and len(self.sample_nodes) < n:
            raise ValueError(f"{n} agents do not fit the {len(self.sample_nodes)} connected "
                             f"free cells of {instance.name!r}")
        self.pos = np.zeros(n, dtype=np.int64)
        """Each agent's cell (the cell it leaves, while in transit)."""
        self.dest = self.pos
        """Each agent's cell after its move under way (``pos`` when standing)."""
        self.goal = np.zeros(n, dtype=np.int64)
        self.dist = np.full((n, self.rows * self.cols + 1), UNREACHABLE, dtype=np.int32)
        """Per agent, distance to its goal from every node; last column: off the grid."""
        self.t = 0
        self._rng: np.random.Generator | None = None
        # A real executor (None: the step rules alone).
        self.executor_spec = config.executor_spec
        if self.rotations and self.executor_spec is not None:
            # Turn actions are plans that stand and turn: the executor must follow them.
            self.executor_spec = self.executor_spec.model_copy(update={"turn_in_place": True})
        self.executor: Any = None
        """The executor of the current episode (rebuilt by every reset)."""
        self.report: StepReport | None = None
        """The executor's report of the last step (None on the grid rules)."""
        self.collisions = 0
        """Collisions the executor reported this episode."""
        self._plans: dict = {}
        if self.executor_spec is not None:
            from ..layout import CellType, Layout
            from ..registry import resolve

            resolve("executor", self.executor_spec.name)  # unknown names fail here
            grid = np.where(obstacles, CellType.OBSTACLE, CellType.FLOOR).astype(np.int8)
            self.layout = Layout(grid=grid, cell_m=1.0, shelves=(), stations=(), parking=(),
                                 access_points=(), num_skus=0, name=instance.name)

    @property
    def num_agents(self) -> int:
        return self.config.num_agents

    @property
    def obs_shape(self) -> tuple[int, int, int]:
        w = 2 * self.config.fov_radius + 1
        return (NUM_CHANNELS + int(self.rotations), w, w)

    @property
    def num_actions(self) -> int:
        """5 (wait, up, down, left, right), or 4 with rotations (wait, forward, left,
        right)."""
        return NUM_ROT_ACTIONS if self.rotations else NUM_ACTIONS

    # ------------------------------------------------------------------------ episode

    def reset(self, rng: np.random.Generator) -> np.ndarray:
        """Start an episode (starts and goals drawn from ``rng`` unless fixed); returns the
        observations ``(N, 4, W, W)``."""
        self._rng = rng
        n = self.num_agents
        inst = self.instance
        if inst.starts is not None:
            self.pos[:] = [r * self.cols + c for r, c in inst.starts]
            self.goal[:] = [r * self.cols + c for r, c in inst.goals]
        else:
            self.pos[:] = rng.choice(self.sample_nodes, size=n, replace=False)
            self.goal[:] = rng.choice(self.sample_nodes, size=n, replace=False)
        if self.rotations and self.executor_spec is None:
            self.heading = rng.integers(4, size=n).astype(np.int64)
        elif self.rotations:  # the executor places every body facing east
            self.heading = np.zeros(n, dtype=np.int64)
        self.turn_to = self.heading.copy()
        for i in range(n):
            self.dist[i, :-1] = self.graph.dist_to(self.graph.cell(int(self.goal[i])))
        if (self.dist[np.arange(n), self.pos] >= UNREACHABLE).any():
            raise ValueError(f"instance {inst.name!r}: a goal cannot be reached from its start")
        self.t = 0
        self.dest = self.pos if self.executor_spec is None else self.pos.copy()
        if self.executor_spec is not None:
            self._bind(np.random.default_rng(int(rng.integers(2**62))))
        return self.observe()

    def _bind(self, rng: np.random.Generator) -> None:
        """Build and bind a fresh executor for the episode (every agent standing)."""
        from ..executors.base import AgvBody, ExecutorSetup
        from ..planning.paths import TimedPath
        from ..registry import build

        spec = self.config.agv_type or default_agv()
        self.executor = build("executor", self.executor_spec)
        self.executor.bind(ExecutorSetup(
            layout=self.layout, tick_s=TICK_S, rng=rng,
            agvs=tuple(AgvBody(i, 1, spec, (int(v), int(v))) for i, v in enumerate(self.pos))))
        self._plans = {i: TimedPath(i, 0, ((int(v), int(v)),)) for i, v in enumerate(self.pos)}
        self.report = None
        self.collisions = 0

    def observe(self) -> np.ndarray:
        obs = observe(self.obs_grid, self.pos, self.goal, self.dist)
        if not self.rotations:
            return obs
        n, _, w, _ = obs.shape
        ahead = np.zeros((n, 1, w, w), dtype=np.float32)
        r = self.config.fov_radius
        ahead[np.arange(n), 0, r + HEADING_STEP[self.heading, 0],
              r + HEADING_STEP[self.heading, 1]] = 1.0
        return np.concatenate([obs, ahead], axis=1)

    def on_goal(self) -> np.ndarray:
        """Agents standing on their goals."""
        if self.dest is self.pos:
            return self.pos == self.goal
        return (self.pos == self.goal) & (self.dest == self.pos)

    def in_transit(self) -> np.ndarray:
        """Agents moving between two cells (only on a real executor)."""
        if self.dest is self.pos:
            return np.zeros(self.num_agents, dtype=bool)
        return self.dest != self.pos

    def turning(self) -> np.ndarray:
        """Agents turning in place (rotations on a real executor only)."""
        if not self.rotations or self.executor_spec is None:
            return np.zeros(self.num_agents, dtype=bool)
        return self.turn_to != self.heading

    def busy(self) -> np.ndarray:
        """Agents whose actions count as wait: in transit or turning."""
        return self.in_transit() | self.turning()

    def states(self) -> dict[int, tuple[int, int]]:
        """Every agent's discrete state ``(pos, dest)``: standing at ``a`` is ``(a, a)``."""
        return {i: (int(a), int(b)) for i, (a, b) in enumerate(zip(self.pos, self.dest,
                                                                     strict=True))}

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool, bool]:
        """Apply one action per agent: ``(obs, rewards, blocked, terminated, truncated)``."""
        cfg = self.config
        actions = np.asarray(actions, dtype=np.int64)
        k = self.num_actions
        if actions.shape != (self.num_agents,) or actions.min(initial=0) < 0 \
                or actions.max(initial=0) >= k:
            raise ValueError(f"expected {self.num_agents} actions in 0..{k - 1}, "
                             f"got {actions!r}")
        was_on = self.on_goal()
        if self.rotations and self.executor is not None:
            actions = np.where(self.busy(), 0, actions)  # in transit or turning: waits
            before = self.pos
            moves = np.where(actions == 1, HEADING_MOVE[self.heading], 0)
            turn_to = np.where(actions >= 2, (self.heading + TURN[actions]) % 4,
                               self.turn_to)
            self._execute(self._resolve(moves), turn_to)
            blocked = (actions == 1) & (self.pos == before) & (self.dest == before)
        elif self.rotations:
            moves = np.where(actions == 1, HEADING_MOVE[self.heading], 0)
            target = self._resolve(moves)
            blocked = (actions == 1) & (target == self.pos)
            self.pos = self.dest = target
            self.heading = (self.heading + TURN[actions]) % 4
        elif self.executor is None:
            target = self._resolve(actions)
            blocked = (actions != 0) & (target == self.pos)
            self.pos = self.dest = target
        else:
            actions = np.where(self.in_transit(), 0, actions)  # in transit: waits
            before = self.pos
            self._execute(self._resolve(actions))
            blocked = (actions != 0) & (self.pos == before) & (self.dest == before)
        self.t += 1
        now_on = self.on_goal()
        rewards = (cfg.goal_reward * (now_on & ~was_on) - cfg.goal_reward * (was_on & ~now_on)
                   + cfg.step_penalty * ~now_on + cfg.blocked_penalty * blocked)
        if cfg.lifelong and now_on.any():
            self._new_goals(np.flatnonzero(now_on))
        terminated = (not cfg.lifelong) and bool(self.on_goal().all())
        truncated = not terminated and self.t >= cfg.max_steps
        return self.observe(), rewards.astype(np.float32), blocked, terminated, truncated

    def _new_goals(self, agents: np.ndarray) -> None:
        for i in agents:
            g = int(self.pos[i])
            while g == self.pos[i]:
                g = int(self._rng.choice(self.sample_nodes))
            self.goal[i] = g
            self.dist[i, :-1] = self.graph.dist_to(self.graph.cell(g))

    def _resolve(self, actions: np.ndarray) -> np.ndarray:
        """Next positions: moves off the grid, onto obstacles or into conflicts cancelled."""
        r, c = np.divmod(self.pos, self.cols)
        nr, nc = r + ACTIONS[actions, 0], c + ACTIONS[actions, 1]
        inside = (nr >= 0) & (nr < self.rows) & (nc >= 0) & (nc < self.cols)
        ok = inside & self.free[np.clip(nr, 0, self.rows - 1), np.clip(nc, 0, self.cols - 1)]
        target = np.where(ok, nr * self.cols + nc, self.pos)
        owner = np.full(self.rows * self.cols, -1, dtype=np.int64)
        idx = np.arange(len(target))
        owner[self.pos] = idx
        real = self.executor is not None
        if real:  # agents in transit keep their move; nobody else may enter its cell
            fixed = self.in_transit()
            target = np.where(fixed, self.dest, target)
        while True:
            moving = target != self.pos
            count = np.bincount(target, minlength=self.rows * self.cols)
            bad = moving & (count[target] > 1)
            j = owner[target]
            bad |= moving & (j >= 0) & (target[np.maximum(j, 0)] == self.pos)
            if real:
                bad &= ~fixed
                if not bad.any():
                    bad = self._rotations(target, owner, moving & ~fixed)
            if not bad.any():
                return target
            target = np.where(bad, self.pos, target)

    def _rotations(self, target: np.ndarray, owner: np.ndarray,
                   moving: np.ndarray) -> np.ndarray:
        """Moving agents on a cycle of moves (each enters the cell the next one leaves)."""
        n = len(target)
        succ = owner[target]  # the agent standing on the cell each agent enters
        follows = moving & (succ >= 0)
        follows &= moving[np.where(follows, succ, 0)]
        far = np.append(np.where(follows, succ, n), n)  # no moving successor: a sink
        for _ in range(max(1, int(n).bit_length())):  # far = next^(2^k), 2^k > n
            far = far[far]
        on = np.zeros(n + 1, dtype=bool)
        on[far] = True  # what n steps reach: only cycle members (and the sink)
        return on[:-1] & moving

    def _execute(self, target: np.ndarray, turn_to: np.ndarray | None = None) -> None:
        """Hand the intended next cells to the executor as one-move plans (with rotations:
        plans with headings, a turn being a plan that stands on its cell and changes its
        heading); take every agent's state (and heading) from its report."""
        from ..executors.base import TickView
        from ..planning.paths import TimedPath

        n, t = self.num_agents, self.t
        plans = self._plans
        idle = (self.dest == self.pos) if turn_to is None else ~self.busy()
        for i in np.flatnonzero(idle):  # in transit or turning: keeps its plan
            cur, nxt = int(self.pos[i]), int(target[i])
            heads = None
            if turn_to is not None:
                h0 = int(self.heading[i])
                heads = (h0, int(turn_to[i]) if nxt == cur else h0)
            plans[int(i)] = TimedPath(int(i), t, ((cur, cur), (nxt, nxt)), heads)
        # Plans are committed afresh every step: nobody is behind them.
        view = TickView(tick=t, plans=MappingProxyType(dict(plans)), behind=(0,) * n,
                        failed=frozenset(), loaded=(False,) * n, carried=(None,) * n,
                        task_state=(0,) * n)
        report = self.executor.step(view)
        pos, dest = self.pos.copy(), self.dest.copy()
        for i, (a, b) in report.states.items():
            pos[i], dest[i] = a, b
        self.pos, self.dest = pos, dest
        self.collisions += int(report.collisions)
        self.report = report
        if turn_to is not None:
            self.turn_to = turn_to
            self.heading = self._reported_headings(report)

    def _reported_headings(self, report: StepReport) -> np.ndarray:
        """Rotations on a real executor: each agent's heading from the body angle of the
        report. A turning agent keeps its heading until its body faces the one it turns to
        (within :data:`ALIGN_RAD`); its turn takes as long as the executor's motion
        model says. An executor without poses (no bodies) turns in one step."""
        if report.poses is None:  # no bodies (the grid executor): a turn takes one step
            return self.turn_to.copy()
        ang = report.poses[:, 2]
        want = self.turn_to * (np.pi / 2)
        done = np.abs((ang - want + np.pi) % (2 * np.pi) - np.pi) < ALIGN_RAD
        return np.where(done, self.turn_to, self.heading)

    def paths(self) -> list[tuple[int, int]]:
        """Current (row, col) of every agent."""
        return [divmod(int(v), self.cols) for v in self.pos]
