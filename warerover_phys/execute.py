"""One fixed plan, executed as written: no scheduler, no planner, no replanning.

``warerover execute FLOOR --plan FILE`` is built from the pieces here:

1. :func:`load_floor`: a MovingAI ``.map`` (free cells and obstacles are all that matter), a
   layout YAML or a scenario YAML becomes a :class:`~warerover_phys.layout.Layout`;
   :func:`load_fleet` gives every agent an AGV type (default: 1x1, 0.7 m bodies, 1 m/s).
2. :func:`validate_plan`: the plan against the floor and the fleet, vectorised over
   timesteps (bounds, obstacles, jumps of more than one cell, vertex / footprint and swap
   conflicts). The first problem is raised as one line naming the agent, the timestep and
   the cells (:class:`PlanError`).
3. :func:`find_cycles`: groups of agents that move round a cycle in one timestep (a
   *rotation*: each enters the cell the next one leaves). The action dependency graph has no
   order for them and bodies turning a block in lockstep overlap. :func:`repair_cycles`
   replaces each rotation by a *local detour*: single-cell moves, one agent at a time, that
   take the rotation's agents to the cells the rotation gives them while everyone else
   stands (A* on the joint state of the rotation's agents within a few cells of it; if they
   alone have no way, the 1x1 agents next to it may step aside and back). The detour's moves
   are inserted before the rotation's timestep; then the whole plan is *re-timed*: each
   agent makes its moves in turn, never before its timestep in the given plan, each cell is
   visited in the same order as before, following is kept and no cycle is formed. Agents
   that do not wait on a detour keep their timing exactly; a plan without rotations comes
   back unchanged. Each repair is reported; ``strict=True`` raises instead. A rotation that
   no detour within :data:`DETOUR_STAGES` can replace (for example four agents on a floor
   with one free cell: a sliding puzzle cannot make a quarter turn of four) is refused with
   one line naming it.
4. :func:`execute_plan`: the executor (``grid``, ``physics`` or a plug-in) follows exactly
   that plan. The result has planned and executed makespan and sum of costs, per-agent
   finish times, the executor's figures and the executed states per tick.

Times: the plan's timestep is one tick of ``tick_s`` seconds (default 1 s). Executed finish
times are in ticks (an agent has finished at the first tick from which it stands at its final
cell for good).
"""

from __future__ import annotations

import heapq
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from .config import AgvTypeSpec, DelaySpec, ExecutorSpec
from .errors import ScenarioError, WareroverError
from .executors.base import AgvBody, ExecutorSetup, StepReport, TickView, record_report
from .layout import CellType, Layout
from .planning.paths import State, TimedPath
from .plans.model import Plan

__all__ = ["PlanError", "Repair", "ExecutionResult", "load_floor", "load_fleet", "robot_model",
           "validate_plan", "find_cycles", "repair_cycles", "plan_to_paths", "execute_plan"]

DEFAULT_TYPE = AgvTypeSpec(body_m=(0.7, 0.7), max_speed_mps=1.0)
"""The AGV of ``execute`` when no fleet is given: 1x1, 0.7 m body, 1 m/s."""


class PlanError(WareroverError):
    """A plan that cannot be executed on this floor with this fleet."""

    def __init__(self, message: str, *, file: str | None = None, agent: int | None = None,
                 timestep: int | None = None, cells: tuple = ()) -> None:
        self.file, self.agent, self.timestep, self.cells = file, agent, timestep, cells
        where = f"{file}: " if file else ""
        parts = [f"agent {agent}" if agent is not None else "",
                 f"timestep {timestep}" if timestep is not None else ""]
        at = ", ".join(p for p in parts if p)
        super().__init__(f"{where}{at + ': ' if at else ''}{message}")


# ----------------------------------------------------------------------------- floor, fleet

def load_floor(path: str | Path) -> tuple[Layout, dict[str, AgvTypeSpec] | None, list[str]]:
    """The floor in ``path`` (``.map``, layout YAML or scenario YAML), the AGV types it
    names (scenarios only) and the type of each of its AGVs (scenarios only)."""
    from .inputs import check_regular_file

    path = check_regular_file(path, "floor")
    if path.suffix == ".map":
        from .problems.movingai import read_map

        m = read_map(path)
        grid = np.where(m.obstacles, CellType.OBSTACLE, CellType.FLOOR).astype(np.int8)
        layout = Layout(grid=grid, cell_m=1.0, shelves=(), stations=(), parking=(),
                        access_points=(), num_skus=0, name=path.stem)
        return layout, None, []
    from .config import LayoutSpec, load_scenario, read_yaml
    from .layout import build_layout

    data = read_yaml(path)
    if isinstance(data, dict) and ("fleet" in data or "layout" in data):
        sc = load_scenario(path)
        layout = build_layout(sc.layout, fleet_size=sc.fleet.size, file=str(path), name=sc.name)
        kinds = [g.type for g in sc.fleet.agvs for _ in range(g.count)]
        return layout, dict(sc.fleet.types), kinds
    try:
        spec = LayoutSpec.model_validate({k: v for k, v in data.items() if k != "name"})
    except Exception as err:  # noqa: BLE001 - pydantic's error, named below
        raise ScenarioError(f"not a layout or scenario ({str(err).splitlines()[0]})",
                            file=str(path)) from None
    if isinstance(spec.map, str):
        spec = spec.model_copy(update={"map": str((path.parent / spec.map).resolve())})
    return build_layout(spec, file=str(path), name=path.stem), None, []


def load_fleet(path: str | Path | None, n: int, scenario_types: dict[str, AgvTypeSpec] | None,
               scenario_kinds: list[str]) -> list[AgvTypeSpec]:
    """The AGV type of each of ``n`` agents.

    ``FLEET.yaml`` is either one type for every agent (``{footprint: 1, body_m: [0.7, 0.7],
    max_speed_mps: 1.0, ...}``) or ``{types: {NAME: {...}}, agents: [NAME, ...]}`` (one name
    per agent, or a single name for all). Without a file: the scenario's fleet if the floor
    is a scenario with ``n`` AGVs, else :data:`DEFAULT_TYPE`.
    """
    if path is None:
        if scenario_types and len(scenario_kinds) == n:
            return [scenario_types[k] for k in scenario_kinds]
        return [DEFAULT_TYPE] * n
    from pydantic import ValidationError

    from .config import read_yaml

    src = str(path)
    data = read_yaml(Path(path))
    if not isinstance(data, dict):
        raise ScenarioError("a fleet file is a mapping", file=src, value=data)
    try:
        if "types" not in data:
            return [AgvTypeSpec.model_validate(data)] * n
        if not isinstance(data["types"], dict) or not data["types"]:
            raise ScenarioError("expected a mapping of type names to AGV types", file=src,
                                field="types", value=data["types"])
        types = {k: AgvTypeSpec.model_validate(v) for k, v in data["types"].items()}
    except ValidationError as err:
        e = err.errors()[0]
        raise ScenarioError(e["msg"], file=src, field=".".join(map(str, e["loc"])),
                            value=e.get("input")) from None
    agents = data.get("agents", next(iter(types), None))
    if not isinstance(agents, str | list):
        raise ScenarioError("expected a type name or a list of them", file=src,
                            field="agents", value=agents)
    names = [agents] * n if isinstance(agents, str) else agents
    if len(names) != n:
        raise ScenarioError(f"lists {len(names)} agents but the plan has {n}", file=src,
                            field="agents", value=len(names))
    for i, name in enumerate(names):
        if not isinstance(name, str) or name not in types:
            raise ScenarioError(f"unknown AGV type (choose from {sorted(types)})", file=src,
                                field=f"agents[{i}]", value=name)
    return [types[name] for name in names]


# ----------------------------------------------------------------------------- validation

def _dense(plan: Plan) -> np.ndarray:
    """Cells as an array (T, N, 2), every path padded with its last cell."""
    horizon = plan.makespan + 1
    out = np.empty((horizon, plan.num_agents, 2), dtype=np.int64)
    for i, path in enumerate(plan.paths):
        arr = np.asarray(path, dtype=np.int64).reshape(-1, 2)
        out[:len(arr), i] = arr
        out[len(arr):, i] = arr[-1]
    return out


def validate_plan(plan: Plan, layout: Layout, sizes: list[int], *, source: str | None = None,
                  ) -> None:
    """Raise :class:`PlanError` for the first problem of ``plan`` on ``layout`` with AGVs
    of footprints ``sizes``: more agents than free cells, a map of another size, a cell off
    the map or on an obstacle, a jump of more than one cell, two agents on one cell (any
    footprint cell), or two agents passing through each other."""
    rows, cols = layout.rows, layout.cols
    n = plan.num_agents
    blocked = np.asarray(layout.grid) == CellType.OBSTACLE
    if plan.rows is not None and plan.cols is not None and (plan.rows, plan.cols) != (rows, cols):
        raise PlanError(f"plan is for a {plan.rows} x {plan.cols} map, the floor is "
                        f"{rows} x {cols}", file=source)
    free = int((~blocked).sum())
    if n > free:
        raise PlanError(f"{n} agents but the floor has only {free} free cells", file=source)
    if len(sizes) != n:
        raise PlanError(f"the fleet has {len(sizes)} AGVs, the plan {n} agents", file=source)
    pos = _dense(plan)
    k = np.asarray(sizes, dtype=np.int64)
    # Footprint cells: offsets (di, dj) for di, dj < k of each agent.
    kmax = int(k.max()) if n else 1
    for di in range(kmax):
        for dj in range(kmax):
            use = (di < k) & (dj < k)
            r, c = pos[:, use, 0] + di, pos[:, use, 1] + dj
            ids = np.flatnonzero(use)
            off = (r < 0) | (r >= rows) | (c < 0) | (c >= cols)
            if off.any():
                t, a = np.argwhere(off)[0]
                raise PlanError(f"cell {(int(r[t, a]), int(c[t, a]))} is off the {rows} x "
                                f"{cols} map", file=source, agent=int(ids[a]), timestep=int(t))
            hit = blocked[r, c]
            if hit.any():
                t, a = np.argwhere(hit)[0]
                raise PlanError(f"cell {(int(r[t, a]), int(c[t, a]))} is an obstacle",
                                file=source, agent=int(ids[a]), timestep=int(t))
    if len(pos) > 1:
        step = np.abs(np.diff(pos, axis=0)).sum(axis=2)
        jump = step > 1
        if jump.any():
            t, a = np.argwhere(jump)[0]
            raise PlanError(f"jumps from {tuple(map(int, pos[t, a]))} to "
                            f"{tuple(map(int, pos[t + 1, a]))} (more than one cell)",
                            file=source, agent=int(a), timestep=int(t + 1))
    _check_conflicts(pos, k, cols, source)


def _occupancy(pos: np.ndarray, k: np.ndarray, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Flat cells (T, M) covered by every agent's footprint, and the agent of each column."""
    cells, owners = [], []
    for di in range(int(k.max())):
        for dj in range(int(k.max())):
            use = np.flatnonzero((di < k) & (dj < k))
            cells.append((pos[:, use, 0] + di) * cols + pos[:, use, 1] + dj)
            owners.append(use)
    return np.concatenate(cells, axis=1), np.concatenate(owners)


def _check_conflicts(pos: np.ndarray, k: np.ndarray, cols: int, source: str | None) -> None:
    occ, owner = _occupancy(pos, k, cols)
    horizon = len(occ)
    order = np.argsort(occ, axis=1, kind="stable")
    srt = np.take_along_axis(occ, order, axis=1)
    dup = srt[:, 1:] == srt[:, :-1]
    if dup.any():
        t, j = np.argwhere(dup)[0]
        a, b = sorted((int(owner[order[t, j]]), int(owner[order[t, j + 1]])))
        cell = divmod(int(srt[t, j]), cols)
        raise PlanError(f"vertex conflict with agent {b} at cell {cell}", file=source, agent=a,
                        timestep=int(t))
    if horizon < 2:
        return
    # Swaps: agent a goes u -> v while agent b goes v -> u (anchor cells; for bigger
    # footprints a swap also overlaps at one of the two timesteps, caught above).
    anchors = pos[..., 0] * cols + pos[..., 1]
    src, dst = anchors[:-1], anchors[1:]
    moved = src != dst
    for t in np.flatnonzero(moved.any(axis=1)):
        m = np.flatnonzero(moved[t])
        fwd = {(int(src[t, a]), int(dst[t, a])): int(a) for a in m}
        for (u, v), a in fwd.items():
            b = fwd.get((v, u))
            if b is not None and a < b:
                raise PlanError(f"swap conflict with agent {b} between cells "
                                f"{divmod(u, cols)} and {divmod(v, cols)}", file=source,
                                agent=a, timestep=int(t + 1))


# ----------------------------------------------------------------------------- cycles

@dataclass(frozen=True)
class Cycle:
    """Agents that move round a cycle at ``timestep`` (each enters the cell the next one
    leaves), and the cells they occupy just before."""

    timestep: int
    agents: tuple[int, ...]
    cells: tuple[tuple[int, int], ...]


def find_cycles(plan: Plan, cols: int, sizes: list[int] | None = None) -> list[Cycle]:
    """Every rotation of ``plan`` (1x1 footprints; a bigger footprint's rotation needs a
    vertex conflict and is rejected by :func:`validate_plan`)."""
    return _cycles_dense(_dense(plan), cols)


def _cycles_dense(pos: np.ndarray, cols: int, start: int = 0) -> list[Cycle]:
    """The rotations of the dense plan ``pos`` (T, N, 2) at rows after ``start``."""
    if len(pos) - start < 2:
        return []
    anchors = pos[..., 0] * cols + pos[..., 1]
    out = []
    moving = (anchors[start + 1:] != anchors[start:-1]).any(axis=1)
    for t in np.flatnonzero(moving) + start:
        before, after = anchors[t], anchors[t + 1]
        moved = np.flatnonzero(before != after)
        at = {int(before[a]): int(a) for a in moved}
        nxt = {int(a): at.get(int(after[a])) for a in moved}  # whose cell a enters
        seen: set[int] = set()
        for a0 in nxt:
            if a0 in seen:
                continue
            chain, a = [], a0
            while a is not None and a not in seen and a not in chain:
                chain.append(a)
                a = nxt.get(a)
            seen.update(chain)
            if a is not None and a in chain:
                cyc = tuple(chain[chain.index(a):])
                out.append(Cycle(int(t + 1), cyc,
                                 tuple(tuple(map(int, pos[t, i])) for i in cyc)))
    return out


@dataclass(frozen=True)
class Repair:
    """One repaired rotation: the agents of its local detour, and how long the detour is."""

    timestep: int
    """The rotation's timestep in the plan as given."""
    agents: tuple[int, ...]
    """The agents that move in the detour: the rotation's, and neighbours that step aside
    and back."""
    cells: tuple[tuple[int, int], ...]
    """The rotation's cells (row, column) just before it."""
    moves: int
    """Single-cell moves of the detour that replaces the rotation's one timestep."""

    def as_dict(self) -> dict[str, Any]:
        return {"timestep": self.timestep, "agents": list(self.agents),
                "cells": [list(c) for c in self.cells], "moves": self.moves}


def repair_cycles(plan: Plan, layout: Layout, sizes: list[int], *, strict: bool = False,
                  source: str | None = None, max_rounds: int | None = None,
                  ) -> tuple[Plan, list[Repair]]:
    """Break every rotation with a local detour, then re-time the plan (see the module
    docstring). ``strict``: raise :class:`PlanError` naming the first rotation instead.
    ``max_rounds``: most rotations repaired (default: ten per agent). A plan without
    rotations comes back as it is."""
    cols = layout.cols
    pos = _dense(plan)
    cycles = _cycles_dense(pos, cols)
    if not cycles:
        return plan, []
    first = cycles[0]
    if strict:
        raise PlanError(f"agents {list(first.agents)} move round a cycle through cells "
                        f"{[list(c) for c in first.cells]} (no execution order exists; "
                        "drop --strict to repair it)", file=source, agent=first.agents[0],
                        timestep=first.timestep)
    floor = _PuzzleFloor(layout)
    release = np.arange(len(pos), dtype=np.int64)  # each row's timestep in the given plan
    repairs: list[Repair] = []
    limit = max_rounds if max_rounds is not None else 10 * max(1, plan.num_agents)
    while cycles:
        if len(repairs) >= limit:
            raise PlanError(f"rotations remain after {limit} repairs", file=source)
        cyc = cycles[0]
        row = cyc.timestep
        moves, agents = _detour(pos, row, cyc, floor, sizes, cols, source,
                                int(release[row]))
        pos, release = _splice(pos, release, row, moves, cols)
        repairs.append(Repair(int(release[row + len(moves)]), agents, cyc.cells, len(moves)))
        cycles = _cycles_dense(pos, cols, start=row - 1)
    paths = _retime(pos, release, sizes, cols)
    return Plan(paths, rows=plan.rows, cols=plan.cols, map_name=plan.map_name,
                meta=plan.meta, fmt=plan.fmt), repairs


DETOUR_EXPANSIONS = 100_000
"""Search budget (joint states expanded) of one local detour."""
DETOUR_STAGES = ((2, -1), (3, -1), (3, 1), (4, 2), (6, 3))
"""The detour searches tried in turn: (how far from the rotation's cells the detour may go,
how far from them other 1x1 agents may step aside and back; -1: none may)."""
DETOUR_HELPERS = 8
"""Most neighbours that step aside in one detour."""


class _PuzzleFloor:
    """The moves of one 1x1 AGV between flat cell indices."""

    def __init__(self, layout: Layout) -> None:
        from .planning.graph import GraphSet

        g = GraphSet(layout).get(1, False)
        self.neighbors = g.neighbors
        self.through = g.expandable_flat  # sinks (shelves ...) only as an agent's own cell


def _detour(pos: np.ndarray, row: int, cyc: Cycle, floor: _PuzzleFloor, sizes: list[int],
            cols: int, source: str | None, given_t: int, *,
            blocked: frozenset[int] = frozenset(), fixed: frozenset[int] = frozenset(),
            ) -> tuple[list[tuple[int, int]], tuple[int, ...]]:
    """Single-cell moves ``(agent, flat cell)``, one at a time, that take the rotation's
    agents from their cells at ``row - 1`` to their cells at ``row`` while everyone else
    stands (stages: :data:`DETOUR_STAGES`), and the agents that move. ``blocked``: more
    flat cells the detour may not use; ``fixed``: agents that may not step aside (the
    open-loop gap's recorded plans: AGVs mid-move or at work)."""
    before, after = pos[row - 1], pos[row]
    flat_b = before[:, 0] * cols + before[:, 1]
    flat_a = after[:, 0] * cols + after[:, 1]
    ring = list(cyc.agents)
    ring_cells = {int(flat_b[i]) for i in ring}
    k = np.asarray(sizes)
    for radius, helper_radius in DETOUR_STAGES:
        region = _region(floor, ring_cells, radius)
        helpers: list[int] = []
        if helper_radius >= 0:
            near = _region(floor, ring_cells, helper_radius)
            helpers = [int(i) for i in np.flatnonzero(k == 1)
                       if int(i) not in cyc.agents and int(i) not in fixed
                       and int(flat_b[i]) in near]
            helpers = helpers[:DETOUR_HELPERS]
        agents = ring + helpers
        free = region - _footprints(before, k, cols, exclude=set(agents)) - blocked
        starts = [int(flat_b[i]) for i in agents]
        goals = [int(flat_a[i]) for i in ring] + starts[len(ring):]
        found = _solve_puzzle(floor, free, starts, goals)
        if found is not None:
            return ([(agents[a], cell) for a, cell in found],
                    tuple(sorted({agents[a] for a, _ in found})))
    raise PlanError(f"cannot repair the rotation of agents {ring} through cells "
                    f"{[list(c) for c in cyc.cells]}: no local detour within "
                    f"{DETOUR_STAGES[-1][0]} cells of it (run with --strict to see it, or "
                    "fix the plan)", file=source, agent=ring[0], timestep=given_t)


def _footprints(cells: np.ndarray, k: np.ndarray, cols: int, exclude: set[int]) -> set[int]:
    """Flat cells covered by the agents at ``cells`` (anchors, footprints ``k``), but those
    of the agents in ``exclude``."""
    out: set[int] = set()
    for i, (r, c) in enumerate(cells.tolist()):
        if i in exclude:
            continue
        for dr in range(int(k[i])):
            for dc in range(int(k[i])):
                out.add((r + dr) * cols + c + dc)
    return out


def _region(floor: _PuzzleFloor, cells: set[int], radius: int) -> set[int]:
    """Cells within ``radius`` moves of ``cells``."""
    seen = set(cells)
    frontier = list(cells)
    for _ in range(radius):
        nxt = []
        for u in frontier:
            for v in floor.neighbors[u]:
                if v not in seen:
                    seen.add(v)
                    nxt.append(v)
        frontier = nxt
    return seen


def _solve_puzzle(floor: _PuzzleFloor, free: set[int], starts: list[int],
                  goals: list[int]) -> list[tuple[int, int]] | None:
    """Fewest single-cell moves ``(agent index, cell)``, one agent at a time, each into an
    empty cell of ``free``, from ``starts`` to ``goals``: A* on the joint state with the sum
    of distances as its (admissible) heuristic. None if there is none within
    :data:`DETOUR_EXPANSIONS`."""
    own = set(starts) | set(goals)
    usable = {v for v in free if floor.through[v] or v in own}
    dist = []
    for g in goals:  # breadth-first distances to each goal within the usable cells
        d = {g: 0}
        frontier = [g]
        while frontier:
            nxt = []
            for u in frontier:
                for v in floor.neighbors[u]:
                    if v in usable and v not in d:
                        d[v] = d[u] + 1
                        nxt.append(v)
            frontier = nxt
        dist.append(d)
    start, goal = tuple(starts), tuple(goals)
    if any(s not in d for s, d in zip(start, dist, strict=True)):
        return None
    parent: dict[tuple[int, ...], tuple[tuple[int, ...], int, int] | None] = {start: None}
    cost = {start: 0}
    h0 = sum(d[c] for c, d in zip(start, dist, strict=True))
    heap = [(h0, 0, start)]
    expanded = 0
    while heap:
        _, g_cost, state = heapq.heappop(heap)
        if state == goal:
            moves = []
            while (link := parent[state]) is not None:
                state, a, cell = link
                moves.append((a, cell))
            return moves[::-1]
        if g_cost > cost[state]:
            continue
        expanded += 1
        if expanded > DETOUR_EXPANSIONS:
            return None
        taken = set(state)
        h = sum(d[c] for c, d in zip(state, dist, strict=True))
        for a, u in enumerate(state):
            da = dist[a]
            for v in floor.neighbors[u]:
                if v in taken or v not in da:
                    continue
                nxt = state[:a] + (v,) + state[a + 1:]
                ng = g_cost + 1
                if ng < cost.get(nxt, 1 << 60):
                    cost[nxt] = ng
                    parent[nxt] = (state, a, v)
                    heapq.heappush(heap, (ng + h - da[u] + da[v], ng, nxt))
    return None


def _splice(pos: np.ndarray, release: np.ndarray, row: int, moves: list[tuple[int, int]],
            cols: int) -> tuple[np.ndarray, np.ndarray]:
    """``pos`` with one row per detour move inserted before ``row``, everyone else
    standing; the detour ends where ``row`` has its agents (the rotation's agents stand
    through ``row``, the others make their own moves of ``row``). The inserted rows are
    released at the rotation's timestep."""
    cur = pos[row - 1].copy()
    rows = []
    for agent, cell in moves:
        cur = cur.copy()
        cur[agent] = divmod(cell, cols)
        rows.append(cur)
    new = np.concatenate([pos[:row], np.asarray(rows).reshape(-1, *pos.shape[1:]),
                          pos[row:]])
    rel = np.concatenate([release[:row], np.full(len(rows), release[row]), release[row:]])
    return new, rel


def _retime(pos: np.ndarray, release: np.ndarray, sizes: list[int], cols: int,
            ) -> tuple[tuple[tuple[int, int], ...], ...]:
    """The plan ``pos`` executed as early as its order allows, no move before its own
    timestep in the given plan (``release``): each agent makes its moves in turn, each cell
    is visited in the same order as in ``pos``, and an agent may enter a cell in the
    timestep its last visitor leaves it (following), but never round a cycle. A plan without
    detours comes back unchanged; a detour delays only what waits on it."""
    n = pos.shape[1]
    k = [int(s) for s in sizes]

    def cells_of(p: np.ndarray, i: int) -> frozenset[int]:
        r, c = int(p[0]), int(p[1])
        return frozenset((r + dr) * cols + c + dc for dr in range(k[i]) for dc in range(k[i]))

    anchors = pos[..., 0] * cols + pos[..., 1]
    changed = anchors[1:] != anchors[:-1]
    # Each agent's moves (release, cells entered, cells left, new anchor), and every visit
    # to a cell as (row it starts, agent, move index; -1 for where the agent starts).
    moves: list[list[tuple[int, frozenset[int], frozenset[int], tuple[int, int]]]] = []
    starts: list[tuple[int, int, int, int]] = []
    holder: dict[int, int] = {}
    for i in range(n):
        occ = cells_of(pos[0, i], i)
        for v in occ:
            holder[v] = i
        mine = []
        for s in (np.flatnonzero(changed[:, i]) + 1).tolist():
            new = cells_of(pos[s, i], i)
            starts.extend((s, i, len(mine), v) for v in new - occ)
            mine.append((int(release[s]), new - occ, occ - new,
                         (int(pos[s, i, 0]), int(pos[s, i, 1]))))
            occ = new
        moves.append(mine)
    starts.sort()
    turn: dict[tuple[int, int, int], int] = {}  # (cell, agent, move) -> its place at the cell
    count: dict[int, int] = {}
    for _, i, m, v in starts:
        count[v] = count.get(v, 0) + 1
        turn[(v, i, m)] = count[v]  # visit 0 is the cell's first occupant (or none)
    begun = dict.fromkeys(count, 0)  # visits begun at each cell after the first
    ptr = [0] * n
    out: list[list[tuple[int, int]]] = [[(int(pos[0, i, 0]), int(pos[0, i, 1]))]
                                        for i in range(n)]
    pending = sum(len(m) for m in moves)
    tick = 0
    while pending:
        tick += 1
        ready = [i for i in range(n) if ptr[i] < len(moves[i])
                 and moves[i][ptr[i]][0] <= tick
                 and all(turn[(v, i, ptr[i])] == begun[v] + 1 for v in moves[i][ptr[i]][1])]
        chosen: set[int] = set()
        waiting: dict[int, list[int]] = {}
        work = list(ready)
        while work:
            i = work.pop()
            if i in chosen:
                continue
            entered = moves[i][ptr[i]][1]
            ok = True
            for v in entered:
                h = holder.get(v)
                if h is None:
                    continue
                if h not in chosen:
                    waiting.setdefault(h, []).append(i)  # it may follow h this timestep
                    ok = False
                    break
                if v not in moves[h][ptr[h]][2]:
                    ok = False  # h moves but keeps this cell
                    break
            if ok:
                chosen.add(i)
                work.extend(waiting.pop(i, []))
        if not chosen:
            if all(moves[i][ptr[i]][0] <= tick for i in range(n) if ptr[i] < len(moves[i])):
                raise AssertionError("re-timing a cycle-free plan stalled")  # pragma: no cover
            for i in range(n):
                out[i].append(out[i][-1])
            continue
        for i in chosen:
            for v in moves[i][ptr[i]][2]:
                if holder.get(v) == i:
                    del holder[v]
        for i in chosen:
            for v in moves[i][ptr[i]][1]:
                holder[v] = i
                begun[v] += 1
            out[i].append(moves[i][ptr[i]][3])
            ptr[i] += 1
            pending -= 1
        for i in range(n):
            if i not in chosen:
                out[i].append(out[i][-1])
    return tuple(_trim(p) for p in out)


def _trim(path: list[tuple[int, int]]) -> tuple[tuple[int, int], ...]:
    """``path`` without the copies of its last cell at its end."""
    end = len(path)
    while end > 1 and path[end - 2] == path[-1]:
        end -= 1
    return tuple(path[:end])


# ----------------------------------------------------------------------------- execution

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
    from .registry import build
    from .util.gc_tuning import long_loop

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


# ----------------------------------------------------------------------------- outputs

def write_execution(result: ExecutionResult, plan: Plan, layout: Layout,
                    types: list[AgvTypeSpec], out_dir: str | Path, tick_s: float,
                    ) -> dict[str, Path]:
    """``metrics.json``, ``events.jsonl``, ``paths.json`` (planned = the executed plan,
    actual = executed states per tick, the same structure as ``warerover run`` writes),
    ``agents.csv`` (planned vs executed finish per agent) and ``trajectories.npz`` (physics;
    a per-tick one on the grid), written as one set (see :mod:`warerover_phys.util.atomic`)."""
    import csv
    import io
    import json

    from .outputs import _savez
    from .util.atomic import write_set

    cols = layout.cols
    paths = {
        "agvs": {str(i): {"type": "execute", "footprint": t.footprint, "ticks_per_move": 1}
                 for i, t in enumerate(types)},
        "planned": [{"agv": i, "tick": 0, "states": [[list(c), list(c)] for c in p]}
                    for i, p in enumerate(plan.paths)],
        "actual": {str(i): [[list(divmod(a, cols)), list(divmod(b, cols))] for a, b in s]
                   for i, s in result.executed.items()},
    }
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["agent", "planned_finish_tick", "executed_finish_tick", "lost_ticks"])
    for i, (p, e) in enumerate(zip(result.planned_finish, result.executed_finish,
                                   strict=True)):
        w.writerow([i, p, e, e - p])
    metrics = {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
               for k, v in result.metrics.items()}
    metrics["cycle_repairs_detail"] = [r.as_dict() for r in result.repairs]
    texts = {
        "metrics.json": json.dumps(metrics, indent=2, sort_keys=True, default=float) + "\n",
        "events.jsonl": "".join(json.dumps(e, sort_keys=True) + "\n" for e in result.events),
        "paths.json": json.dumps(paths, separators=(",", ":")) + "\n",
        "agents.csv": buf.getvalue(),
    }
    traj = result.trajectory if result.trajectory is not None else \
        _grid_trajectory(result, layout, types, tick_s, plan)
    traj.setdefault("corridors_json", np.array("[]"))
    writers: dict[str, Callable[[Path], object]] = {
        name: (lambda p, text=text: p.write_text(text, encoding="utf-8"))
        for name, text in texts.items()}
    writers["trajectories.npz"] = lambda p: _savez(p, traj)
    written = write_set(out_dir, writers, meta={"plan": plan.meta.get("source", ""),
                                                "agents": plan.num_agents})
    names = {"metrics.json": "metrics", "events.jsonl": "events", "paths.json": "paths",
             "agents.csv": "agents", "trajectories.npz": "trajectory"}
    files = {names[n]: p for n, p in written.items()}
    return files


def _grid_trajectory(result: ExecutionResult, layout: Layout, types: list[AgvTypeSpec],
                     tick_s: float, plan: Plan | None = None) -> dict[str, np.ndarray]:
    """One sample per tick of the executed states (the renderer's grid poses), with what
    each agent was doing against ``plan``'s paths."""
    from .executors.grid_record import grid_execution, state_array
    from .poses import states_poses

    k = np.array([t.footprint for t in types], dtype=np.int64)
    pos, heading = states_poses(result.executed, k, layout.cols, float(layout.cell_m))
    ticks, n = heading.shape
    cols = layout.cols
    plans = [] if plan is None else [
        (i, 0, [(r * cols + c, r * cols + c) for r, c in p]) for i, p in enumerate(plan.paths)]
    execution = grid_execution(state_array(result.executed, n, ticks), plans, k, cols,
                               layout.rows)
    return {**execution, "t": np.arange(ticks, dtype=np.float64) * tick_s, "x": pos[..., 0],
            "y": pos[..., 1], "heading": heading,
            "state": np.zeros((ticks, n), dtype=np.int8),
            "loaded": np.zeros((ticks, n), dtype=bool), "footprint": k,
            "body_m": np.array([t.body_m for t in types], dtype=np.float64),
            "cell_m": np.array(float(layout.cell_m)), "tick_s": np.array(float(tick_s)),
            "grid": np.asarray(layout.grid).copy()}


def executed_plan(result: ExecutionResult, cols: int) -> Plan:
    """The executed paths as a plan (one cell per tick: the cell an agent is leaving while
    it moves), for ``--export``."""
    return Plan(tuple(tuple(divmod(a, cols) for a, _ in states)
                      for _, states in sorted(result.executed.items())))


def executor_spec(name: str, *, dt_s: float = 0.02, delays: DelaySpec | None = None,
                  trajectory_hz: float = 10.0, params: dict | None = None,
                  options: dict[str, Any] | None = None,
                  source: str = "--set") -> ExecutorSpec:
    """The executor section of an execution: ``name`` and the command line's own settings,
    plus ``options`` (other :class:`~warerover_phys.config.ExecutorSpec` fields, by name),
    validated by the schema; a bad one raises :class:`ScenarioError` naming ``source``'s
    field and value."""
    from pydantic import ValidationError

    options = dict(options or {})
    own = {"name", "params", "dt_s", "delays", "trajectory_hz"} & set(options)
    if own:
        key = sorted(own)[0]
        raise ScenarioError("set it with its own option (--executor, --dt-s, --delays)",
                            file="<command line>", field=f"{source} executor.{key}",
                            value=options[key])
    try:
        return ExecutorSpec(name=name, params=params or {}, dt_s=dt_s,
                            delays=delays or DelaySpec(), trajectory_hz=trajectory_hz,
                            **options)
    except ValidationError as err:
        e = err.errors()[0]
        loc = ".".join(str(p) for p in e["loc"])
        msg = "unknown executor option" if e["type"] == "extra_forbidden" else e["msg"]
        raise ScenarioError(msg.removeprefix("Value error, "), file="<command line>",
                            field=f"{source} executor.{loc}" if loc else source,
                            value=e.get("input")) from None


def executor_options(texts: list[str] | None) -> dict[str, Any]:
    """``["no_slip=true", "executor.comm_latency_s=0.2"]`` (``--set`` of ``warerover
    execute``; the ``executor.`` prefix is optional; values are YAML) as a dict."""
    from .config import parse_override

    out: dict[str, Any] = {}
    for text in texts or []:
        try:
            key, value = parse_override(text)
        except ScenarioError as err:
            raise err.with_file("<command line>") from None
        key = key.removeprefix("executor.")
        if not key or "." in key:
            raise ScenarioError("expected an executor field: --set FIELD=VALUE (e.g. "
                                "no_slip=true)", file="<command line>", field="--set",
                                value=text)
        out[key] = value
    return out


REORDER_MODES = ("none", "greedy", "milp")


def check_reorder(mode: str) -> str:
    """``--reorder`` (``executor.reorder``): one of :data:`REORDER_MODES`, else a
    :class:`~warerover_phys.errors.WareroverError` naming the option and the value."""
    if mode not in REORDER_MODES:
        raise WareroverError(f"--reorder must be none, greedy or milp (got {mode!r})")
    return mode


def robot_model(options: dict[str, Any], types: list[AgvTypeSpec]
                ) -> tuple[dict[str, Any], list[AgvTypeSpec]]:
    """``--set robot=diffdrive`` of ``warerover execute`` (a key of ``options`` from
    :func:`executor_options`): the executor options and AGV types with the preset of a
    scenario's ``robot: diffdrive`` (:func:`~warerover_phys.config.diffdrive_preset`:
    ``no_slip`` on, wheel limits for differential-drive types that give none); ``robot``
    is taken out of the options. ``default`` or no ``robot``: unchanged."""
    from pydantic import ValidationError

    from .config import diffdrive_preset

    options = dict(options)
    robot = options.pop("robot", "default")
    if robot == "default":
        return options, types
    if robot != "diffdrive":
        raise ScenarioError("expected default or diffdrive", file="<command line>",
                            field="--set robot", value=robot)
    if options.get("no_slip") is False:
        raise ScenarioError("robot=diffdrive drives without side slip; no_slip=false "
                            "contradicts it", file="<command line>", field="--set no_slip",
                            value=False)
    unique = {t: f"t{k}" for k, t in enumerate(dict.fromkeys(types))}  # (frozen: hashable)
    raw = diffdrive_preset({"fleet": {"types": {name: t.model_dump(exclude_none=True)
                                                for t, name in unique.items()}}})
    try:
        made = {k: AgvTypeSpec.model_validate(v) for k, v in raw["fleet"]["types"].items()}
    except ValidationError as err:
        raise ScenarioError(err.errors()[0]["msg"], file="<command line>",
                            field="--set robot") from None
    return {**options, "no_slip": True}, [made[unique[t]] for t in types]


def parse_delays(text: str | None) -> DelaySpec:
    """``MODEL:PROB[:MIN_TICKS:MAX_TICKS]`` (``bernoulli:0.05:1:10``) as a DelaySpec."""
    if not text:
        return DelaySpec()
    from pydantic import ValidationError

    parts = text.split(":")
    keys = ["model", "prob", "min_ticks", "max_ticks"]
    if len(parts) not in (2, 4) or parts[0] not in ("none", "bernoulli", "poisson"):
        raise WareroverError(f"--delays: expected MODEL:PROB[:MIN_TICKS:MAX_TICKS] with MODEL "
                             f"bernoulli or poisson (got {text!r})")
    values: dict[str, object] = {"model": parts[0]}
    for key, part, kind in zip(keys[1:], parts[1:], (float, int, int), strict=False):
        try:  # the command line gives text: numbers are read here, ranges checked below
            values[key] = kind(part)
        except ValueError:
            what = "a number" if kind is float else "a whole number of ticks"
            raise WareroverError(f"--delays: {key}: expected {what} (got {part!r} in "
                                 f"{text!r})") from None
    try:
        return DelaySpec.model_validate(values)
    except ValidationError as err:
        e = err.errors()[0]
        where = e["loc"][0] if e["loc"] else "MIN_TICKS:MAX_TICKS"
        raise WareroverError(f"--delays: {where}: {e['msg']} (got {text!r})") from None
