"""The plan on an executor, exactly as written (:func:`execute_plan`)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from ..config import AgvTypeSpec, DelaySpec
from ..executors.base import AgvBody, ExecutorSetup, StepReport, TickView, record_report
from ..layout import Layout
from ..planning.paths import State, TimedPath
from ..plans.model import Plan
from .options import executor_spec
from .repair import Repair


def plan_to_paths(plan: Plan, cols: int) -> dict[int, TimedPath]:
    """Timed paths (one standing state per timestep) of every agent, from tick 0."""
    return {i: TimedPath(i, 0, tuple((r * cols + c, r * cols + c) for r, c in path))
            for i, path in enumerate(plan.paths)}


@dataclass
class ExecutionResult:
    metrics: dict[str, Any]
    executed: dict[int, list[State]]
    """Executed state per tick per agent, from tick 0."""
    planned_finish: list[int]
    executed_finish: list[int]
    events: list[dict] = field(default_factory=list)
    trajectory: dict | None = None
    repairs: list[Repair] = field(default_factory=list)


def execute_plan(plan: Plan, layout: Layout, types: list[AgvTypeSpec], *,
                 executor: str = "physics", seed: int = 0, delays: DelaySpec | None = None,
                 tick_s: float = 1.0, dt_s: float = 0.02, trajectory_hz: float = 10.0,
                 max_ticks: int | None = None, executor_params: dict | None = None,
                 repairs: list[Repair] | None = None, given: Plan | None = None,
                 progress: Callable[[int, int], None] | None = None,
                 options: dict[str, Any] | None = None) -> ExecutionResult:
    """Execute ``plan`` (validated, cycle-free) on ``executor`` and measure it. ``given``:
    the plan as it was given, before :func:`repair_cycles` made ``plan`` of it; the
    planned figures are then the given plan's, and the repaired plan's are reported
    beside them. ``options``: other fields of the executor section
    (:class:`~warerover_phys.config.ExecutorSpec`: ``no_slip``, ``payload``,
    ``comm_latency_s``, ``shelf_contacts``, ``park``, ``speed_scale``, ``adg`` ...), checked
    by its schema (see :func:`executor_options`)."""
    from ..registry import build

    spec = executor_spec(executor, dt_s=dt_s, delays=delays, trajectory_hz=trajectory_hz,
                         params=executor_params, options=options)
    ex = build("executor", spec)
    n = plan.num_agents
    cols = layout.cols
    paths = plan_to_paths(plan, cols)
    rngs = np.random.SeedSequence(seed).spawn(5)  # same streams as an episode's make_rngs
    rng = np.random.default_rng(rngs[4])
    ex.bind(ExecutorSetup(layout=layout, tick_s=tick_s, rng=rng, agvs=tuple(
        AgvBody(i, t.footprint, t, paths[i].states[0]) for i, t in enumerate(types))))
    planned_finish = list((given or plan).costs)
    horizon = plan.makespan
    limit = max_ticks if max_ticks is not None else max(50, 10 * horizon + 100)
    final = {i: p.states[-1] for i, p in paths.items()}
    tick, executed, events, counts, wall = _follow(ex, paths, n, horizon, limit, final,
                                                   progress)
    done = all(executed[i][-1] == final[i] for i in range(n)) and \
        not any(ex.remaining(i) for i in range(n))
    executed_finish = []
    for i in range(n):
        states = executed[i]
        t = len(states) - 1
        while t > 0 and states[t - 1] == final[i]:
            t -= 1
        executed_finish.append(t)
    summary = ex.summary()
    planned_soc, exec_soc = sum(planned_finish), sum(executed_finish)
    planned_ms, exec_ms = max(planned_finish, default=0), max(executed_finish, default=0)
    lost = np.asarray(executed_finish) - np.asarray(planned_finish)
    metrics: dict[str, Any] = {
        "mode": "open-loop (fixed plan)",
        "executor": executor, "agents": n, "seed": seed, "tick_s": tick_s,
        "completed": done, "ticks": tick,
        "planned_makespan_ticks": planned_ms, "executed_makespan_ticks": exec_ms,
        "makespan_ratio": exec_ms / planned_ms if planned_ms else 1.0,
        "planned_sum_of_costs_ticks": planned_soc, "executed_sum_of_costs_ticks": exec_soc,
        "sum_of_costs_ratio": exec_soc / planned_soc if planned_soc else 1.0,
        "lost_ticks_per_agent_mean": float(lost.mean()) if n else 0.0,
        "lost_ticks_per_agent_max": int(lost.max()) if n else 0,
        **counts,
        "cycle_repairs": len(repairs or []),
        "cycle_repair_moves": sum(r.moves for r in repairs or []),
        "repaired_makespan_ticks": plan.makespan,
        "repaired_sum_of_costs_ticks": sum(plan.costs),
        "cycle_repair_added_ticks": sum(plan.costs) - planned_soc,
        "execute_wall_s": wall,
        "real_time_factor": tick * tick_s / wall if wall > 0 else math.inf,
        **summary,
    }
    if "real_time_factor" in summary:
        metrics["real_time_factor"] = summary["real_time_factor"]
    trajectory = ex.trajectory()
    return ExecutionResult(metrics=metrics, executed=executed, planned_finish=planned_finish,
                           executed_finish=executed_finish, events=events,
                           trajectory=trajectory, repairs=list(repairs or []))


def _follow(ex, paths: dict[int, TimedPath], n: int, horizon: int, limit: int,
            final: dict[int, State], progress: Callable[[int, int], None] | None):
    """Step the bound executor along the fixed ``paths`` until every agent stands at its
    final state with nothing left (from the plan's makespan on) or ``limit`` ticks: the
    ticks run, the executed states, the events, the counts and the wall time."""
    from ..util.gc_tuning import long_loop

    plans = MappingProxyType(paths)
    behind = [0] * n
    executed = {i: [paths[i].states[0]] for i in range(n)}
    events: list[dict] = []
    counts = {"blocked_moves": 0, "collisions": 0, "executor_replan_requests": 0}
    zeros = tuple([0] * n)
    wall0 = time.perf_counter()
    tick = 0
    with long_loop():  # (see gc_tuning)
        while tick < limit:
            view = TickView(tick=tick, plans=plans, behind=tuple(behind), failed=frozenset(),
                            loaded=(False,) * n, carried=(None,) * n, task_state=zeros)
            report: StepReport = ex.step(view)
            record_report(report, tick, executed, behind, events)
            counts["blocked_moves"] += len(report.blocked)
            counts["collisions"] += report.collisions
            counts["executor_replan_requests"] += len(report.replan)
            tick += 1
            if progress is not None:
                progress(tick, horizon)
            if tick >= horizon and all(executed[i][-1] == final[i] for i in range(n)) and \
                    not any(ex.remaining(i) for i in range(n)):
                break
    wall = time.perf_counter() - wall0
    return tick, executed, events, counts, wall
