"""The plan of the ideal run, as data: what the open-loop gap executes on physics.

:func:`record_grid_run` runs a scenario in the closed loop on the grid executor (scheduler +
planner, the ideal run) and keeps, per tick, every AGV's executed state, task state and
cargo. That record is a :class:`TimedPlan`: each AGV's timed path over the whole episode
(moves and waits, from tick 0) and its *dwells*, the ticks it stands still to work:

- ``pick``, ``handover``, ``place``: ticks it spends in that task state, standing at the
  shelf or station (``tasks.pick_ticks`` ... of the scenario);
- ``park``: ticks it stands idle at its home parking cell before its next move (a last
  parking with no move after it is not a dwell: the AGV has finished).

Every other tick it stands still is a plain *wait* of the plan. An executor that skips a
plan's waits (physics, through the dependency graph) must still hold every dwell for its
planned duration: :attr:`TimedPlan.dwell_view` is what the executor is told
(``TickView.dwells``).

When the last order completes, a 2x2 AGV may be half-way through a two-tick move: the grid
run is stepped on until every AGV has stood still once, and each path is cut at its first
standing state from the episode's last tick on, so every path ends standing; the run's
metrics are those at the end of the episode.

:func:`plan_from_file` makes a :class:`TimedPlan` of an imported MAPF plan (no dwells).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

from ..executors.adg import path_moves
from ..planning.paths import TimedPath

if TYPE_CHECKING:
    from ..config import AgvTypeSpec, Scenario
    from ..layout import Layout

__all__ = ["Dwell", "Failure", "TimedPlan", "PlannedAction", "record_grid_run", "plan_from_file",
           "check_executable", "repair_rotations", "DWELL_KINDS"]

DWELL_KINDS = ("pick", "handover", "place", "park")
_WORK = {2: "pick", 4: "handover", 6: "place"}  # world.AgvState values
_IDLE = 0


@dataclass(frozen=True)
class Dwell:
    """``ticks`` ticks of work in place from ``tick``, standing at anchor ``node``."""

    agv: int
    tick: int
    ticks: int
    kind: str
    node: int


@dataclass(frozen=True)
class Failure:
    """AGV ``agv`` is down for ``ticks`` ticks from ``tick`` (a failure of the grid run,
    replayed at the same tick in the open loop)."""

    agv: int
    tick: int
    ticks: int


@dataclass(frozen=True)
class PlannedAction:
    """One move of the plan, with the dwell and the plain wait before it (ticks)."""

    agv: int
    seq: int
    src: int
    dst: int
    tick: int
    """Last tick it stands at ``src`` (it moves during this tick)."""
    ticks: int
    """Planned duration of the move."""
    dwell: int
    """Planned dwell ticks before the move (from its arrival at ``src``)."""
    wait: int
    """Planned plain waits before the move (ticks standing that are not a dwell)."""

    @property
    def finish(self) -> int:
        return self.tick + self.ticks


@dataclass
class TimedPlan:
    """A fixed plan with work in place (see the module docstring)."""

    layout: Layout
    types: list[AgvTypeSpec]
    tick_s: float
    paths: dict[int, TimedPath]
    """Every AGV's states per tick from tick 0, ending standing."""
    dwells: dict[int, tuple[Dwell, ...]]
    source: str
    """Where the plan comes from (for reports)."""
    task_state: np.ndarray | None = None
    """(T + 1, N) task state per tick (``world.AgvState``), if recorded."""
    loaded: np.ndarray | None = None
    carried: np.ndarray | None = None
    """(T + 1, N) carried shelf id per tick (-1: none)."""
    orders: list[dict] = field(default_factory=list)
    """Orders completed in the plan: ``{"order", "agv", "arrival_tick", "completed_tick"}``
    (the completion is the end of a hand-over dwell of that AGV)."""
    grid_metrics: dict[str, Any] | None = None
    """The grid run's own metrics (closed loop), if the plan is one."""
    given_finish: tuple[int, ...] | None = None
    """Every AGV's planned finish tick in the plan *as given*, when this plan is its
    rotation repair (:func:`repair_rotations`, :func:`plan_from_file`); None: as given."""
    repairs: tuple = ()
    """The rotations repaired (:class:`warerover_phys.execute.Repair`), in order."""
    failures: tuple[Failure, ...] = ()
    """The grid run's failures (``faults``), by tick of the run as given."""

    @property
    def num_agents(self) -> int:
        return len(self.paths)

    @property
    def dwell_view(self) -> MappingProxyType:
        """``TickView.dwells``: per AGV, ``(tick, ticks)`` of each dwell."""
        return MappingProxyType({i: tuple((d.tick, d.ticks) for d in ds)
                                 for i, ds in self.dwells.items() if ds})

    def actions(self, i: int) -> list[PlannedAction]:
        """AGV ``i``'s moves in order, each with the dwell and wait before it."""
        moves = path_moves(self.paths[i], self.layout.cols)
        dwells = sorted(self.dwells.get(i, ()), key=lambda d: d.tick)
        out, j, prev = [], 0, 0
        for seq, (src, dst, tick, ticks) in enumerate(moves):
            d = 0
            while j < len(dwells) and dwells[j].tick <= tick:
                d += dwells[j].ticks
                j += 1
            out.append(PlannedAction(i, seq, src, dst, tick, ticks, d, tick - prev - d))
            prev = tick + ticks
        return out

    def trailing_dwell(self, i: int) -> int:
        """Dwell ticks after AGV ``i``'s last move (work it ends with)."""
        moves = path_moves(self.paths[i], self.layout.cols)
        last = moves[-1][2] if moves else -1
        return sum(d.ticks for d in self.dwells.get(i, ()) if d.tick > last)

    def planned_finish(self, i: int) -> int:
        """Tick AGV ``i`` finishes its last move or trailing dwell."""
        acts = self.actions(i)
        end = acts[-1].finish if acts else 0
        return end + self.trailing_dwell(i)

    def given_planned_finish(self, i: int) -> int:
        """:meth:`planned_finish` of AGV ``i`` in the plan as given (before any rotation
        repair): the planned side of the gap."""
        return self.given_finish[i] if self.given_finish is not None \
            else self.planned_finish(i)


# ----------------------------------------------------------------------------- grid run

def record_grid_run(scenario: Scenario, progress=None) -> TimedPlan:
    """Run ``scenario`` (its seed) in the closed loop on the grid executor and return the
    record as a :class:`TimedPlan` (``grid_metrics`` holds the run's metrics)."""
    from ..sim import Simulation

    sim = Simulation(scenario.with_executor("grid"))
    w = sim.world
    n = len(w.agvs)
    states, task, loaded, carried = [], [], [], []

    def snap() -> None:
        states.append([a.pos for a in w.agvs])
        task.append([int(a.state) for a in w.agvs])
        loaded.append([a.loaded for a in w.agvs])
        carried.append([a.trip.shelf if a.loaded and a.trip is not None else -1
                        for a in w.agvs])

    snap()
    while not sim.done:
        sim.step()
        snap()
        if progress is not None:
            progress(w.tick, len(w.completed_tick), len(w.status))
    metrics = sim.metrics.summary(w)
    metrics.update(sim.executor.summary())
    # Step on until every AGV has stood still once since the end, so that every path can
    # end standing: each is cut at its first standing state from the last tick on.
    last = len(states) - 1
    stood = [a.pos[0] == a.pos[1] for a in w.agvs]
    extra = 0
    while not all(stood) and extra < 16:
        sim.step()
        snap()
        extra += 1
        stood = [s or a.pos[0] == a.pos[1] for s, a in zip(stood, w.agvs, strict=True)]
    tick_arr = np.asarray(task, dtype=np.int8)
    homes = [a.home for a in w.agvs]
    paths, dwells = {}, {}
    for i in range(n):
        seq = [s[i] for s in states]
        end = next((t + 1 for t in range(last, len(seq)) if seq[t][0] == seq[t][1]), None)
        if end is None:  # a move still running after 16 extra ticks: dropped
            end = last + 1
            while end > 1 and seq[end - 1][0] != seq[end - 1][1]:
                end -= 1
        paths[i] = TimedPath(i, 0, tuple(seq[:end]))
        dwells[i] = _dwells(i, seq[:end], tick_arr[:end, i], homes[i])
    orders = []
    for ev in w.events:
        if ev["event"] == "order_completed":
            o = w.orders[ev["order"]]
            orders.append({"order": ev["order"], "agv": ev["agv"], "arrival_tick": o.tick,
                           "completed_tick": ev["tick"]})
    types = [a.spec for a in w.agvs]
    failures = _failures(w.events, len(states))
    return TimedPlan(
        layout=w.layout, types=types, tick_s=scenario.tick_s, paths=paths, dwells=dwells,
        source=f"grid run of {scenario.name} seed {scenario.seed} ({scenario.scheduler.name}"
               f" + {scenario.planner.name}, closed loop)",
        task_state=tick_arr, loaded=np.asarray(loaded, dtype=bool),
        carried=np.asarray(carried, dtype=np.int64), orders=orders, grid_metrics=metrics,
        failures=failures)


def _failures(events: list[dict], end: int) -> tuple[Failure, ...]:
    """The failures of a run's event log: from ``agv_failed`` to ``agv_repaired`` (or the
    end of the record, tick ``end``, for one never repaired)."""
    out, down = [], {}
    for ev in events:
        if ev["event"] == "agv_failed":
            down[ev["agv"]] = ev["tick"]
        elif ev["event"] == "agv_repaired" and ev["agv"] in down:
            t = down.pop(ev["agv"])
            out.append(Failure(ev["agv"], t, ev["tick"] - t))
    out += [Failure(a, t, max(0, end - t)) for a, t in down.items()]
    return tuple(sorted(out, key=lambda f: (f.tick, f.agv)))


def _dwells(i: int, seq: list, task: np.ndarray, home: int) -> tuple[Dwell, ...]:
    """The dwells of one recorded path (see the module docstring)."""
    out: list[Dwell] = []
    last_move = max((t for t in range(len(seq) - 1) if seq[t + 1] != seq[t]), default=-1)
    run: list[int] | None = None  # [start, length, kind, node]
    for t in range(len(seq) - 1):
        a, b = seq[t]
        standing = a == b and seq[t + 1] == seq[t]
        kind = None
        if standing:
            if int(task[t]) in _WORK:
                kind = _WORK[int(task[t])]
            elif int(task[t]) == _IDLE and int(task[t + 1]) == _IDLE and a == home \
                    and t < last_move:
                kind = "park"
        if run is not None and (kind != run[2] or a != run[3] or not standing):
            out.append(Dwell(i, run[0], run[1], run[2], run[3]))
            run = None
        if kind is not None:
            if run is None:
                run = [t, 0, kind, a]
            run[1] += 1
    if run is not None:
        out.append(Dwell(i, run[0], run[1], run[2], run[3]))
    return tuple(out)


def check_executable(plan: TimedPlan) -> None:
    """Raise :class:`~warerover_phys.errors.WareroverError` if the dependency graph of
    ``plan`` has a cycle: a *rotation* of the grid run (AGVs that each enter the cell the
    next one leaves in the same tick, which the grid executor allows) has no execution
    order, so the plan cannot run open loop on physics. The message names the AGVs and
    cells. :func:`repair_rotations` removes them first; this is its guard."""
    from ..errors import WareroverError
    from ..executors.adg import ADGCycleError, build

    try:
        build(plan.paths, {i: t.footprint for i, t in enumerate(plan.types)},
              cols=plan.layout.cols)  # checks that the graph is acyclic
    except ADGCycleError as err:
        raise WareroverError(
            f"{plan.source}: the plan has a rotation (AGVs {list(err.agvs)} each enter the "
            f"cell the next one leaves, cells {[list(c) for c in err.cells]}): the action "
            "dependency graph cannot order it, so it cannot be executed open loop "
            "(--mode closed compares this seed)") from None


# ----------------------------------------------------------------------------- rotations

def repair_rotations(plan: TimedPlan, *, strict: bool = False,
                     max_rounds: int | None = None) -> TimedPlan:
    """``plan`` with every *rotation* (AGVs that each enter the cell the next one leaves in
    the same tick: the grid allows it, the dependency graph has no order for it) replaced
    by the local detour of :func:`warerover_phys.execute.repair_cycles`: single-cell moves,
    one AGV at a time, that take the rotation's AGVs to the cells the rotation gives them
    (1x1 neighbours may step aside and back; AGVs mid-move, at work or down stay put and
    their cells are avoided). The ``L`` detour moves are inserted as ``L`` ticks before the
    rotation's tick, in which every other AGV stands: an AGV standing then waits ``L`` ticks
    more there, one mid-move finishes its move first and then waits. Dwells, task states,
    cargo and order completions after the insertion move with their AGV. A plan without
    rotations comes back as it is (the same object).

    The result keeps the plan as given as the planned side: ``given_finish`` (each AGV's
    planned finish tick before the repair) and ``repairs`` (one
    :class:`~warerover_phys.execute.Repair` per rotation: tick as given, AGVs of the detour,
    cells, moves = ticks inserted). The repaired plan is checked with the independent
    validator. ``strict``: raise instead of repairing. Raises
    :class:`~warerover_phys.errors.WareroverError` (naming the AGVs and cells) if a
    rotation has no local detour."""
    from ..errors import WareroverError
    from ..execute import Repair, _PuzzleFloor

    cols = plan.layout.cols
    n = plan.num_agents
    states = {i: list(plan.paths[i].states) for i in range(n)}
    first = _rotations(states, n, cols, 0)
    if not first:
        return plan
    if strict:
        c = first[0]
        raise WareroverError(f"{plan.source}: AGVs {list(c.agents)} move round a cycle "
                             f"through cells {[list(x) for x in c.cells]} at tick "
                             f"{c.timestep - 1} (a rotation)")
    sizes = [t.footprint for t in plan.types]
    floor = _PuzzleFloor(plan.layout)
    dwells = {i: list(plan.dwells.get(i, ())) for i in range(n)}
    arrays = [a for a in (plan.task_state, plan.loaded, plan.carried) if a is not None]
    arrays = [np.asarray(a).copy() for a in arrays]
    orders = [dict(o) | {"given_completed_tick": o["completed_tick"]} for o in plan.orders]
    given_t = list(range(max(len(s) for s in states.values()) + 1))  # new tick -> as given
    repairs: list[Repair] = []
    limit = max_rounds if max_rounds is not None else 10 * max(1, n)
    cycles = first
    while cycles:
        if len(repairs) >= limit:
            raise WareroverError(f"{plan.source}: rotations remain after {limit} repairs")
        cyc = cycles[0]
        row = cyc.timestep
        before, moves, agents, given_tick = _find_detour(plan, states, dwells, given_t, cyc,
                                                         floor, sizes)
        length = len(moves)
        stops = _insert_detour(states, before, moves, agents, row)
        for i, p in stops.items():
            dwells[i] = [d if d.tick + d.ticks <= p else
                         Dwell(d.agv, d.tick + length, d.ticks, d.kind, d.node)
                         for d in dwells[i]]
        arrays = [_insert_rows(a, length, stops) for a in arrays]
        for o in orders:
            p = stops.get(o["agv"])
            if p is not None and o["completed_tick"] > p:
                o["completed_tick"] += length
        given_t[row:row] = [given_tick] * length
        repairs.append(Repair(given_tick, tuple(agents), cyc.cells, length))
        cycles = _rotations(states, n, cols, max(0, row - 1))
    paths = {i: TimedPath(i, 0, tuple(states[i])) for i in range(n)}
    it = iter(arrays)
    out = TimedPlan(
        layout=plan.layout, types=plan.types, tick_s=plan.tick_s, paths=paths,
        dwells={i: tuple(ds) for i, ds in dwells.items()}, source=plan.source,
        task_state=next(it) if plan.task_state is not None else None,
        loaded=next(it) if plan.loaded is not None else None,
        carried=next(it) if plan.carried is not None else None,
        orders=orders, grid_metrics=plan.grid_metrics, failures=plan.failures,
        given_finish=tuple(plan.planned_finish(i) for i in range(n)),
        repairs=tuple(repairs))
    _check_repaired(plan, out)
    return out


def _find_detour(plan: TimedPlan, states: dict[int, list], dwells: dict[int, list],
                 given_t: list[int], cyc, floor, sizes: list[int]):
    """For :func:`repair_rotations`: every path padded to the rotation's tick, then the
    detour of rotation ``cyc`` around the AGVs mid-move, at work or down: the states before
    the rotation, the detour's moves and AGVs, and the tick as given."""
    from ..errors import WareroverError
    from ..execute import PlanError, _detour

    cols, n, row = plan.layout.cols, plan.num_agents, cyc.timestep
    for i in range(n):  # pad every path to the rotation's tick
        if len(states[i]) < row + 1:
            states[i] += [states[i][-1]] * (row + 1 - len(states[i]))
    before = [states[i][row - 1] for i in range(n)]
    moving = {i for i in range(n) if before[i][0] != before[i][1]}
    working = {d.agv for i in range(n) for d in dwells[i]
               if d.tick <= row - 1 < d.tick + d.ticks}
    g = given_t[min(row - 1, len(given_t) - 1)]
    working |= {f.agv for f in plan.failures if f.tick <= g < f.tick + f.ticks}  # down
    blocked = {v for i in moving for v in _cells(before[i][1], sizes[i], cols)}
    pos = np.asarray([[divmod(s[0], cols) for s in before],
                      [divmod(states[i][row][0], cols) for i in range(n)]])
    given_tick = given_t[min(row, len(given_t) - 1)]
    try:
        moves, agents = _detour(pos, 1, cyc, floor, sizes, cols, plan.source, given_tick,
                                blocked=frozenset(blocked),
                                fixed=frozenset(moving | working))
    except PlanError as err:
        raise WareroverError(f"{plan.source}: {err}") from None
    return before, moves, agents, given_tick


def _insert_detour(states: dict[int, list], before: list, moves: list, agents,
                   row: int) -> dict[int, int]:
    """For :func:`repair_rotations`: the detour's ticks inserted before ``row`` (its AGVs
    make its moves, every other AGV waits where it next stands); per AGV shifted, the index
    after which the ticks went in."""
    length = len(moves)
    detour = {a: [] for a in agents}
    cur = {a: before[a][0] for a in agents}
    for a, cell in moves:
        cur[a] = cell
        for b in agents:
            detour[b].append((cur[b], cur[b]))
    stops = {}  # AGV -> index after which the detour ticks are inserted
    for i in range(len(states)):
        if i in detour:
            stops[i] = row - 1
            states[i][row:row] = detour[i]
            continue
        p = next((t for t in range(row - 1, len(states[i]))
                  if states[i][t][0] == states[i][t][1]), len(states[i]) - 1)
        if p >= len(states[i]) - 1:
            continue  # nothing left to do after it: nothing to shift
        stops[i] = p
        states[i][p + 1:p + 1] = [states[i][p]] * length
    return stops


def _cells(anchor: int, k: int, cols: int) -> tuple[int, ...]:
    from ..planning.paths import footprint_nodes

    return footprint_nodes(anchor, k, cols)


def _rotations(states: dict[int, list], n: int, cols: int, start: int) -> list:
    """The rotations (:class:`warerover_phys.execute.Cycle`) of per-AGV state lists from
    row ``start`` on (anchors: the cell each AGV stands on or leaves)."""
    from ..execute import _cycles_dense

    horizon = max(len(s) for s in states.values())
    pos = np.empty((horizon, n, 2), dtype=np.int64)
    for i in range(n):
        a = np.asarray([s[0] for s in states[i]] + [states[i][-1][0]] *
                       (horizon - len(states[i])), dtype=np.int64)
        pos[:, i, 0], pos[:, i, 1] = a // cols, a % cols
    return _cycles_dense(pos, cols, start=start)


def _insert_rows(a: np.ndarray, length: int, stops: dict[int, int]) -> np.ndarray:
    """``a`` (T, N), per-tick values of each AGV, with ``length`` copies of row ``p`` of
    column ``i`` inserted after it for every ``i: p`` of ``stops``; the other columns (and
    columns whose stop is past the end) go on with their last value."""
    T = a.shape[0]
    out = np.concatenate([a, np.repeat(a[-1:], length, axis=0)])
    for i, p in stops.items():
        if p >= T - 1:
            continue
        out[p + 1:p + 1 + length, i] = a[p, i]
        out[p + 1 + length:, i] = a[p + 1:, i]
    return out


def _check_repaired(given: TimedPlan, repaired: TimedPlan) -> None:
    """The independent validator on the repaired plan (a bug, if it finds a conflict the
    plan as given did not have)."""
    from ..errors import WareroverError
    from ..validate import validate_states

    obstacles = given.layout.obstacles
    sizes = {i: t.footprint for i, t in enumerate(given.types)}
    speeds = {i: t.ticks_per_move(given.layout.cell_m, given.tick_s)
              for i, t in enumerate(given.types)}

    def check(p: TimedPlan) -> list:
        return validate_states({i: list(x.states) for i, x in p.paths.items()}, obstacles,
                               sizes=sizes, ticks_per_move=speeds)

    found = check(repaired)
    if found and not check(given):
        raise WareroverError(f"{given.source}: the rotation repair made a plan with "
                             f"conflicts (a bug): {found[:3]}")


# ----------------------------------------------------------------------------- imported plan

def plan_from_file(floor: str, plan_file: str, fleet: str | None = None, *,
                   fmt: str | None = None, xy: bool = True, strict: bool = False,
                   tick_s: float = 1.0) -> tuple[TimedPlan, list]:
    """An imported MAPF plan (read, validated and cycle-repaired as ``warerover execute``
    does) as a :class:`TimedPlan` without dwells; returns it and the repairs made."""
    from ..execute import load_fleet, load_floor, plan_to_paths, repair_cycles, validate_plan
    from ..plans import read_plan

    layout, types_by_name, kinds = load_floor(floor)
    the_plan = read_plan(plan_file, fmt, xy=xy)
    types = load_fleet(fleet, the_plan.num_agents, types_by_name, kinds)
    sizes = [t.footprint for t in types]
    validate_plan(the_plan, layout, sizes, source=str(plan_file))
    the_plan, repairs = repair_cycles(the_plan, layout, sizes, strict=strict,
                                      source=str(plan_file))
    if repairs:
        validate_plan(the_plan, layout, sizes, source=str(plan_file))
    given = plan_to_paths(read_plan(plan_file, fmt, xy=xy), layout.cols) if repairs else None
    paths = plan_to_paths(the_plan, layout.cols)
    out = TimedPlan(layout=layout, types=list(types), tick_s=tick_s, paths=paths,
                    dwells={}, source=f"plan file {plan_file}", repairs=tuple(repairs))
    if given is not None:  # the planned side stays the plan as given
        as_given = TimedPlan(layout=layout, types=list(types), tick_s=tick_s, paths=given,
                             dwells={}, source="")
        out.given_finish = tuple(as_given.planned_finish(i) for i in range(len(given)))
    return out, repairs
