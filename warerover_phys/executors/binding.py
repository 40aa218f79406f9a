"""How the loop talks to an executor: the setup it binds to, the view of one tick it steps on,
and what its step report changes in the world (:mod:`warerover_phys.sim` re-exports the names)."""

from __future__ import annotations

from types import MappingProxyType

from ..world import Agv, AgvState, World
from .base import AgvBody, ExecutorSetup, StepReport, TickView


def executor_setup(world: World) -> ExecutorSetup:
    """What an executor is bound to for ``world``'s episode."""
    return ExecutorSetup(
        layout=world.layout, tick_s=world.scenario.tick_s, rng=world.rngs["delays"],
        agvs=tuple(AgvBody(a.id, a.k, a.spec, a.pos) for a in world.agvs),
        intrusion_checker=world.scenario.faults.checker)


def tick_view(world: World) -> TickView:
    """What the executor may know of the world's current tick (read-only)."""
    agvs = world.agvs
    return TickView(
        tick=world.tick, plans=MappingProxyType(world.reservations.paths),
        behind=tuple(a.delay for a in agvs),
        failed=frozenset(a.id for a in agvs if a.state == AgvState.FAILED),
        loaded=tuple(a.loaded for a in agvs),
        carried=tuple(a.trip.shelf if a.loaded and a.trip is not None else None
                      for a in agvs),
        task_state=tuple(int(a.state) for a in agvs),
        corridors=MappingProxyType(world.corridors),
        goals=tuple(_goal_now(world, a) for a in agvs))


def _goal_now(world: World, agv: Agv) -> int | None:
    """Where the AGV is headed now: its yield spot while it makes way, else its task goal
    (None while it works in place or is down)."""
    if agv.state == AgvState.FAILED:
        return None
    if agv.yield_goal is not None and world.tick < agv.yield_until:
        return agv.yield_goal
    return world.goal_of(agv)


def apply_report(world: World, report: StepReport) -> None:
    """Write what the executor reports into the world (before the tick advances)."""
    from ..faults.intrusion_log import record_checks

    for i, state in report.states.items():
        world.agvs[i].pos = state
    for i, behind in report.behind.items():
        world.agvs[i].delay = behind
    for name, fields in report.events:
        world.log(name, **fields)
    record_checks(world, report.intrusion_checks, unit=report.intrusion_unit)


def step_executor(world: World, executor) -> StepReport:
    """One executor tick against ``world``, as the loop runs it (view in, report applied;
    the caller advances ``world.tick``). The executor must be bound
    (``executor.bind(executor_setup(world))``)."""
    report = executor.step(tick_view(world))
    apply_report(world, report)
    return report
