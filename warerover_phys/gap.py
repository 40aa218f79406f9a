"""The sim-to-real gap: one scenario and seed, run on the ideal grid executor and on physics.

``makespan_ratio`` = executed makespan (physics) / planned makespan (grid), in ticks until
every order is done (or ``max_ticks``); ``tp_ratio`` and ``latency_ratio`` compare
throughput and mean order latency the same way (physics / grid). The per-action delay split,
contacts, separation, deadlocks and the real-time factor come from the physics run.
"""

from __future__ import annotations

from .config import Scenario

__all__ = ["gap_report", "GAP_KEYS"]

GAP_KEYS = ("makespan_ratio", "tp_ratio", "latency_ratio", "delay_dependency_wait_s",
            "delay_kinematic_s", "delay_turns_s", "delay_injected_s", "agv_contacts",
            "static_contacts", "min_clearance_m", "min_separation_m", "limit_violations",
            "deadlocks", "replans", "real_time_factor")


def _ratio(a: float, b: float) -> float | None:
    return a / b if b else None


def gap_report(scenario: Scenario, seed: int | None = None) -> dict:
    """Run ``scenario`` on both executors and compare; returns a flat dict (see the module
    doc), with the full metrics of both runs under ``grid`` and ``physics``."""
    from .sim import run_episode

    base = scenario.with_seed(seed) if seed is not None else scenario
    grid = run_episode(base.with_executor("grid")).metrics
    phys = run_episode(base.with_executor("physics")).metrics
    out = {
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
    out["grid"] = grid
    out["physics"] = phys
    return out
