"""The sim-to-real gap of a scenario and seed, in two modes.

**Open loop** (the default, ``mode="open"``): the plan of the ideal run (the closed loop on
the grid executor: scheduler + planner) is executed *unchanged* on physics: every AGV's timed
sequence of moves, waits and dwells (pick, hand-over, place, parking) over the whole
episode, with no scheduler, no planner and no replanning, through the action dependency
graph; a dwell takes at least its planned time (:mod:`.gap_plan`, :mod:`.gap_open`). Both
sides then run the same plan, so the ratio is the physics gap alone. A *rotation* of the
grid run (AGVs turning round a cycle in one tick, which the dependency graph cannot order)
is replaced by a local detour first (:func:`.gap_plan.repair_rotations`); the planned
figures stay the grid run's, the repaired plan's are beside them (``repaired_*``,
``cycle_repairs*``) and the ticks it added are the cause ``rotation_repair``. The grid
run's failures (``faults``) are replayed on physics: the same AGV goes down at the same tick
for the same number of ticks (it brakes and starts nothing), whatever it is doing then;
that time is the cause ``failures``. Corridors are not opened on the physics side (the
plan is fixed: nobody can be replanned around them). Figures (seconds of
simulated time; ratios are executed / planned):

- ``makespan_ratio`` (last AGV's finish), ``sum_of_costs_ratio`` (sum of the AGVs' finish
  times), per-AGV ``lost_s`` = executed finish - planned finish (negative: ahead of plan);
- ``orders_makespan_ratio`` (the last order's completion), ``tp_ratio`` (planned / executed
  time to complete the orders) and ``latency_ratio`` (mean order latency), so that the two
  modes can be set side by side;
- lost time split into causes (``lost_{part}_s_fleet_total`` over the fleet,
  ``lost_{part}_s_per_agv_mean`` per AGV; parts in :data:`.gap_open.PARTS`), whose parts add
  up to the total for every AGV; per AGV the top blockers; per action planned vs executed
  completion;
- contacts, clearance, deadlocks and the real-time factor of the physics execution.

**Closed loop** (``mode="closed"``): the scenario runs twice in the closed loop, once per
executor, and the totals are compared (``makespan_ratio`` = physics / grid ticks until every
order is done, ``tp_ratio``, ``latency_ratio``). The two runs are different episodes (the
physics run replans, meets other failures and ends with other assignments), so this ratio
mixes the physics gap with a different history. The delay figures (``delay_*_s``) are fleet
totals of the physics run.

**Timing** (``planner.timing``): ``unit`` (the default) takes the planned side as the plan's
ticks x ``tick_s``; ``motion`` (open loop only) takes it from the plan's motion-timed
schedule (:mod:`.planning.timing`: what a robot with its type's limits needs for this plan,
every dependency kept), so ``makespan_ratio`` measures what the schedule did not foresee;
the unit figures stay beside them as ``KEY_unit`` (:func:`.gap_open.motion_timed`).

Every report carries ``mode`` (``"open-loop"`` or ``"closed-loop"``) and ``timing``
(``"unit"`` or ``"motion"``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import Scenario
from ..errors import WareroverError

__all__ = ["gap_report", "GAP_KEYS", "OPEN_KEYS", "OpenLoopGap", "open_loop_gap",
           "plan_gap", "closed_loop_report", "MODES"]

MODES = ("open", "closed")
GAP_KEYS = ("makespan_ratio", "tp_ratio", "latency_ratio", "delay_dependency_wait_s",
            "delay_kinematic_s", "delay_turns_s", "delay_injected_s", "agv_contacts",
            "static_contacts", "min_clearance_m", "min_separation_m", "limit_violations",
            "deadlocks", "replans", "real_time_factor")
"""The closed-loop figures (also present in the open-loop report)."""
OPEN_KEYS = ("makespan_ratio", "sum_of_costs_ratio", "orders_makespan_ratio", "tp_ratio",
             "latency_ratio", "lost_s_fleet_total", "lost_s_per_agv_mean")
"""The headline open-loop figures."""


def _ratio(a: float, b: float) -> float | None:
    return a / b if b else None


@dataclass
class OpenLoopGap:
    """An open-loop gap: the report, its per-AGV and per-action rows, and the run."""

    report: dict[str, Any]
    agents: list[dict] = field(default_factory=list)
    actions: list[dict] = field(default_factory=list)
    run: Any = None
    """The :class:`~.gap_open.OpenLoopRun` (executed states, cause log, trajectory)."""
    schedule: Any = None
    """``planner.timing: motion``: the :class:`~.planning.timing.Schedule` the planned
    figures come from (None: unit timing)."""


def open_loop_gap(scenario: Scenario, seed: int | None = None,
                  progress: Callable[[str, int, int], None] | None = None) -> OpenLoopGap:
    """Record the ideal run of ``scenario`` on the grid and execute its plan unchanged on
    the scenario's physics executor (its ``executor`` section: dt, delays, parameters)."""
    from .ideal_plan import check_executable, record_grid_run, repair_rotations
    from .open_loop import execute_timed, open_loop_report

    base = scenario.with_seed(seed) if seed is not None else scenario
    plan = record_grid_run(
        base, None if progress is None else lambda t, d, n: progress("grid", t, 0))
    plan = repair_rotations(plan)
    check_executable(plan)
    spec = base.with_executor("physics").executor
    run = execute_timed(plan, spec, seed=base.seed, progress=None if progress is None else
                        lambda t, h: progress("physics", t, h))
    report, agents, actions = open_loop_report(run)
    report, agents, actions, sched = _timed(report, agents, actions, plan,
                                            base.planner.timing, spec)
    head = {"mode": "open-loop", "scenario": base.name, "seed": base.seed,
            "scheduler": base.scheduler.name, "planner": base.planner.name}
    report = {**head, **report}
    g = plan.grid_metrics or {}
    report["success_rate_grid"] = g.get("success_rate")
    return OpenLoopGap(report=report, agents=agents, actions=actions, run=run, schedule=sched)


def _timed(report: dict, agents: list[dict], actions: list[dict], plan, timing: str,
           spec) -> tuple[dict, list[dict], list[dict], Any]:
    """``timing`` ``unit``: the figures as they are (labelled); ``motion``: the planned side
    from the plan's motion-timed schedule (:func:`.gap_open.motion_timed`), and the
    schedule."""
    if timing != "motion":
        return {**report, "timing": "unit"}, agents, actions, None
    from ..planning.timing import schedule_plan
    from .open_loop import motion_timed

    sched = schedule_plan(plan, payload=bool(getattr(spec, "payload", False)),
                          comm_latency_s=float(getattr(spec, "comm_latency_s", 0.0)))
    report, agents, actions = motion_timed(report, agents, actions, plan, sched)
    return {**report, **schedule_spacetime(plan, sched)}, agents, actions, sched


def schedule_spacetime(plan, sched) -> dict:
    """The continuous-time check of a motion-timed schedule (:mod:`.spacetime`): every
    planned move and turn as its swept body volume in ``(x, y, t)``, checked pairwise with
    fcl (``schedule_spacetime_conflicts``: pairs of AGVs whose planned bodies meet; the
    first few under ``schedule_spacetime_first``). Bodies only: carried shelves stay
    parallel to the grid and are not in the schedule."""
    from ..spacetime import from_schedule, validate_spacetime

    lay = plan.layout
    starts = {i: p.states[0][0] for i, p in plan.paths.items()}
    poses = sched.poses(lay.cols, starts)
    tp = from_schedule(poses, cell_m=lay.cell_m,
                       footprints={i: int(plan.types[i].footprint) for i in poses},
                       body_m={i: tuple(plan.types[i].body_m) for i in poses},
                       source="schedule")
    res = validate_spacetime(tp, shelves=False, contact_resolution_s=None, max_conflicts=20)
    return {"schedule_spacetime_conflicts": len(res.conflicts),
            "schedule_spacetime_truncated": res.truncated,
            "schedule_spacetime_first": [str(c) for c in res.conflicts[:3]],
            "schedule_spacetime_s": round(res.timings_s.get("total", 0.0), 3)}


def plan_gap(floor, plan_file, *, fleet=None, fmt: str | None = None, xy: bool = True,
             delays: str | None = None, tick_s: float = 1.0, dt_s: float = 0.02,
             seed: int = 0, strict: bool = False, trajectory_hz: float = 10.0,
             timing: str = "unit", agvs: Sequence[int] = (),
             progress: Callable[[str, int, int], None] | None = None,
             reorder: str = "none", max_ticks: int | None = None) -> OpenLoopGap:
    """The open-loop gap of an imported MAPF plan (any format ``warerover execute`` reads,
    validated and cycle-repaired alike) on ``floor``: the plan's timesteps are the planned
    side (``timing`` ``motion``: its motion-timed schedule), its execution on physics the
    executed side (no dwells). ``agvs``: ids the caller will draw, each checked to be one of
    the plan's agents before anything runs. ``reorder``: ``executor.reorder`` of the
    execution. ``max_ticks``: where the execution stops (None: 10x the plan's makespan +
    200 ticks)."""
    from ..config import ExecutorSpec
    from ..execute import parse_delays
    from .ideal_plan import plan_from_file
    from .open_loop import execute_timed, open_loop_report

    plan, _ = plan_from_file(str(floor), str(plan_file), None if fleet is None
                                   else str(fleet), fmt=fmt, xy=xy, strict=strict,
                                   tick_s=tick_s)
    check_agv_ids(agvs, plan.num_agents, str(plan_file))
    spec = ExecutorSpec(name="physics", dt_s=dt_s, delays=parse_delays(delays),
                        trajectory_hz=trajectory_hz, reorder=reorder)
    run = execute_timed(plan, spec, seed=seed, max_ticks=max_ticks,
                        progress=None if progress is None else
                        lambda t, h: progress("physics", t, h))
    report, agents, actions = open_loop_report(run)
    report, agents, actions, sched = _timed(report, agents, actions, plan, timing, spec)
    report = {"mode": "open-loop", "scenario": Path(str(floor)).stem, "seed": seed,
              "plan": str(plan_file), **report}
    return OpenLoopGap(report=report, agents=agents, actions=actions, run=run, schedule=sched)


def check_agv_ids(agvs: Sequence[int], count: int, source: str) -> None:
    """Refuse AGV ids (``--agvs``) that are not among ``count`` AGVs."""
    bad = [i for i in agvs if not 0 <= i < count]
    if bad:
        raise WareroverError(f"--agvs: {source} has {count} AGVs (ids 0 to {count - 1}); "
                             f"no AGV {', '.join(map(str, bad))}")


def closed_loop_report(scenario: Scenario, seed: int | None = None) -> dict:
    """Run ``scenario`` in the closed loop on both executors and compare (see the module
    doc); the full metrics of both runs are under ``grid`` and ``physics``."""
    from ..sim import run_episode

    base = scenario.with_seed(seed) if seed is not None else scenario
    grid = run_episode(base.with_executor("grid")).metrics
    phys = run_episode(base.with_executor("physics")).metrics
    out = {
        "mode": "closed-loop", "timing": "unit",
        "scenario": base.name, "seed": base.seed, "scheduler": base.scheduler.name,
        "planner": base.planner.name,
        "makespan_grid_ticks": grid["ticks"], "makespan_physics_ticks": phys["ticks"],
        "makespan_ratio": _ratio(phys["ticks"], grid["ticks"]),
        "tp_ratio": _ratio(phys["throughput"], grid["throughput"]),
        "latency_ratio": _ratio(phys["order_latency_mean_ticks"],
                                grid["order_latency_mean_ticks"]),
        "success_rate_grid": grid["success_rate"], "success_rate_physics": phys["success_rate"],
        "replans": phys["replans"] - grid["replans"],
        "replans_grid": grid["replans"], "replans_physics": phys["replans"],
    }
    for key in GAP_KEYS:
        if key not in out:
            out[key] = phys.get(key)
    n = sum(g.count for g in base.fleet.agvs)
    for key in ("delay_dependency_wait_s", "delay_kinematic_s", "delay_turns_s",
                "delay_injected_s"):
        v = phys.get(key)
        out[f"{key}_fleet_total"] = v
        out[f"{key}_per_agv_mean"] = v / n if v is not None and n else None
    out["grid"] = grid
    out["physics"] = phys
    return out


def gap_report(scenario: Scenario, seed: int | None = None, mode: str = "open") -> dict:
    """The gap report of ``scenario`` (with ``seed`` if given) in ``mode`` (``"open"``:
    one plan on both sides, the default; ``"closed"``: two closed-loop episodes); a flat
    dict of figures with the runs' own metrics under ``grid`` and ``physics``."""
    if mode not in MODES:
        raise ValueError(f"gap mode must be one of {MODES}, got {mode!r}")
    if mode == "closed":
        return closed_loop_report(scenario, seed)
    return open_loop_gap(scenario, seed).report
