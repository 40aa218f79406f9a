"""Guide paths for one-shot PIBT / LaCAM ("scatter", after SUO and LaCAM3's use of it).

Plain PIBT sends every agent down its own shortest path, so agents whose shortest paths
share a corridor pile into it and push each other back and forth. Guide paths spread them
out before the search starts: each agent gets a path from its start to its goal that is at
most ``margin`` moves longer than a shortest one and, among those, crosses the other agents'
guide paths as rarely as possible. A crossing ("collision") is counted in space-time along
the paths, one move per tick from the start: two guide paths on the same cell at the same
tick, two paths that swap cells between two ticks, or a path that enters a cell at a tick
after another path has ended there (its agent waits on its goal). The agents are planned one
after the other, in a random order, each against all the others' current paths, and the
whole round is repeated while the number of collisions keeps dropping (a few rounds).

PIBT then uses the guide: at cell ``v`` an agent's first choice is the cell after ``v`` on
its guide path (if ``v`` is on it), its other candidates follow in the usual distance order
(:func:`~warerover_phys.planning.pibt.reference.pibt_step`, argument ``guide``).

The single-agent search is A* over cells (not cell-time pairs: each cell is closed once),
ordered by (collisions so far, f = g + h); ``g`` counts moves, the tick at which a cell is
reached is ``g``. Paths never return to their start cell. All of it is deterministic for a
given ``rng``.
"""

from __future__ import annotations

import heapq
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = ["GuidePaths", "guide_for", "guide_paths"]


@dataclass
class GuidePaths:
    """Guide paths (node lists) and, per agent, ``next[i][v]``: the node after ``v`` on
    agent i's guide path."""

    paths: list[list[int]]
    next: list[dict[int, int]]
    stats: dict = field(default_factory=dict)


class _Table:
    """Space-time occupancy of the guide paths: ``body[t * n + v]`` lists the agents whose
    path is at node v at tick t; ``ends[v]`` the last ticks of the paths that end at v."""

    def __init__(self, num_nodes: int) -> None:
        self.n = num_nodes
        self.body: dict[int, list[int]] = {}
        self.ends: dict[int, list[int]] = {}
        self.ticks: dict[int, list[int]] = {}
        """Per node, the ticks at which some path is there (one entry per path and tick)."""
        self.collisions = 0

    def step_cost(self, u: int, v: int, t: int) -> int:
        """Collisions of a move u -> v from tick t to t + 1."""
        n, body = self.n, self.body
        c = 0
        here = body.get((t + 1) * n + v)
        if here:
            c += len(here)
        a = body.get((t + 1) * n + u)
        if a:
            b = body.get(t * n + v)
            if b:
                c += sum(1 for j in a if j in b)
        e = self.ends.get(v)
        if e:
            c += sum(1 for last in e if t + 1 > last)
        return c

    def _path_cost(self, path: list[int]) -> int:
        c = sum(self.step_cost(path[t - 1], path[t], t - 1) for t in range(1, len(path)))
        last = len(path) - 1
        # others that pass through our goal after we have stopped there
        return c + sum(1 for t in self.ticks.get(path[-1], ()) if t > last)

    def add(self, i: int, path: list[int]) -> None:
        self.collisions += self._path_cost(path)
        n, body = self.n, self.body
        ticks = self.ticks
        for t, v in enumerate(path):
            body.setdefault(t * n + v, []).append(i)
            ticks.setdefault(v, []).append(t)
        self.ends.setdefault(path[-1], []).append(len(path) - 1)

    def remove(self, i: int, path: list[int]) -> None:
        n, body = self.n, self.body
        for t, v in enumerate(path):
            lst = body[t * n + v]
            lst.remove(i)
            if not lst:
                del body[t * n + v]
            self.ticks[v].remove(t)
        self.ends[path[-1]].remove(len(path) - 1)
        self.collisions -= self._path_cost(path)


_BIG = 1 << 24
"""Heap keys are ``collisions * _BIG + f`` (f stays far below it)."""


def _search(neighbors: Sequence[Sequence[int]], table: _Table, start: int, goal: int,
            dist: Sequence[int], margin: int) -> list[int] | None:
    """The guide path of one agent: fewest collisions, then shortest, within ``margin``."""
    if start == goal:
        return [start]
    ub = dist[start] + margin
    n, body, ends = table.n, table.body, table.ends
    heap = [(dist[start], 0, start, -1)]
    parent: dict[int, int] = {}
    best: dict[int, int] = {}  # lowest key pushed per node: a higher one can never win
    push, pop = heapq.heappush, heapq.heappop
    big = _BIG
    while heap:
        key, neg_g, v, par = pop(heap)
        if v in parent:
            continue
        parent[v] = par
        if v == goal:
            path = [v]
            while par != -1:
                path.append(par)
                par = parent[par]
            path.reverse()
            return path
        g = -neg_g
        t1 = g + 1
        c = key // big
        for u in neighbors[v]:
            if u == start or u in parent:
                continue
            f = t1 + dist[u]
            if f > ub:
                continue
            # collisions of the move v -> u from tick g to g + 1 (as _Table.step_cost)
            cc = c
            here = body.get(t1 * n + u)
            if here:
                cc += len(here)
            a = body.get(t1 * n + v)
            if a:
                b = body.get(g * n + u)
                if b:
                    for j in a:
                        if j in b:
                            cc += 1
            e = ends.get(u)
            if e:
                for last in e:
                    if t1 > last:
                        cc += 1
            k = cc * big + f
            old = best.get(u)
            if old is not None and old <= k:
                continue
            best[u] = k
            push(heap, (k, -t1, u, v))
    return None


ENGINES = ("auto", "numba", "python")
NUMBA_MIN_AGENTS = 300
"""``engine="auto"`` compiles the search (:mod:`.scatter_numba`), and :func:`.lacam.lacam`
its steps, from this many agents up;
below, numba's import and cache loads (~0.6 s of CPU) cost more than they save (measured:
the whole `solve` at 250 agents 1.3 s of CPU with Python, 1.6 s compiled; at 350, 1.9 and 1.4 s)."""
COLD_COMPILE_S = 150.0
"""``auto`` compiles the kernels (numba's cache empty or stale: 20-30 s of CPU, once; on a
loaded 2-core box over a minute of wall time) only when at least this many seconds are left
before the deadline; otherwise it runs Python (the same plans), so that the time limit
(``solve``'s default 60 s included) is honoured on a cold cache too.
:func:`.oneshot.warm_up` fills the cache ahead."""
_CHUNK = 32
"""Agents planned per call of the compiled round (the deadline is checked between calls)."""


def guide_paths(neighbors: Sequence[Sequence[int]], starts: Sequence[int],
                goals: Sequence[int], dists: Sequence[np.ndarray | list[int]], rng: np.random.Generator,
                *, margin: int = 20, max_rounds: int = 2, deadline: float | None = None,
                engine: str = "auto", arrays: Sequence[np.ndarray] | None = None,
                ) -> GuidePaths:
    """Guide paths for agents from ``starts`` to ``goals`` (node indices).

    ``dists[i]`` is the table of moves to agent i's goal; ``margin`` the most moves a guide
    path may exceed the shortest one by; at most ``max_rounds`` rounds, stopping early when
    a round does not lower the number of collisions (the paths with the fewest collisions
    are kept) or at ``deadline`` (a ``time.monotonic()`` value; an agent not planned by then
    has no guide path and PIBT falls back to its distance order for it).

    ``engine``: ``python`` (the reference below), ``numba`` (the same search compiled,
    :mod:`.scatter_numba`: the same paths; the deadline is checked every ``_CHUNK`` agents
    instead of every agent) or ``auto`` (numba from :data:`NUMBA_MIN_AGENTS` agents, when it
    imports). The compiled search reads the tables as numpy arrays: ``arrays``, the same
    tables as ``dists`` as arrays, when ``dists`` holds lists (else they are converted,
    which costs time).
    """
    if engine not in ENGINES:
        raise ValueError(f"engine: one of {', '.join(ENGINES)} (got {engine!r})")
    if engine == "auto":
        engine = "numba" if use_numba(len(starts), deadline) else "python"
    if engine == "numba":
        return _guide_paths_numba(neighbors, starts, goals,
                                  dists if arrays is None else arrays, rng, margin=margin,
                                  max_rounds=max_rounds, deadline=deadline)
    t0 = time.perf_counter()
    num = len(starts)
    table = _Table(len(neighbors))
    lists = [d if isinstance(d, list) else d.tolist() for d in dists]
    paths: list[list[int] | None] = [None] * num
    best: list[list[int] | None] = [None] * num
    best_collisions: int | None = None
    history: list[int] = []
    stopped = "rounds"
    for _ in range(max_rounds):
        order = rng.permutation(num).tolist()
        timed_out = False
        for i in order:
            if deadline is not None and time.monotonic() > deadline:
                timed_out = True
                break
            old = paths[i]
            if old is not None:
                table.remove(i, old)
                if table._path_cost(old) == 0:
                    table.add(i, old)  # no collision: nothing to gain
                    continue
            new = _search(neighbors, table, starts[i], goals[i], lists[i], margin)
            if new is None:
                new = old
            if new is not None:
                table.add(i, new)
            paths[i] = new
        history.append(table.collisions)
        improved = best_collisions is None or table.collisions < best_collisions
        if improved and not timed_out:
            best = list(paths)
            best_collisions = table.collisions
        if timed_out:
            stopped = "time"
            if best_collisions is None:
                best = list(paths)
            break
        if table.collisions == 0:
            stopped = "no collisions"
            break
        if not improved:
            stopped = "no improvement"
            break
    out = [p if p is not None else [] for p in best]
    return _finish(out, history, stopped, margin, t0, "python")


def _finish(out: list[list[int]], history: list[int], stopped: str, margin: int, t0: float,
            engine: str) -> GuidePaths:
    nxt = [dict(zip(p, p[1:], strict=False)) for p in out]
    stats = {"rounds": len(history), "collisions": history, "stopped": stopped,
             "margin": margin, "wall_s": time.perf_counter() - t0,
             "unplanned": sum(1 for p in out if not p), "engine": engine}
    return GuidePaths(out, nxt, stats)


def use_numba(num_agents: int, deadline: float | None = None,
              also: Callable[[], Sequence] | None = None) -> bool:
    """``engine="auto"``'s choice: the compiled kernels from :data:`NUMBA_MIN_AGENTS`
    agents where numba imports, and, where they are not in numba's cache yet, only with
    :data:`COLD_COMPILE_S` seconds left before ``deadline`` (``time.monotonic()``).
    ``also``: gives further compiled functions the caller will use
    (:func:`.lacam.lacam_kernels`), checked in the cache too."""
    if num_agents < NUMBA_MIN_AGENTS or not _numba_available():
        return False
    from .scatter_kernels import compiled_ready

    return compiled_ready(also() if also is not None else ()) or deadline is None or \
        deadline - time.monotonic() >= COLD_COMPILE_S


def _numba_available() -> bool:
    try:
        import numba  # noqa: F401
    except ImportError:  # pragma: no cover - numba is a dependency
        return False
    return True


def _guide_paths_numba(neighbors: Sequence[Sequence[int]], starts: Sequence[int],
                       goals: Sequence[int], dists: Sequence[np.ndarray | list[int]],
                       rng: np.random.Generator, *, margin: int, max_rounds: int,
                       deadline: float | None) -> GuidePaths:
    """:func:`guide_paths` with the rounds run by :func:`.scatter_numba.run_agents`."""
    from . import scatter_kernels as sn

    t0 = time.perf_counter()
    num = len(starts)
    # one row per distinct table (agents with one goal share the table object)
    row_of: dict[int, int] = {}
    rows = np.empty(num, dtype=np.int64)
    unique: list = []
    for i, d in enumerate(dists):
        r = row_of.get(id(d))
        if r is None:
            r = row_of[id(d)] = len(unique)
            unique.append(d)
        rows[i] = r
    matrix = np.stack([np.asarray(d) for d in unique]) if unique else np.zeros((0, 1))
    if matrix.dtype != np.int32 and matrix.dtype != np.int64:
        matrix = matrix.astype(np.int64)
    s = np.asarray(starts, dtype=np.int64)
    g = np.asarray(goals, dtype=np.int64)
    from ..graph import UNREACHABLE

    ds = matrix[rows, s] if num else np.zeros(0, dtype=np.int64)
    ds = ds[ds < UNREACHABLE]
    horizon = int(ds.max()) + margin + 1 if len(ds) else 1
    table = sn.NbTable(len(neighbors), num, horizon)
    indptr, indices = sn.csr(neighbors)
    best: tuple[np.ndarray, np.ndarray] | None = None
    best_collisions: int | None = None
    history: list[int] = []
    stopped = "rounds"
    for _ in range(max_rounds):
        order = rng.permutation(num).astype(np.int64)
        timed_out = False
        for k in range(0, num, _CHUNK):
            if deadline is not None and time.monotonic() > deadline:
                timed_out = True
                break
            sn.run_agents(table, order[k:k + _CHUNK], indptr, indices, s, g, matrix, rows,
                          margin)
        collisions = int(table.state[0])
        history.append(collisions)
        improved = best_collisions is None or collisions < best_collisions
        if (improved and not timed_out) or (timed_out and best_collisions is None):
            best = (table.paths.copy(), table.lengths.copy())
            if not timed_out:
                best_collisions = collisions
        if timed_out:
            stopped = "time"
            break
        if collisions == 0:
            stopped = "no collisions"
            break
        if not improved:
            stopped = "no improvement"
            break
    out: list[list[int]] = [[] for _ in range(num)]
    if best is not None:
        paths, lengths = best
        out = [paths[i, :lengths[i]].tolist() for i in range(num)]
    return _finish(out, history, stopped, margin, t0, "numba")


def guide_for(graph, starts: Sequence[int], goals: Sequence[int], dists: Sequence[np.ndarray],
              seed: int, deadline: float, share: float = 0.5,
              arrays: Sequence[np.ndarray] | None = None, engine: str = "auto",
              ) -> tuple[list[dict[int, int]], dict]:
    """Guide paths on a :class:`~warerover_phys.planning.graph.MotionGraph` in at most
    ``share`` of the time left before ``deadline`` (``time.monotonic()``), with their own
    generator spawned from ``seed``; returns (``next`` per agent, stats). ``arrays`` and
    ``engine``: as for :func:`guide_paths`."""
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
    now = time.monotonic()
    guide = guide_paths(graph.neighbors, starts, goals, dists, rng,
                        deadline=now + share * max(0.0, deadline - now), arrays=arrays,
                        engine=engine)
    return guide.next, guide.stats
