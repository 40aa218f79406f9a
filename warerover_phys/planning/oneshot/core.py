"""One-shot MAPF on a plain grid (MovingAI instances): every agent from its start to its goal.

>>> import numpy as np
>>> from warerover_phys.planning.oneshot.core import solve
>>> free = np.zeros((3, 3), dtype=bool)
>>> result = solve(free, [(0, 0), (2, 2)], [(2, 2), (0, 0)], planner="lacam", time_limit_s=5)
>>> result.success, result.lower_bound
(True, 8)
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ...errors import PlanningError
from ...layout import CellType, Layout
from ..graph import UNREACHABLE, MotionGraph

__all__ = ["OneShotResult", "grid_graph", "goal_tables", "solve", "write_plan", "ONESHOT_PLANNERS",
           "warm_up"]

Cell = tuple[int, int]


@dataclass
class OneShotResult:
    """Paths (one list of cells per agent, all padded to the makespan) and their figures."""

    success: bool
    paths: list[list[Cell]] = field(default_factory=list)
    sum_of_costs: int = 0
    """Sum over agents of the last tick at which the agent arrives at its goal for good."""
    makespan: int = 0
    lower_bound: int = 0
    """Sum of single-agent shortest-path lengths."""
    wall_s: float = 0.0
    planner: str = ""
    stats: dict = field(default_factory=dict)

    @property
    def soc_ratio(self) -> float:
        return self.sum_of_costs / self.lower_bound if self.lower_bound else 1.0


def grid_graph(obstacles: np.ndarray) -> MotionGraph:
    """The 1x1 motion graph of a bare obstacle grid."""
    grid = np.where(obstacles, CellType.OBSTACLE, CellType.FLOOR).astype(np.int8)
    layout = Layout(grid=grid, cell_m=1.0, shelves=(), stations=(), parking=(),
                    access_points=(), num_skus=0, name="grid")
    return MotionGraph(layout, 1, False)


def goal_tables(graph: MotionGraph, goals: list[Cell], engine: str = "python",
                ) -> list[np.ndarray]:
    """Per goal, the moves from every node to it: the same read-only int32 tables as
    :meth:`MotionGraph.dist_to` (:data:`UNREACHABLE` where none), for all the goals at once
    by :func:`_grid_bfs` where ``graph``'s moves are the plain 4-neighbour ones (else by
    ``dist_to``), and left in ``graph``'s table cache (while it has room) for the planners
    that ask ``graph`` for them. ``engine="numba"``: on a plain grid, one compiled
    breadth-first search per goal instead (:func:`.scatter_numba.goal_bfs`, the same tables;
    for a process that loads numba anyway: 0.055 s of CPU for 700 goals on the MovingAI
    warehouse map where the bit-parallel search takes 0.15 s, best of three, load ~4.7)."""
    cache = graph._tables
    wanted = list(dict.fromkeys(graph.node(g) for g in goals))
    out = {g: cache[g] for g in wanted if g in cache}
    todo = [g for g in wanted if g not in out]
    plain = bool(todo) and _plain_grid(graph)
    if plain and engine == "numba":
        from .scatter_kernels import goal_bfs

        valid = np.asarray(graph.expandable_flat, dtype=bool)
        enter = np.asarray(graph.enterable, dtype=bool)
        for g, table in zip(todo, goal_bfs(valid, enter, graph.rows, graph.cols, todo),
                            strict=True):
            table.setflags(write=False)
            out[g] = table
            if len(cache) < graph._cap:
                cache[g] = table
        todo = []
    for start in range(0, len(todo), _BFS_CHUNK):
        chunk = todo[start:start + _BFS_CHUNK]
        if not plain:
            out.update((g, graph.dist_to(divmod(g, graph.cols))) for g in chunk)
            continue
        for g, table in zip(chunk, _grid_bfs(graph, chunk), strict=True):
            table.setflags(write=False)
            out[g] = table
            if len(cache) < graph._cap:
                cache[g] = table
    return [out[graph.node(goal)] for goal in goals]


_BFS_CHUNK = 512
"""Goals searched together by :func:`_grid_bfs` (8 words of 64 bits per cell)."""


def _plain_grid(graph: MotionGraph) -> bool:
    """Whether ``graph``'s moves (from expandable nodes) are exactly the moves from each
    expandable cell to each enterable 4-neighbour, as on a bare grid."""
    valid = np.asarray(graph.expandable_flat, dtype=bool).reshape(graph.rows, graph.cols)
    enter = np.asarray(graph.enterable, dtype=bool)
    pairs = int((valid[:, :-1] & enter[:, 1:]).sum() + (valid[:, 1:] & enter[:, :-1]).sum()
                + (valid[:-1] & enter[1:]).sum() + (valid[1:] & enter[:-1]).sum())
    starts, dst = graph._adj_src, graph._adj_dst
    src = np.repeat(np.arange(graph.num_nodes), np.diff(starts))
    from_valid = valid.ravel()[src]
    d = np.abs(dst[from_valid] - src[from_valid])
    return int(from_valid.sum()) == pairs and bool(np.all((d == 1) | (d == graph.cols)))


def _grid_bfs(graph: MotionGraph, goals: list[int]) -> list[np.ndarray]:
    """Breadth-first searches from many goals at once on a plain grid (:func:`_plain_grid`),
    bit-parallel: one bit per goal in each cell's words. The cells are laid out with a
    blank column after each row, so that a move is a shift of the flat array by 1 or by a
    row: a level of every search is then a few numpy operations over the whole grid (a cell
    is reached when it is expandable, not reached yet, and a 4-neighbour was reached the
    level before). The depths are kept bit-sliced (plane k holds bit k of every depth) and
    unpacked once at the end. The same move counts as :meth:`MotionGraph.dist_to` (a goal
    that is not enterable is reached from nowhere), without scipy: 0.2 s for 400 goals on a
    10,000-cell map where ``dist_to`` takes 0.3-0.6 s and scipy's import 0.4 s more."""
    rows, cols, m = graph.rows, graph.cols, len(goals)
    words = max(1, -(-m // 64))
    word = np.dtype("<u8")
    wide = cols + 1
    n = rows * wide

    def spread(mask: np.ndarray) -> np.ndarray:  # (rows, cols) bools -> (n, 1) words
        out = np.zeros((rows, wide), dtype=word)
        out[:, :cols][mask] = np.uint64(0xFFFF_FFFF_FFFF_FFFF)
        return out.reshape(n, 1)

    valid = np.asarray(graph.expandable_flat, dtype=bool).reshape(rows, cols)
    enter = np.asarray(graph.enterable, dtype=bool).ravel()
    seen = np.zeros((n, words), dtype=word)  # the goals (depth 0)
    for j, g in enumerate(goals):
        if enter[g]:
            r, c = divmod(g, cols)
            seen[r * wide + c, j // 64] |= np.uint64(1) << np.uint64(j % 64)
    front = seen.copy()
    open_ = spread(valid) & ~seen  # may still be reached: expandable, not reached yet
    reached = np.empty_like(front)
    planes: list[np.ndarray] = []
    level = 0
    while True:
        level += 1
        reached[:-1] = front[1:]  # moves by one column, then by one row, both ways
        reached[-1] = 0
        reached[1:] |= front[:-1]
        reached[:-wide] |= front[wide:]
        reached[wide:] |= front[:-wide]
        reached &= open_
        if not reached.any():
            break
        open_ ^= reached
        front, reached = reached, front
        for k in range(level.bit_length()):
            if k == len(planes):
                planes.append(np.zeros((n, words), dtype=word))
            if level >> k & 1:
                planes[k] |= front

    def unpack(bits: np.ndarray) -> np.ndarray:  # (n, words) -> (rows * cols, goals) 0/1
        flat = np.unpackbits(bits.view(np.uint8), axis=1, bitorder="little")[:, :m]
        return flat.reshape(rows, wide, m)[:, :cols].reshape(rows * cols, m)

    depth = np.zeros((rows * cols, m), dtype=np.uint16 if len(planes) <= 16 else np.int32)
    for k, plane in enumerate(planes):
        depth |= unpack(plane).astype(depth.dtype) << k
    out = np.ascontiguousarray(depth.T, dtype=np.int32)
    reach = (spread(valid) & ~open_) | seen  # reached: expandable and not open, or a goal
    out[unpack(reach).T == 0] = UNREACHABLE
    return list(out)


def _costs(paths: list[list[Cell]], goals: list[Cell]) -> tuple[int, int]:
    soc = 0
    for path, goal in zip(paths, goals, strict=True):
        t = len(path) - 1
        while t > 0 and path[t - 1] == goal:
            t -= 1
        soc += t
    return soc, max((len(p) - 1 for p in paths), default=0)


ONESHOT_PLANNERS = ("lacam", "pibt", "astar", "learned")


def solve(obstacles: np.ndarray, starts: list[Cell], goals: list[Cell], planner: str = "lacam",
          time_limit_s: float = 60.0, seed: int = 0, guide: bool = True,
          refine: bool = False, refine_iterations: int | None = None,
          on_improve: Callable[[float, int], None] | None = None) -> OneShotResult:
    """Solve a one-shot instance with the named planner; paths are not validated here
    (use :func:`warerover_phys.validate.validate_states`).

    ``guide`` (``lacam`` and ``pibt``): PIBT follows guide paths that spread the agents over
    the map (:mod:`~warerover_phys.planning.oneshot.scatter`), for first solutions of far lower cost.

    ``refine``: after the first solution, lower its sum of costs by large-neighbourhood
    search (:mod:`~warerover_phys.planning.refine.lns`) until ``REFINE_SHARE`` of the time limit
    has passed since the call (or after ``refine_iterations`` neighbourhoods); the plan stays
    valid throughout. ``on_improve(seconds, soc)`` is called after each improvement;
    ``stats["refine"]`` holds the first solution's SoC and the SoC after each improvement.
    """
    t0 = time.perf_counter()
    start_mono = time.monotonic()
    deadline = start_mono + time_limit_s
    graph = grid_graph(obstacles)
    # where lacam compiles its guide search and steps, the tables are compiled too
    from ..lacam.reference import lacam_kernels
    from .scatter import use_numba
    compiled = planner == "lacam" and use_numba(len(goals), deadline, also=lacam_kernels)
    tables = goal_tables(graph, goals, engine="numba" if compiled else "python")
    lb = 0
    for s, g, table in zip(starts, goals, tables, strict=True):
        d = 0 if s == g else int(table[graph.node(s)])
        if d >= UNREACHABLE:
            raise PlanningError(f"goal {g} cannot be reached from start {s}")
        lb += d
    if planner == "pibt":
        from ..pibt.reference import pibt_oneshot
        paths, stats = pibt_oneshot(graph, starts, goals, deadline, seed, guide=guide)
    elif planner == "lacam":
        from ..lacam.reference import lacam
        # lacam makes Python lists of the tables where its steps run in Python (PIBT reads
        # single entries, far faster from a list than from numpy); the compiled ones read these.
        paths, stats = lacam(graph, starts, goals, deadline, seed, guide=guide,
                             dist_arrays=tables)
    elif planner == "astar":
        paths, stats = _prioritized(graph, starts, goals, deadline)
    elif planner == "learned":
        from ..learned.planner import learned_oneshot
        paths, stats = learned_oneshot(graph, starts, goals, deadline, seed)
    else:
        raise PlanningError(f"unknown one-shot planner {planner!r} "
                            f"(choose from {', '.join(ONESHOT_PLANNERS)})")
    wall = time.perf_counter() - t0
    if paths is None:
        return OneShotResult(False, [], 0, 0, lb, wall, planner, stats)
    if refine:
        paths = _refine(graph, paths, goals, start_mono + REFINE_SHARE * time_limit_s, seed,
                        refine_iterations, on_improve, stats)
        wall = time.perf_counter() - t0
    soc, makespan = _costs(paths, goals)
    return OneShotResult(True, paths, soc, makespan, lb, wall, planner, stats)


REFINE_SHARE = 0.98
"""Refinement stops at this share of the time limit (after the call started), leaving the
rest for building the result; the CLI's validation comes on top."""


def _refine(graph: MotionGraph, paths: list[list[Cell]], goals: list[Cell], deadline: float,
            seed: int, iterations: int | None, on_improve, stats: dict) -> list[list[Cell]]:
    from ..refine.lns import refine

    cols = graph.cols
    nodes = [[r * cols + c for r, c in p] for p in paths]
    goal_nodes = [graph.node(g) for g in goals]
    dists = [graph.dist_to(g) for g in goals]
    first = _costs(paths, goals)[0]
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[1])
    res = refine(graph.neighbors, nodes, goal_nodes, dists, deadline, rng,
                 max_iterations=iterations, on_improve=on_improve)
    stats["refine"] = {"first_soc": first, "soc": res.sum_of_costs,
                       "history": [(round(t, 4), c) for t, c in res.history], **res.stats}
    horizon = max((len(p) for p in res.paths), default=1)
    return [[divmod(v, cols) for v in p] + [divmod(p[-1], cols)] * (horizon - len(p))
            for p in res.paths]


def _prioritized(graph: MotionGraph, starts: list[Cell], goals: list[Cell], deadline: float,
                 ) -> tuple[list[list[Cell]] | None, dict]:
    """Prioritized space-time A* (farthest agent first); fails if any agent finds no path."""
    from ..base import AgentRequest, PlanRequest
    from ..graph import GraphSet
    from ..reservation import ReservationTable
    from ..search.astar import AStarPlanner

    # Classic prioritized planning: an agent avoids the agents planned before it; those not
    # planned yet do not exist for it (they move out of its way when their turn comes).
    res = ReservationTable(graph.cols)
    agents = [AgentRequest(i, graph.node(s), graph.node(g), priority=(-graph.distance(s, g),))
              for i, (s, g) in enumerate(zip(starts, goals, strict=True))]
    graphs = GraphSet(graph.layout)
    graphs._graphs[(1, False)] = graph
    result = AStarPlanner(max_expansions=200_000, budget_per_move=None).plan(
        PlanRequest(0, agents, graphs, res, deadline=deadline))
    if result.failed or result.detours:
        return None, {"failed": len(result.failed) + len(result.detours)}
    horizon = max(p.end_tick for p in res.paths.values())
    cols = graph.cols
    return [[divmod(res.paths[i].state_at(t)[1], cols) for t in range(horizon + 1)]
            for i in range(len(starts))], {"expansions": result.expansions}


def write_plan(path, result: OneShotResult, *, map_file: str = "", scen_file: str = "") -> None:
    """Write a plan in the text format MAPF visualizers read: ``key=value`` header lines,
    then ``solution=`` and one line per timestep ``t:(x,y),(x,y),...`` (x = column,
    y = row, agents in scenario order)."""
    lines = [f"agents={len(result.paths)}", f"map_file={map_file}", f"scen_file={scen_file}",
             f"solver={result.planner}", f"solved={int(result.success)}",
             f"soc={result.sum_of_costs}", f"soc_lb={result.lower_bound}",
             f"makespan={result.makespan}", f"comp_time={round(result.wall_s * 1000)}",
             "solution="]
    paths = result.paths
    horizon = max((len(p) for p in paths), default=0)
    if any(len(p) != horizon for p in paths):  # hold each agent at its last cell
        paths = [list(p) + [p[-1]] * (horizon - len(p)) for p in paths]
    # Each cell's text once; then a timestep is a join of looked-up strings (3x faster at
    # 1,000 agents than formatting every entry).
    text = {cell: f"({cell[1]},{cell[0]})," for cell in set().union(*paths)}
    get = text.__getitem__
    lines += [f"{t}:" + "".join(map(get, column))
              for t, column in enumerate(zip(*paths, strict=True))]
    from pathlib import Path
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


def warm_up() -> float:
    """Compile the one-shot kernels (:mod:`.scatter_numba`'s and :mod:`.lacam_numba`'s) into
    numba's on-disk cache, or load them from it, on a 3 x 3 grid; returns the CPU seconds it
    took. ``solve`` compiles them by itself only with :data:`~.scatter.COLD_COMPILE_S`
    seconds to spare; this does it once ahead (``python -c "from
    warerover_phys.planning.oneshot.core import warm_up; print(warm_up())"``)."""
    from ..lacam.reference import lacam

    c = time.process_time()
    graph = grid_graph(np.zeros((3, 3), dtype=bool))
    goal_tables(graph, [(0, 0)], engine="numba")
    lacam(graph, [(0, 0), (2, 2)], [(2, 2), (0, 0)], time.monotonic() + 3600, guide=True,
          engine="numba")
    return time.process_time() - c
