"""The executor interface: committed plans go in, a step report comes out.

An executor never touches the world. The loop builds it from the scenario's ``executor``
section, :meth:`Executor.bind` s it once to an :class:`ExecutorSetup` (the floor and the
fleet, fixed for the episode) and then, once per tick, hands it a read-only
:class:`TickView` (the committed plans and what the loop knows of each AGV) and applies the
:class:`StepReport` it returns: every AGV's new discrete state, how far each is behind its
plan, blocked AGVs, contacts, events to log, corridor intrusion hits and AGVs to replan.

Two more hooks serve the fault model: :meth:`Executor.remaining` (what an AGV still has to
drive) and :meth:`Executor.stop_short` (a corridor opened: stop before it). At the end the
loop asks for :meth:`Executor.summary` (figures for ``metrics.json``) and
:meth:`Executor.trajectory` (recorded poses, or None).

A plug-in executor is any class with these members; :func:`warerover_phys.testing.check_executor`
runs it through small fixed cases and says what is wrong.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from ..planning.paths import State, TimedPath

if TYPE_CHECKING:
    from ..config import AgvTypeSpec
    from ..layout import Layout

__all__ = ["AgvBody", "ExecutorSetup", "TickView", "StepReport", "Executor", "record_report"]


@dataclass(frozen=True, slots=True)
class AgvBody:
    """One AGV as an executor sees it: fixed for the episode."""

    id: int
    k: int
    """Footprint: a ``k x k`` cell square anchored at its top-left cell."""
    spec: AgvTypeSpec
    """Body size, mass, speed, acceleration and turn limits, drive type."""
    start: State
    """Where it stands at tick 0."""


@dataclass(frozen=True)
class ExecutorSetup:
    """What an executor is bound to once, before the first tick."""

    layout: Layout
    tick_s: float
    """Seconds of simulated time per planning tick."""
    agvs: tuple[AgvBody, ...]
    rng: np.random.Generator
    """The episode's ``delays`` generator (random delays, speed scales)."""


@dataclass(frozen=True)
class TickView:
    """What the loop tells the executor at the start of a tick (read-only)."""

    tick: int
    plans: Mapping[int, TimedPath]
    """The committed path of every AGV (a new object whenever the loop commits one)."""
    behind: tuple[int, ...]
    """Ticks each AGV is behind its committed path (what the last report said)."""
    failed: frozenset[int]
    """AGVs that are down: they brake and start nothing."""
    loaded: tuple[bool, ...]
    carried: tuple[int | None, ...]
    """Shelf id each AGV carries (None if unloaded)."""
    task_state: tuple[int, ...]
    """Each AGV's task state (``world.AgvState`` values; 7 = failed), for recordings."""
    corridors: Mapping[int, Any] = field(default_factory=dict)
    """Open safety corridors by id (``faults.corridors.Corridor``)."""
    dwells: Mapping[int, tuple[tuple[int, int], ...]] = field(default_factory=dict)
    """Work in place in the committed paths (open-loop execution of a recorded plan; the
    loop leaves it empty because its world holds AGVs while they work): per AGV,
    ``(tick, ticks)`` intervals during which its path stands still to pick, hand over,
    place or park. An executor that skips a plan's waits (physics, through the dependency
    graph) must still keep the AGV standing there for ``ticks`` ticks from its arrival
    before its next move; one that follows the ticks (grid) needs nothing more."""
    goals: tuple[int | None, ...] = ()
    """Each AGV's current goal anchor (None while it works in place or is down; a yield
    spot while it makes way), for the freeze detector (``freeze``); empty: unknown."""


@dataclass
class StepReport:
    """What happened during one tick, for the loop to apply."""

    states: dict[int, State] = field(default_factory=dict)
    """Every AGV's discrete state at the end of the tick (standing or between two cells)."""
    behind: dict[int, int] = field(default_factory=dict)
    """Ticks each AGV is now behind its committed path (absent: unchanged)."""
    blocked: list[int] = field(default_factory=list)
    """AGVs that wanted to move but could not (their next cells were held)."""
    collisions: int = 0
    """Overlaps or swaps that happened anyway (0 for any valid plan); in physics, AGV-AGV
    contacts that began during the tick."""
    replan: list[int] = field(default_factory=list)
    """AGVs the executor asks the loop to replan now (dependency deadlock, deviation)."""
    events: list[tuple[str, dict]] = field(default_factory=list)
    """Events to log, in order: ``(name, fields)``."""
    intrusion_checks: list[list[tuple[int, int, float]]] = field(default_factory=list)
    """Corridor checks made during the tick, in order; each lists its ``(agv, corridor,
    depth)`` hits (the failed AGV of a corridor is never listed for its own corridor)."""
    intrusion_unit: str = "m"
    """Unit of the depths: ``m`` (physics) or ``cells`` (grid)."""
    poses: np.ndarray | None = None
    """Continuous poses at the end of the tick, (N, 3): x, y (metres), heading (radians);
    None for executors without continuous bodies (grid)."""
    speeds: np.ndarray | None = None
    """Body speeds at the end of the tick, (N,) m/s (None on the grid)."""
    settled: frozenset[int] | None = None
    """AGVs at rest at the end of the tick: standing on the last state of their committed
    path with nothing left to drive, and (physics) holding that pose within the
    executor's tolerance. A task stage's work starts and its dwell counts down only while
    the AGV is settled on the stage's goal. None: the executor does not say; the loop then
    judges from the committed path alone (how far along it the AGV is)."""
    freezes: list[Any] = field(default_factory=list)
    """Freezes found during the tick (``freeze.Freeze``): AGVs without progress for
    ``executor.freeze_s`` while nothing they wait on can still move. The loop counts them
    as deadlocks, logs them and replans the AGVs involved from where they stand."""
    committed: dict[int, int] = field(default_factory=dict)
    """AGVs that are committed beyond their state (physics: they drive through released
    actions they claimed, and cannot stop before): the node each will stand on when those
    are done, where a new plan must start. Absent: its state's node."""


@runtime_checkable
class Executor(Protocol):
    """Carries out committed plans; see the module docstring for the life cycle."""

    name: str

    def bind(self, setup: ExecutorSetup) -> None:
        """Build the executor's own state for an episode (called once, before tick 0)."""
        ...

    def step(self, view: TickView) -> StepReport:
        """Advance every AGV from ``view.tick`` to ``view.tick + 1``."""
        ...

    def remaining(self, agv: int) -> list[State]:
        """States AGV ``agv`` still has to drive beyond its committed path's view of now
        (an executor that follows the committed path exactly returns ``[]``)."""
        ...

    def stop_short(self, agv: int, cells: frozenset[int], view: TickView) -> tuple[bool, bool]:
        """A corridor opened over ``cells``: stop ``agv`` as soon as it can. Returns
        ``(handled, enters)``: whether the executor stopped it itself (else the loop cuts
        its committed path), and whether what it can no longer drop enters ``cells``."""
        ...

    def summary(self) -> dict[str, Any]:
        """Executor figures for ``metrics.json``."""
        ...

    def trajectory(self) -> dict[str, np.ndarray] | None:
        """Recorded poses (see ``PhysicsExecutor.trajectory``), or None."""
        ...


def record_report(report: StepReport, tick: int, executed: dict[int, list], behind: list[int],
                  events: list[dict]) -> None:
    """An open-loop run's bookkeeping of one tick's report (``execute_plan``, the open-loop
    gap): each AGV's state appended to ``executed[i]``, its lateness written to
    ``behind[i]``, the events appended to ``events`` with the tick."""
    for i, s in report.states.items():
        executed[i].append(s)
    for i, b in report.behind.items():
        behind[i] = b
    for name, fields in report.events:
        events.append({"tick": tick, "event": name, **fields})
