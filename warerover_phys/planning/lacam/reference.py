"""LaCAM: lazy constraints addition search for MAPF (Okumura, AAAI 2023).

A depth-first search over whole configurations (one node per agent). Each high-level node
keeps a lazily grown tree of low-level constraints ("agent i goes to v next"); every time the
node is visited the next constraint is popped, and PIBT generates the successor
configuration that respects it. A configuration seen before is not added twice: the search
goes back to its node, which then tries its next constraint. LaCAM is complete: given time,
it finds a solution if one exists and reports failure otherwise.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..graph import UNREACHABLE, MotionGraph
from ..oneshot.scatter import ENGINES
from ..pibt.reference import _to_paths, initial_priorities, pibt_step, update_priorities

__all__ = ["lacam", "lacam_nodes"]

Cell = tuple[int, int]


@dataclass(slots=True)
class _Low:
    who: tuple[int, ...] = ()
    where: tuple[int, ...] = ()

    @property
    def depth(self) -> int:
        return len(self.who)


@dataclass(slots=True)
class _High:
    config: tuple[int, ...]
    parent: _High | None
    prio: list[float]
    order: list[int]
    tree: deque = field(default_factory=lambda: deque([_Low()]))
    ranked: np.ndarray | None = None
    """All agents, highest priority first (the compiled steps' order)."""


def _plain_moves(graph: MotionGraph) -> bool:
    """At most four moves from a cell (the compiled steps' neighbour table)."""
    return max((len(x) for x in graph.neighbors), default=0) <= 4


def lacam(graph: MotionGraph, starts: Sequence[Cell], goals: Sequence[Cell], deadline: float,
          seed: int = 0, guide: bool = False, dists: Sequence[Sequence[int]] | None = None,
          dist_arrays: Sequence[np.ndarray] | None = None, engine: str = "auto",
          ) -> tuple[list[list[Cell]] | None, dict]:
    """Solve; returns (paths or None, stats). None with ``stats["exhausted"]`` True means
    there is no solution; otherwise the deadline passed. ``guide``: PIBT follows guide paths
    (:mod:`~warerover_phys.planning.oneshot.scatter`, computed in at most half the time left).
    ``dists``: per agent, the moves from every node to its goal (``graph.dist_to(goal)`` as
    a list), when the caller has them already; ``dist_arrays`` the same tables as numpy
    arrays (the compiled steps read those; either may be given).

    ``engine``: ``python``, ``numba`` (the guide search and PIBT's steps compiled,
    :mod:`.scatter_numba`, :mod:`.lacam_numba`: the same plans, the tables read as arrays;
    a graph of at most four moves a cell) or ``auto`` (numba from
    :data:`~.scatter.NUMBA_MIN_AGENTS` agents where it applies, :func:`.scatter.use_numba`);
    ``stats["engine"]``."""
    s = [graph.node(c) for c in starts]
    g = [graph.node(c) for c in goals]
    if engine not in ENGINES:
        raise ValueError(f"engine: one of {', '.join(ENGINES)} (got {engine!r})")
    if engine == "numba" and not _plain_moves(graph):
        raise ValueError("engine numba: a graph of at most four moves a cell")
    if engine == "auto":
        from ..oneshot.scatter import use_numba
        engine = "numba" if _plain_moves(graph) and use_numba(
            len(s), deadline, also=lacam_kernels) else "python"
    if engine == "numba":  # the compiled steps read arrays
        if dist_arrays is None:
            dist_arrays = ([np.asarray(d) for d in dists] if dists is not None
                           else [graph.dist_to(c) for c in goals])
        dists = dist_arrays
    elif dists is None:
        # Python lists: PIBT reads single entries, far faster from a list than from numpy.
        dists = ([t.tolist() for t in dist_arrays] if dist_arrays is not None
                 else [graph.dist_to(c).tolist() for c in goals])
    nxt, guide_stats = None, None
    if guide:
        from ..oneshot.scatter import guide_for
        nxt, guide_stats = guide_for(graph, s, g, dists, seed, deadline, arrays=dist_arrays,
                                     engine=engine)
    configs, stats = lacam_nodes(graph, s, g, dists, deadline, np.random.default_rng(seed),
                                 guide=nxt, engine=engine)
    stats["engine"] = engine
    if guide_stats is not None:
        stats["guide"] = guide_stats
    return (None if configs is None else _to_paths(graph, configs)), stats


def lacam_nodes(graph: MotionGraph, starts: Sequence[int], goals: Sequence[int],
                dists: Sequence[np.ndarray], deadline: float, rng: np.random.Generator,
                tables: Sequence[Sequence[tuple[int, ...]]] | None = None,
                held: Sequence[int] = (), prio: list[float] | None = None,
                max_iterations: int | None = None,
                guide: Sequence[dict[int, int]] | None = None, engine: str = "python",
                ) -> tuple[list[list[int]] | None, dict]:
    """LaCAM over node indices: the configurations from ``starts`` to ``goals``.

    Stops (None, ``stats["stopped"]``) after ``max_iterations`` high-level iterations
    (``"iterations"``: the same result on any machine) or at ``deadline``, a
    ``time.monotonic()`` value kept as a safety stop (``"time"``).

    ``tables`` gives each agent its own neighbour lists; agents in ``held`` never move (their
    goal must be their start). ``guide``: per agent, the cell PIBT tries first from each
    cell (:func:`~warerover_phys.planning.pibt.reference.pibt_step`). ``engine="numba"``: the steps
    compiled (:mod:`.lacam_numba`; ``tables`` not supported, ``dists`` numpy arrays, at most
    four moves a cell): the same result.
    """
    ties = (rng.random(graph.num_nodes + 4099) * 0.5).tolist()  # same values, faster reads
    s, g = tuple(starts), tuple(goals)
    neighbors = graph.neighbors
    held_set = set(held)
    held_moves = tuple((i, s[i]) for i in sorted(held_set))
    movable = [i for i in range(len(s)) if i not in held_set]

    def make(config: tuple[int, ...], parent: _High | None, prio: list[float]) -> _High:
        return _new_high(config, parent, prio, engine, held_set, movable)

    if any(dists[i][s[i]] >= UNREACHABLE for i in movable):
        # An agent that cannot reach its goal (a closed corridor, say): no configuration
        # search can succeed, so do not spend the budget proving it.
        return None, {"iterations": 0, "explored": 0, "exhausted": True,
                      "stopped": "unreachable"}
    compiled = _compiled(engine, tables, graph, dists, g, ties, guide)
    root = make(s, None, prio if prio is not None else initial_priorities(dists, s))
    stack = [root]
    explored = {s: root}
    iterations = 0
    while stack:
        iterations += 1
        if max_iterations is not None and iterations > max_iterations:
            return None, {"iterations": iterations, "explored": len(explored),
                          "exhausted": False, "stopped": "iterations"}
        if iterations % 64 == 0 and time.monotonic() > deadline:
            return None, {"iterations": iterations, "explored": len(explored),
                          "exhausted": False, "stopped": "time"}
        node = stack[-1]
        if node.config == g:
            return _configs_to(node), {"iterations": iterations, "explored": len(explored)}
        if not node.tree:
            stack.pop()
            continue
        low = node.tree.popleft()
        if low.depth < len(node.order):
            _grow_low(node, low, tables, neighbors, dists, rng)
        salt = int(rng.integers(4096))
        if compiled is not None:
            nxt = _compiled_successor(compiled, node, low, held_moves, salt)
        else:
            nxt = pibt_step(graph, node.config, dists, node.prio, ties[salt:], goals=g,
                            forced=held_moves + tuple(zip(low.who, low.where, strict=True)),
                            tables=tables, guide=guide)
        if nxt is None:
            continue
        key = tuple(nxt)
        known = explored.get(key)
        if known is not None:
            stack.append(known)
            continue
        new = make(key, node, update_priorities(node.prio, key, g))
        stack.append(new)
        explored[key] = new
    return None, {"iterations": iterations, "explored": len(explored), "exhausted": True}


def _new_high(config: tuple[int, ...], parent: _High | None, prio: list[float], engine: str,
              held_set: set[int], movable: list[int]) -> _High:
    """A high-level node: its agents in priority order (held agents left out)."""
    if engine == "numba":  # the same order by numpy's stable sort
        from ..pibt.kernels import priority_order
        ranked = priority_order(prio)
        order = ranked.tolist()
        if held_set:
            order = [i for i in order if i not in held_set]
        return _High(config, parent, prio, order, ranked=ranked)
    order = sorted(movable, key=lambda i: -prio[i])
    return _High(config, parent, prio, order)


def _compiled(engine: str, tables, graph: MotionGraph, dists: Sequence[np.ndarray],
              g: tuple[int, ...], ties: list[float], guide) -> tuple | None:
    """For :func:`lacam_nodes`: the compiled step and its arrays (``engine="numba"``), or
    None (``"python"``)."""
    if engine == "numba":
        if tables is not None:
            raise ValueError("lacam_nodes: engine numba takes no per-agent tables")
        from ..pibt import kernels as pibt_numba
        from . import kernels as lacam_numba
        st = pibt_numba.step_tables(graph.neighbors, graph.cols)
        return (st, pibt_numba.robot_tables(dists),
                np.asarray(g, dtype=np.int64), np.asarray(ties, dtype=np.float64),
                *lacam_numba.guide_arrays(guide, graph.num_nodes), lacam_numba.step)
    if engine != "python":
        raise ValueError(f"lacam_nodes: engine python or numba (got {engine!r})")
    return None


def _configs_to(node: _High) -> list[list[int]]:
    """The configurations from the root to ``node``."""
    configs = []
    walk: _High | None = node
    while walk is not None:
        configs.append(list(walk.config))
        walk = walk.parent
    configs.reverse()
    return configs


def _grow_low(node: _High, low: _Low, tables, neighbors, dists: Sequence[np.ndarray],
              rng: np.random.Generator) -> None:
    """Add ``low``'s children to ``node``'s constraint tree: the next agent in order at
    each cell it can take (its neighbours towards which its goal is reachable, and where it
    is), in random order."""
    i = node.order[low.depth]
    here = node.config[i]
    near = tables[i][here] if tables is not None else neighbors[here]
    d = dists[i]
    cands = [v for v in near if d[v] < UNREACHABLE] + [here]
    rng.shuffle(cands)
    for v in cands:
        node.tree.append(_Low(low.who + (i,), low.where + (v,)))


def _compiled_successor(compiled: tuple, node: _High, low: _Low, held_moves: tuple,
                        salt: int) -> list[int] | None:
    """The compiled PIBT step from ``node`` under ``low``'s constraints (None: none)."""
    st, robot, goal_arr, tie_arr, gkeys, gvals, step = compiled
    who = np.asarray([i for i, _ in held_moves] + list(low.who), dtype=np.int64)
    where = np.asarray([v for _, v in held_moves] + list(low.where), dtype=np.int64)
    out = step(st.nbr, st.deg, np.asarray(node.config, dtype=np.int64), goal_arr,
               robot, node.ranked, tie_arr[salt:], who, where, gkeys, gvals,
               st.cols)
    return None if out is None else out.tolist()


def lacam_kernels() -> tuple:
    """The compiled functions of LaCAM's numba engine (:mod:`.lacam_numba`), for
    :func:`.scatter.use_numba`'s cache check."""
    from . import kernels as lacam_numba

    return (lacam_numba._step,)
