"""Duration-aware timing of a grid plan: a MAPF-POST-like schedule over the action dependency
graph (``planner.timing: motion``, issue 15).

A grid plan says *in which order* AGVs use cells; :func:`schedule` says *when* a robot with
the :class:`~warerover_phys.planning.motion.MotionModel` of its type can do each move. It is
a pure function of the plan (timed paths, optional dwells and cargo), the fleet (one
``AgvTypeSpec`` per AGV) and the floor (``cols``, ``rows``, ``cell_m``), and it times the
plan the way the physics executor drives it (:mod:`warerover_phys.executors.follow`):

- **Actions and dependencies** are those of the executor's
  :class:`~warerover_phys.executors.adg.ActionGraph` (plan waits dropped; one action per cell
  move; per cell a queue of visits in planned order, turn sweeps and turn locks included).
  An action may start only once, for every cell (or lock) it enters, the previous visitor's
  leaving action has *finished* (the ADG's type-2 edges); an AGV's actions run in order.
- **Runs.** Consecutive moves in one direction with no dwell between them form a run, driven
  from rest to rest as one trapezoid (:meth:`MotionModel.reach_s`): move ``m`` of a run of
  ``K`` starting at ``S`` lasts from ``S + reach_s(m, K)`` to ``S + reach_s(m + 1, K)``. If a
  move's dependencies are not met when the AGV would enter it (its start inside the run), the
  run is *split* there: the AGV stops at the cell before and starts a new run when they are.
  Where to split depends on the other AGVs' runs, so the earliest-time pass is repeated,
  each deciding the runs' lengths from the ready times of the pass before, until no move is
  entered before it is ready (a handful of passes on the paper scenarios). Ready times
  mostly grow from pass to pass, but not always (a run split earlier may pass a later cell
  at speed, sooner than a robot that stopped there), so after ``max_passes`` passes the
  search falls back to adding a split wherever a move is late, which only delays and ends.
- **Turns** (differential drive): before a move in a direction other than the AGV's heading
  (AGVs start facing east, as the physics executor places them) it turns in place for
  :meth:`MotionModel.turn_s`. As in the executor the turn starts when the AGV arrives, during
  its dwell and while it waits for its dependencies, except a turn that sweeps other cells
  (:attr:`Action.sweeps`), which starts only once those are its own.
- **Dwells** (picks, hand-overs, places, parking: ``dwells`` per AGV as ``(tick, ticks)``, as
  ``TickView.dwells``) hold the AGV ``ticks x tick_s`` seconds from its arrival before the
  first move that starts at or after ``tick``; a dwell after the last move ends the AGV's
  plan.

So a run's first move starts at ``max(arrival + turn, arrival + dwell, ready)`` (``ready``:
the latest finish among its dependencies), and the schedule is the earliest one that keeps
every dependency: what a perfect robot with the model's limits needs for this plan. Top
speeds are the types' own (the executor's random ``speed_scale`` is left out), acceleration
the loaded limit while the plan says the AGV carries a shelf when ``payload`` is set, and a
communication latency (``comm_latency_s``) delays every dependency on another AGV.

>>> from warerover_phys.config import AgvTypeSpec
>>> from warerover_phys.planning.base import TimedPath
>>> # One AGV, four cells east in a 1 x 5 corridor: one run of 4 cells, no turn.
>>> s = schedule({0: TimedPath(0, 0, tuple((c, c) for c in range(5)))}, [AgvTypeSpec()],
...              cols=5, rows=1)
>>> round(s.makespan_s, 4), s.makespan_unit_s, len(s.actions[0])
(4.1667, 4.0, 4)
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..executors.adg import ActionGraph
from .motion import MotionModel, quarter_turns
from .sweep import agv_sweeps

if TYPE_CHECKING:
    from ..config import AgvTypeSpec
    from .base import TimedPath

__all__ = ["TimedAction", "Schedule", "schedule", "schedule_plan", "SCHEDULE_FORMAT"]

SCHEDULE_FORMAT = "warerover-schedule/1"
"""``format`` of :meth:`Schedule.to_json` (``schedule.json``)."""
_EPS = 1e-9
_EAST = (0, 1)
_HEADING = {(0, 1): 0, (1, 0): 1, (0, -1): 2, (-1, 0): 3}


@dataclass(frozen=True)
class TimedAction:
    """One move of the schedule (seconds from the plan's start)."""

    agv: int
    seq: int
    src: int
    dst: int
    direction: tuple[int, int]
    tick: int
    """Planned start tick of the unit plan (the last tick it stands at ``src``)."""
    ticks: int
    """Planned duration in the unit plan (ticks)."""
    run: int
    """Index of the run (straight drive from rest to rest) it belongs to, per AGV."""
    turn_s: float
    """Turn in place before it (0: none)."""
    dwell_s: float
    """Dwell before it, from the arrival at ``src``."""
    ready_s: float
    """When its last dependency on another AGV finishes (0: none)."""
    start_s: float
    finish_s: float


@dataclass(frozen=True)
class Schedule:
    """Planned start and finish of every action, per AGV (see the module docstring)."""

    actions: Mapping[int, tuple[TimedAction, ...]]
    finish_s: Mapping[int, float]
    """Per AGV: its last move's finish plus a trailing dwell (0 for an AGV that never
    moves and has no dwell)."""
    finish_unit_s: Mapping[int, float]
    """Per AGV: the same in the unit plan (ticks x ``tick_s``)."""
    tick_s: float
    cell_m: float
    models: Mapping[int, MotionModel]
    """Per AGV its (unloaded) motion model."""
    dependencies: int
    """Cross-AGV dependency edges kept."""
    splits: int
    """Runs split because a dependency was not met in time."""
    passes: int
    """Earliest-time passes until no split was needed."""

    @property
    def makespan_s(self) -> float:
        return max(self.finish_s.values(), default=0.0)

    @property
    def sum_of_costs_s(self) -> float:
        return float(sum(self.finish_s.values()))

    @property
    def makespan_unit_s(self) -> float:
        return max(self.finish_unit_s.values(), default=0.0)

    @property
    def sum_of_costs_unit_s(self) -> float:
        return float(sum(self.finish_unit_s.values()))

    def start_s(self, agv: int) -> float:
        """When AGV ``agv`` starts its first move (or turn); 0 without moves."""
        acts = self.actions.get(agv, ())
        return acts[0].start_s - acts[0].turn_s if acts else 0.0

    def poses(self, cols: int, starts: Mapping[int, int]) -> dict[int, list[tuple]]:
        """Per AGV its planned poses as ``((row, col), heading, t_s)`` (heading 0 east, 1
        south, 2 west, 3 north; AGVs start facing east, as the physics executor places
        them): where each turn starts and ends and where each move starts and ends, so that
        straight lines between them trace the planned motion's path in space (within a run
        the schedule's speed profile is a trapezoid, not the constant speed of the lines
        between cell centres). ``starts``: every AGV's first cell (linear), also for AGVs
        that never move (they stand there until the makespan). For
        :func:`warerover_phys.spacetime.from_schedule`."""
        end = self.makespan_s
        out: dict[int, list[tuple]] = {}
        for i, cell in starts.items():
            h = 0
            here = divmod(cell, cols)
            poses: list[tuple] = [(here, h, 0.0)]

            def add(pose: tuple, t: float, poses: list[tuple] = poses) -> None:
                last = poses[-1]
                if t <= last[2] + 1e-9:
                    if pose == last[:2]:
                        return  # standing: nothing new
                    t = last[2] + 1e-6  # an instant change (none expected): keep time strict
                poses.append((*pose, t))

            omni = i in self.models and self.models[i].omni
            for a in self.actions.get(i, ()):
                h_new = h if omni else _HEADING[a.direction]  # omni bodies never turn
                if a.turn_s > 0 or h_new != h:
                    add((here, h), a.start_s - a.turn_s)
                    add((here, h_new), a.start_s)
                else:
                    add((here, h), a.start_s)
                h, here = h_new, divmod(a.dst, cols)
                add((here, h), a.finish_s)
            add((here, h), end)
            if len(poses) == 1:
                poses.append((here, h, max(end, 1e-6)))
            out[i] = poses
        return out

    def to_json(self, cols: int, source: str | None = None) -> dict[str, Any]:
        """The schedule as plain data (``schedule.json``; cells as ``[row, col]``)."""
        agvs = []
        for i in sorted(self.actions):
            m = self.models[i]
            agvs.append({
                "agv": i, "footprint": m.footprint, "omni": m.omni,
                "max_speed_mps": m.max_speed_mps, "max_accel_mps2": m.max_accel_mps2,
                "max_turn_rate_radps": m.max_turn_rate_radps,
                "start_s": self.start_s(i), "finish_s": self.finish_s[i],
                "finish_unit_s": self.finish_unit_s[i],
                "actions": [{"seq": a.seq, "src": list(divmod(a.src, cols)),
                             "dst": list(divmod(a.dst, cols)), "tick": a.tick,
                             "ticks": a.ticks, "run": a.run, "turn_s": a.turn_s,
                             "dwell_s": a.dwell_s, "ready_s": a.ready_s,
                             "start_s": a.start_s, "finish_s": a.finish_s}
                            for a in self.actions[i]]})
        return {"format": SCHEDULE_FORMAT, "timing": "motion", "source": source,
                "tick_s": self.tick_s, "cell_m": self.cell_m,
                "makespan_s": self.makespan_s, "sum_of_costs_s": self.sum_of_costs_s,
                "makespan_unit_s": self.makespan_unit_s,
                "sum_of_costs_unit_s": self.sum_of_costs_unit_s,
                "dependencies": self.dependencies, "splits": self.splits,
                "passes": self.passes, "agvs": agvs}


def _holds(acts: Sequence, dwells: Sequence[tuple[int, int]]) -> tuple[dict[int, int], int]:
    """Dwell ticks before each action (by index) and after the last one, as the physics
    executor maps them (``PlanFollower._set_holds``: the first action that starts at or
    after the dwell's tick)."""
    holds: dict[int, int] = {}
    trailing = 0
    j = 0
    for tick, ticks in sorted(dwells):
        while j < len(acts) and acts[j].tick < tick:
            j += 1
        if j == len(acts):
            trailing += int(ticks)
        else:
            holds[j] = holds.get(j, 0) + int(ticks)
    return holds, trailing


def schedule(paths: Mapping[int, TimedPath], fleet: Sequence[AgvTypeSpec], *, cols: int,
             rows: int, cell_m: float = 1.0, tick_s: float = 1.0,
             dwells: Mapping[int, Sequence[tuple[int, int]]] | None = None,
             loaded: np.ndarray | None = None, payload: bool = False,
             comm_latency_s: float = 0.0,
             downtime: Mapping[int, Sequence[tuple[float, float]]] | None = None,
             max_passes: int = 200) -> Schedule:
    """The motion-timed schedule of a plan (see the module docstring).

    ``paths``: every AGV's timed path (all from the same tick, starting and ending standing);
    ``fleet[i]``: AGV ``i``'s type; ``cols`` / ``rows`` / ``cell_m``: the floor;
    ``tick_s``: seconds per plan tick (dwells and the unit figures); ``dwells``: per AGV
    ``(tick, ticks)`` of its work in place; ``loaded`` (T + 1, N): whether each AGV carries
    a shelf at each tick (with ``payload``: the loaded acceleration limit applies to moves
    that start loaded); ``comm_latency_s`` (``executor.comm_latency_s``): an AGV hears this
    long after another AGV's action finished that its cells are free; ``downtime``: per AGV
    the ``(from_s, to_s)`` windows it is down (failures replayed, as the open-loop gap
    does): no run or turn starts inside one; in a run it falls into the AGV brakes at its
    limit where it is, and drives the rest from rest once it is up again. Raises
    ``ADGCycleError`` if the plan has no execution order.
    """
    agvs = sorted(paths)
    sizes = {i: int(fleet[i].footprint) for i in agvs}
    swept = agv_sweeps([fleet[i] for i in agvs], cell_m)  # keyed by position in agvs
    graph = ActionGraph(cols, sizes, sweeps={agvs[p]: sw for p, sw in swept.items()},
                        rows=rows)
    for i in agvs:
        graph.set_plan(i, paths[i])
    graph.check_acyclic()
    dwells = dwells or {}
    acts = {i: graph.upcoming(i) for i in agvs}
    models, model, dwell_s, turn_s, joins, trailing = _action_params(
        agvs, acts, fleet, dwells, cell_m, tick_s, loaded, payload)
    index = {(i, a.seq): n for i in agvs for n, a in enumerate(acts[i])}
    deps, n_deps = _dependencies(agvs, acts, paths, graph, sizes, cols, index, model)
    order = _topological(acts, deps)
    down = {i: sorted((float(a), float(b)) for a, b in w if b > a)
            for i, w in (downtime or {}).items() if w}
    sweeps = {(i, n): bool(a.sweeps) for i in agvs for n, a in enumerate(acts[i])}
    # Where a run must stop depends on when the other AGVs free its cells, which depends
    # on where their runs stop. Each pass decides every run's length from the ready times
    # the pass before found (a run stops before its first move that would be entered before
    # it is ready) and computes the earliest times in dependency order; the first pass in
    # which no move is entered before it is ready is the schedule.
    passes = 0
    predict: dict[tuple[int, int], float] = {}
    forced: set[tuple[int, int]] = set()
    while True:
        passes += 1
        times, ready, runs, late, splits = _pass(order, acts, deps, model, dwell_s, turn_s,
                                                 joins, sweeps, predict, forced,
                                                 comm_latency_s, down)
        if not late:
            break
        if passes < max_passes:
            predict = ready
        else:  # not settled: split wherever a move is late (only adds splits, so it ends)
            forced |= splits | set(late)
            predict = {}
    out: dict[int, tuple[TimedAction, ...]] = {}
    finish: dict[int, float] = {}
    finish_unit: dict[int, float] = {}
    for i in agvs:
        row = []
        for n, a in enumerate(acts[i]):
            s, f = times[(i, n)]
            row.append(TimedAction(a.agv, a.seq, a.src, a.dst, a.direction, a.tick, a.ticks,
                                   runs[(i, n)], turn_s[(i, n)], dwell_s[(i, n)],
                                   ready[(i, n)], s, f))
        out[i] = tuple(row)
        end = row[-1].finish_s if row else 0.0
        finish[i] = end + trailing[i] * tick_s
        unit_end = (acts[i][-1].tick + acts[i][-1].ticks) if acts[i] else 0
        finish_unit[i] = (unit_end + trailing[i]) * tick_s
    return Schedule(actions=out, finish_s=finish, finish_unit_s=finish_unit, tick_s=tick_s,
                    cell_m=cell_m, models=models, dependencies=n_deps, splits=len(splits),
                    passes=passes)


def _action_params(agvs: list[int], acts: dict, fleet: Sequence[AgvTypeSpec],
                   dwells: Mapping[int, Sequence[tuple[int, int]]], cell_m: float,
                   tick_s: float, loaded: np.ndarray | None, payload: bool):
    """For :func:`schedule`: each AGV's motion model (empty, and loaded with ``payload``),
    and per action ``(agv, n)`` its model, dwell and turn (seconds) and whether a run may
    continue into it; each AGV's trailing dwell (ticks)."""
    models = {i: MotionModel.of(fleet[i], cell_m) for i in agvs}
    models_loaded = {i: MotionModel.of(fleet[i], cell_m, loaded=True, payload=True)
                     for i in agvs} if payload else models
    model: dict[tuple[int, int], MotionModel] = {}
    dwell_s: dict[tuple[int, int], float] = {}
    turn_s: dict[tuple[int, int], float] = {}
    joins: dict[tuple[int, int], bool] = {}
    trailing: dict[int, int] = {}
    for i in agvs:
        holds, trailing[i] = _holds(acts[i], dwells.get(i, ()))
        heading = _EAST
        for n, a in enumerate(acts[i]):
            key = (i, n)
            carrying = loaded is not None and payload and 0 <= a.tick < loaded.shape[0] \
                and bool(loaded[a.tick, i])
            model[key] = models_loaded[i] if carrying else models[i]
            dwell_s[key] = holds.get(n, 0) * tick_s
            turn_s[key] = model[key].turn_s(quarter_turns(heading, a.direction))
            joins[key] = n > 0 and a.direction == heading and n not in holds \
                and model[key] == model[(i, n - 1)]
            heading = a.direction
    return models, model, dwell_s, turn_s, joins, trailing


def _dependencies(agvs: list[int], acts: dict, paths: Mapping[int, TimedPath], graph,
                  sizes: dict[int, int], cols: int, index: dict, model: dict):
    """For :func:`schedule`: the cross-AGV dependencies, per queue (cell or sweep key) the
    previous visitor's leaving action before the next one's entering action, and their
    count."""
    deps: dict[tuple[int, int], list[tuple[int, int]]] = {k: [] for k in model}
    keys: set[int] = set()
    for i in agvs:
        keys.update(_footprint(paths[i].states[0][0], sizes[i], cols))
        for a in acts[i]:
            keys.update(a.enters)
            keys.update(a.sweeps)
    n_deps = 0
    for key in keys:
        q = graph.visits(key)
        for prev, nxt in zip(q, q[1:], strict=False):
            if nxt.enter is None or prev.agv == nxt.agv or prev.leave is None:
                continue
            deps[(nxt.agv, index[(nxt.agv, nxt.enter)])].append(
                (prev.agv, index[(prev.agv, prev.leave)]))
            n_deps += 1
    return deps, n_deps


def _footprint(node: int, k: int, cols: int) -> tuple[int, ...]:
    r, c = divmod(node, cols)
    return tuple((r + dr) * cols + c + dc for dr in range(k) for dc in range(k))


def _topological(acts: Mapping[int, list], deps: Mapping[tuple[int, int], list]
                 ) -> list[tuple[int, int]]:
    """Actions in an order that puts every action after its own previous one and after its
    dependencies (Kahn; the graph is acyclic: ``check_acyclic`` ran)."""
    succ: dict[tuple[int, int], list[tuple[int, int]]] = {k: [] for k in deps}
    indeg = dict.fromkeys(deps, 0)
    for i, row in acts.items():
        for n in range(1, len(row)):
            succ[(i, n - 1)].append((i, n))
            indeg[(i, n)] += 1
    for k, ds in deps.items():
        for d in ds:
            succ[d].append(k)
            indeg[k] += 1
    todo = sorted((k for k, d in indeg.items() if d == 0), reverse=True)
    out = []
    while todo:
        k = todo.pop()
        out.append(k)
        for s in succ[k]:
            indeg[s] -= 1
            if indeg[s] == 0:
                todo.append(s)
    if len(out) != len(indeg):  # pragma: no cover - check_acyclic ran first
        raise ValueError("the dependency graph has a cycle")
    return out


def _pass(order, acts, deps, model, dwell_s, turn_s, joins, sweeps, predict, forced,
          latency=0.0, down=None):
    """One earliest-time pass (see :func:`schedule`). ``predict``: per action the ready time
    its run's length is decided with (missing: 0); ``forced``: actions that start a run
    whatever ``predict`` says. Returns start/finish per action, ready times, run index per
    action, the moves entered before they were ready (at most one per run) and the moves
    that start a run although they could have continued the one before (the splits).
    ``down``: per AGV its sorted downtime windows (seconds)."""
    down = down or {}
    times: dict[tuple[int, int], tuple[float, float]] = {}
    ready: dict[tuple[int, int], float] = {}
    runs: dict[tuple[int, int], int] = {}
    late: list[tuple[int, int]] = []
    splits: set[tuple[int, int]] = set()
    # Per AGV: run start index, run length, run start time, run index, flagged late.
    seg: dict[int, list] = {}
    for key in order:
        i, n = key
        r = max((times[d][1] + latency for d in deps[key]), default=0.0)
        ready[key] = r
        m = model[key]
        cur = seg.get(i)
        if cur is not None and n < cur[0] + cur[1]:  # inside the AGV's current run
            first, length, t0, run, flagged, pause = cur
            pos = n - first
            d = length * m.cell_m
            start = _run_time(t0, pos * m.cell_m, d, m, pause)
            if r > start + _EPS and not flagged:
                late.append(key)
                cur[4] = True
            times[key] = (start, _run_time(t0, (pos + 1) * m.cell_m, d, m, pause))
            runs[key] = run
            continue
        if n > 0 and joins[key]:
            splits.add(key)
        arrive = times[(i, n - 1)][1] if n else 0.0
        if sweeps[key]:
            go = max(max(arrive, r) + turn_s[key], arrive + dwell_s[key])
        else:
            go = max(arrive + turn_s[key], arrive + dwell_s[key], r)
        row = acts[i]
        length = 1
        while n + length < len(row) and joins[(i, n + length)] \
                and (i, n + length) not in forced:
            length += 1
        if predict:
            # Stop before the first move that would be entered before it is ready; the
            # moves before it are reached later in the shorter run, so they stay ready.
            for j in range(1, length):
                if predict.get((i, n + j), 0.0) > go + m.reach_s(j, length) + _EPS:
                    length = j
                    break
        pause = None
        if i in down:
            go, pause = _downtime(go, arrive, turn_s[key], m, length, down[i])
        run = cur[3] + 1 if cur is not None else 0
        seg[i] = [n, length, go, run, False, pause]
        times[key] = (go, _run_time(go, m.cell_m, length * m.cell_m, m, pause))
        runs[key] = run
    return times, ready, runs, late, splits


def _downtime(go: float, arrive: float, turn: float, m: MotionModel, length: int,
              windows: list[tuple[float, float]]) -> tuple[float, tuple | None]:
    """A run of ``length`` cells that would start at ``go`` (the AGV arrived at ``arrive``
    and turns for ``turn`` before it), given the AGV's downtime ``windows``: its start moved
    past the windows it falls in (a turn that a window interrupts is done again after it),
    and the first window that opens while it drives as ``(at, until, x, v)``: ``at``
    seconds into the run it brakes at its limit from ``v`` m/s at ``x`` m, and drives the
    rest of the run from rest at ``until`` (seconds, absolute), as the executor does."""
    for a, b in windows:
        if turn > 0 and arrive <= a < arrive + turn and a < go:
            go = max(go, b + turn)
        elif a - _EPS <= go < b:
            go = b
    span = m.reach_s(length, length)
    for a, b in windows:
        if go < a < go + span:
            x, v = m.state_at(a - go, length * m.cell_m)
            return go, (a - go, b, x, v)
    return go, None


def _run_time(go: float, x: float, d: float, m: MotionModel, pause: tuple | None) -> float:
    """When a run of ``d`` metres started at ``go`` passes ``x`` metres, with the pause of
    :func:`_downtime` (None: none)."""
    if pause is None:
        return go + m.at_s(x, d)
    at, until, x0, v = pause
    if x <= x0 + _EPS:
        return go + m.at_s(x, d)
    acc = m.max_accel_mps2
    x_stop = x0 + v * v / (2 * acc)
    if x <= x_stop + _EPS:  # reached while braking
        disc = max(0.0, v * v - 2 * acc * (x - x0))
        return go + at + (v - math.sqrt(disc)) / acc
    # the rest from rest, once it is up again
    return until + m.at_s(x - x_stop, d - x_stop)


def schedule_plan(plan, *, payload: bool = False, comm_latency_s: float = 0.0) -> Schedule:
    """The schedule of a :class:`~warerover_phys.gap.ideal_plan.TimedPlan` (the open-loop gap's
    plan: paths, dwells, cargo); ``payload``, ``comm_latency_s``: the executor's settings."""
    lay = plan.layout
    down: dict[int, list[tuple[float, float]]] = {}
    for f in getattr(plan, "failures", ()):
        down.setdefault(f.agv, []).append((f.tick * plan.tick_s, (f.tick + f.ticks) * plan.tick_s))
    return schedule(plan.paths, plan.types, cols=lay.cols, rows=lay.rows, cell_m=lay.cell_m,
                    tick_s=plan.tick_s, dwells=dict(plan.dwell_view), loaded=plan.loaded,
                    payload=payload, comm_latency_s=comm_latency_s, downtime=down)
