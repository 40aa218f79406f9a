"""Episode metrics: one flat dict, written as ``metrics.json``.

Keys (units in the name or below):

- ``success_rate``: orders completed / orders generated (1.0 if none were generated);
- ``throughput``: orders completed per tick;
- ``ticks``: ticks simulated; ``sim_time_s`` = ticks x ``tick_s``;
- ``orders_generated``, ``orders_completed``;
- ``order_latency_mean_ticks``, ``order_latency_p99_ticks``: arrival to hand-over;
- ``ct_total_s``: wall seconds in scheduler + planner over the episode;
- ``ct_mean_ms`` / ``ct_p99_ms``: per tick, scheduler + planner; ``ct_sched_mean_ms``,
  ``ct_sched_p99_ms``, ``ct_plan_mean_ms``, ``ct_plan_p99_ms``: the same split;
- ``blocked_moves``: AGV-ticks an AGV wanted to move and had to wait (not a collision);
- ``collisions``: overlaps or swaps the executor carried out (0 with a valid plan);
- ``replans``: single-AGV plans committed; ``plan_failures``: searches that found no path
  (the AGV kept its old path and retried); ``goal_busy_detours``: plans that sent an AGV to
  wait near a goal another AGV was standing on; ``planner_budget_hits``: times a planner ran
  out of its node or time budget and used its documented fallback;
- ``failures`` (AGV breakdowns), ``down_ticks`` (AGV-ticks spent failed),
  ``orders_delayed_by_failures`` (orders held by an AGV when it failed),
  ``failure_replans`` (AGVs stopped and replanned because a corridor opened across their
  path);
- safety corridors (physics: an AGV body within ``corridor_margin_m`` of the person's space,
  checked every physics step; grid: an AGV cell on a corridor cell, checked every tick;
  the failed AGV in its own corridor and AGVs that are down are never counted):
  ``corridor_inside_agv_s`` (every AGV-second inside an open corridor),
  ``corridor_intrusion_agv_s`` (the part of it that is intrusion: all of it, except the
  time an AGV caught inside when the corridor opened takes to leave within its exit
  bound), ``corridor_intrusions`` (intrusion visits: an AGV entering, or a caught AGV still
  inside at its deadline; once per AGV and corridor visit), ``corridor_caught_inside``
  (AGVs caught inside, or unable to stop before, a corridor as it opened; each gets an
  exit bound, ``faults.exit_time_s`` or derived from its speed),
  ``corridor_exits_within_bound`` and ``corridor_exits_overrun`` (how those exits ended;
  they add up to ``corridor_caught_inside``) and ``corridor_exit_max_s`` (longest exit that
  was seen to end, seconds from the opening; null if none). Exact rules:
  ``faults/intrusion_log.py``;
- ``wall_s``: wall seconds of the whole episode.

The physics executor adds its own figures (``PhysicsExecutor.summary``), among them
``min_clearance_m`` (smallest edge-to-edge clearance between two AGVs' rectangles, carried
shelves included, over every physics step; negative = overlap depth; ``min_separation_m``
is its deprecated alias), ``min_clearance_t_s``, ``limit_violations`` (a measured speed,
acceleration or turn rate more than 5% above its limit, counted each time it rises above)
and ``peak_speed_ratio`` / ``peak_accel_ratio`` / ``peak_turn_rate_ratio`` (fleet maximum of
measured peak / limit, against the limit in force when it was measured: a loaded AGV's
acceleration limit is lower with ``executor.payload``); the per-AGV peaks are in
``trajectories.npz``. Also ``peak_lateral_speed_mps`` (highest speed across its heading of
any differential-drive AGV: how much the controller slips sideways; ~0 with
``executor.no_slip``), the switches ``no_slip``, ``payload``, ``comm_latency_s``, and
``delay_comm_latency_s`` (AGV-seconds spent with the next action's cells free but the
dependency graph's message saying so not yet arrived).

Planning that takes time (:mod:`warerover_phys.invoke`): ``planner_invoke``,
``planner_latency``, ``planner_window_ticks``, ``planner_calls``, ``ct_plan_call_mean_ms`` /
``ct_plan_call_p99_ms`` (wall ms per planner call, a window's steps together),
``plan_effect_ticks_mean`` (ticks from a call to its plan taking effect), ``plan_wait_agv_s``
(AGV-seconds standing at the end of a committed path short of the goal: waiting for a plan;
counted with ``periodic`` / ``event`` calls or a latency) and ``plans_dropped`` (paths of a
late plan not taken because the AGV's path changed while it was computed).

CT keys, wall seconds and the physics executor's ``real_time_factor`` are the only ones that
change between two runs with the same scenario and seed; :data:`TIMING_KEYS` lists every
such key.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .config import Scenario
    from .world import World

__all__ = ["MetricsRecorder", "TIMING_KEYS"]

TIMING_KEYS = ("ct_total_s", "ct_mean_ms", "ct_p99_ms", "ct_sched_mean_ms", "ct_sched_p99_ms",
               "ct_plan_mean_ms", "ct_plan_p99_ms", "wall_s", "real_time_factor",
               "execute_wall_s", "ct_plan_call_mean_ms", "ct_plan_call_p99_ms")


class MetricsRecorder:
    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self.sched_s: list[float] = []
        self.plan_s: list[float] = []
        self.blocked = 0
        self.collisions = 0
        self.replans = 0
        self.plan_failures = 0
        self.detours = 0
        self.budget_hits = 0
        self.plans_dropped = 0
        """New paths of a late plan not taken (the AGV's path changed while it was
        computed; ``planner.latency``)."""
        self._t0 = time.perf_counter()

    def record_tick(self, *, sched_s: float, plan_s: float, blocked: int,
                    collisions: int) -> None:
        self.sched_s.append(sched_s)
        self.plan_s.append(plan_s)
        self.blocked += blocked
        self.collisions += collisions

    def replans_this_tick(self, planned: int, failed: int, detours: int,
                          budget_hits: int = 0) -> None:
        self.replans += planned
        self.plan_failures += failed
        self.detours += detours
        self.budget_hits += budget_hits

    def summary(self, world: World) -> dict:
        sc = self.scenario
        ticks = world.tick
        generated = len(world.orders)
        completed = len(world.completed_tick)
        latencies = np.array([t - world.orders[o].tick for o, t in world.completed_tick.items()],
                             dtype=float)
        sched = np.array(self.sched_s) * 1e3
        plan = np.array(self.plan_s) * 1e3
        total = sched + plan

        def mean(x: np.ndarray) -> float:
            return float(x.mean()) if x.size else 0.0

        def p99(x: np.ndarray) -> float:
            return float(np.percentile(x, 99)) if x.size else 0.0

        return {
            "scenario": sc.name,
            "seed": sc.seed,
            "scheduler": sc.scheduler.name,
            "planner": sc.planner.name,
            "executor": sc.executor.name,
            "order_pattern": sc.orders.pattern,
            "agvs": len(world.agvs),
            "success_rate": completed / generated if generated else 1.0,
            "throughput": completed / ticks if ticks else 0.0,
            "ticks": ticks,
            "sim_time_s": ticks * sc.tick_s,
            "orders_generated": generated,
            "orders_completed": completed,
            "order_latency_mean_ticks": mean(latencies),
            "order_latency_p99_ticks": p99(latencies),
            "blocked_moves": self.blocked,
            "collisions": self.collisions,
            "replans": self.replans,
            "plan_failures": self.plan_failures,
            "goal_busy_detours": self.detours,
            "planner_budget_hits": self.budget_hits,
            "plans_dropped": self.plans_dropped,
            "failures": world.fault_stats["failures"],
            "down_ticks": world.fault_stats["down_ticks"],
            "orders_delayed_by_failures": len(world.delayed_orders),
            **world.corridor_book.summary(),
            "failure_replans": world.fault_stats["failure_replans"],
            "ct_total_s": float(total.sum() / 1e3),
            "ct_mean_ms": mean(total),
            "ct_p99_ms": p99(total),
            "ct_sched_mean_ms": mean(sched),
            "ct_sched_p99_ms": p99(sched),
            "ct_plan_mean_ms": mean(plan),
            "ct_plan_p99_ms": p99(plan),
            "wall_s": time.perf_counter() - self._t0,
        }
