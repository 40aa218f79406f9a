"""Lifelong PIBT for fleets of 1x1 AGVs, compiled: the loop's step planner at fleet scale.

:class:`~.pibt_planner.PIBTPlanner` hands a request here when every AGV is 1x1, moves a cell
in one tick and is unloaded (or the fleet has no shelves), with no turn-aware bodies, and,
with rotations (``planner.rotations``), turns a quarter in one tick under a Robot Runners
rule (``planner.rotation_rule``: ``actions`` or ``turn-first``). One step of
:mod:`.pibt_numba` then moves every AGV: without rotations PIBT with swaps
(:func:`~.pibt_numba.pibt_step_nb`, the reference :func:`~.pibt.pibt_step`); with rotations
PIBT over forward / turn / wait (:func:`~.heading_kernels.heading_step_nb`) or PIBT on cells
then turn first (:func:`~.heading_kernels.turn_first_nb`). AGVs that work in place (``hold``)
stay.

Distance tables come from one :class:`~.dist_store.DistStore` per motion graph (one table
per goal cell, shared by every AGV and tick, least recently used evicted under a budget),
rebuilt when the loop's graphs change (a safety corridor opens or closes). What
:class:`CompiledStep` keeps between calls is a cache (each AGV's table row) and, for the
``actions`` rule, which AGVs turned last tick to make way (``escaping``, as the rule
defines it): the same requests give the same paths.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..base import AgentRequest, PlanRequest, PlanResult, TimedPath
from ..search.turning_astar import heading_index
from ..sweep import turn_aware

__all__ = ["CompiledStep", "RULES", "ENGINES", "eligible"]

RULES = ("actions", "turn-first")
"""Rotation rules with a compiled step."""
ENGINES = ("numba", "python")
DEFAULT_BUDGET_MB = 1024.0


def eligible(agents: Sequence[AgentRequest], rule: str) -> bool:
    """Whether :class:`CompiledStep` can plan ``agents`` (see the module docstring)."""
    from . import kernels as pn

    if not pn.AVAILABLE or not agents:
        return False
    rot = agents[0].turn_ticks is not None
    if rot and rule not in RULES:
        return False
    for a in agents:
        if a.k != 1 or a.ticks_per_move != 1 or turn_aware(a) or (rot and a.loaded):
            return False
        if (a.turn_ticks is not None) != rot or (rot and a.turn_ticks[0] != 1):
            return False
    return True


class CompiledStep:
    """The compiled lifelong step and its caches (one per planner object, i.e. episode)."""

    def __init__(self, budget_mb: float = DEFAULT_BUDGET_MB, engine: str = "numba") -> None:
        if engine not in ENGINES:
            raise ValueError(f"engine: expected one of {ENGINES}, got {engine!r}")
        self.budget_mb = budget_mb
        self.engine = engine
        """``numba`` (compiled) or ``python``: the reference steps of :mod:`.pibt` and
        :mod:`.pibt_heading`, the same plans (slow; for tests)."""
        self._graph = None
        self._store = None
        self._st = None
        self._goal = np.zeros(0, dtype=np.int64)
        self._rows = np.zeros(0, dtype=np.int64)
        self._held_tables: list = []
        self._escaping = np.zeros(0, dtype=bool)

    def _bind(self, request: PlanRequest, n_ids: int) -> None:
        """(Re)build the stores and step tables when the loop's graphs changed: the
        unloaded 1x1 graph, and on a floor with shelves the loaded one (a loaded 1x1 AGV
        keeps to the aisles; every shelf shares that graph), both tables in one slab."""
        from ..dist_store import DistStore
        from . import heading_kernels as hk
        from . import kernels as pn

        graph = request.graphs.get(1, False)
        if graph is not self._graph:
            self._graph = graph
            shelves = bool(graph.layout.shelves)
            self._store = DistStore(graph, self.budget_mb, reserve=n_ids,
                                    dtype=np.int32 if shelves else None,
                                    stores=2 if shelves else 1)
            self._stores = [self._store]
            self._sts = [pn.step_tables(graph.neighbors, graph.cols)]
            if shelves:
                loaded = request.graphs.get(1, True)
                self._stores.append(DistStore(loaded, self.budget_mb, share=self._store))
                self._sts.append(pn.step_tables(loaded.neighbors, graph.cols))
            self._st = self._sts[0]
            self._neighbors = [graph.neighbors] + (
                [request.graphs.get(1, True).neighbors] if shelves else [])
            self._goal = np.full(n_ids, -1, dtype=np.int64)
            self._gidx = np.zeros(n_ids, dtype=np.int64)
            self._rows = np.zeros(n_ids, dtype=np.int64)
            self._held_tables = [None] * n_ids
            pn.warm_up(self._store.dtype)
            hk.warm_up(self._store.dtype)
        if len(self._goal) < n_ids:  # more AGVs than the store was made for
            grow = n_ids - len(self._goal)
            self._goal = np.concatenate([self._goal, np.full(grow, -1, dtype=np.int64)])
            self._gidx = np.concatenate([self._gidx, np.zeros(grow, dtype=np.int64)])
            self._rows = np.concatenate([self._rows, np.zeros(grow, dtype=np.int64)])
            self._held_tables += [None] * grow
        if len(self._escaping) < n_ids:
            self._escaping = np.concatenate(
                [self._escaping, np.zeros(n_ids - len(self._escaping), dtype=bool)])

    def plan(self, request: PlanRequest, agents: Sequence[AgentRequest], rule: str
             ) -> PlanResult:
        """One step for ``agents`` (sorted by AGV id; :func:`eligible`)."""
        from . import heading_kernels as hk
        from . import kernels as pn

        ids = np.fromiter((a.agv for a in agents), dtype=np.int64, count=len(agents))
        self._bind(request, int(ids.max()) + 1)
        store, st = self._store, self._st
        config = np.fromiter((a.start for a in agents), dtype=np.int64, count=len(agents))
        goal = np.fromiter((a.goal for a in agents), dtype=np.int64, count=len(agents))
        prio = np.fromiter((float(a.priority[0]) if a.priority else 0.0 for a in agents),
                           dtype=np.float64, count=len(agents))
        held = np.fromiter((a.hold for a in agents), dtype=bool, count=len(agents))
        gidx = np.fromiter((a.loaded for a in agents), dtype=np.int64, count=len(agents)) \
            if len(self._stores) > 1 else np.zeros(len(agents), dtype=np.int64)
        if gidx.any() and len(self._stores) < 2:
            raise ValueError("a loaded AGV on a floor without shelves")
        for j in np.flatnonzero((self._goal[ids] != goal) | (self._gidx[ids] != gidx)).tolist():
            i = int(ids[j])
            table = self._stores[gidx[j]].get(int(goal[j]))
            self._held_tables[i] = table
            self._rows[i] = store.slot(table)
            self._goal[i] = goal[j]
            self._gidx[i] = gidx[j]
        tabs = (store.slab, self._rows[ids])
        moves = (tuple(self._sts), gidx) if len(self._sts) > 1 else None
        rng = request.rng if request.rng is not None else np.random.default_rng(0)
        tie = rng.random(self._graph.num_nodes) * 0.5
        rot = agents[0].turn_ticks is not None
        heading = np.fromiter((heading_index(a.heading) for a in agents), dtype=np.int64,
                              count=len(agents)) if rot else None
        if self.engine == "python":
            nxt, nh = self._python(ids, config, goal, prio, tie, held, heading, rule,
                                   request.acyclic)
            return _paths(agents, request.tick, config, nxt, heading, nh)
        order = pn.priority_order(prio)
        if not rot:
            nxt = pn.pibt_step_nb(st, config, goal, tabs, order, tie, held=held, moves=moves,
                                  acyclic=request.acyclic)
            return _paths(agents, request.tick, config, nxt, None, None)
        if rule == "actions":
            nxt, nh, _, esc = hk.heading_step_nb(st, config, heading, tabs, order, tie,
                                                 self._escaping[ids], held=held,
                                                 acyclic=request.acyclic)
            self._escaping[ids] = esc
        else:
            nxt = pn.pibt_step_nb(st, config, goal, tabs, order, tie, heading=heading,
                                  held=held, acyclic=request.acyclic)
            nxt, nh, _ = hk.turn_first_nb(config, nxt, heading, st.cols, self._graph.num_nodes)
        return _paths(agents, request.tick, config, nxt, heading, nh)


    def _python(self, ids, config, goal, prio, tie, held, heading, rule, acyclic):
        """The step by the Python references (lists in, arrays out)."""
        from .heading import Facing, heading_pibt_step, steps_of, turn_first
        from .reference import pibt_step

        graph, cols = self._graph, self._graph.cols
        slab = self._store.slab
        tabs = [memoryview(slab[r]) for r in self._rows[ids].tolist()]
        cfg, pr, tl = config.tolist(), prio.tolist(), tie.tolist()
        forced = [(j, cfg[j]) for j in np.flatnonzero(held).tolist()]
        if heading is None:
            nxt = pibt_step(graph, cfg, tabs, pr, tl, forced=forced, goals=goal.tolist(),
                            tables=[self._neighbors[int(g)] for g in self._gidx[ids].tolist()],
                            acyclic=acyclic)
            return np.asarray(nxt, dtype=np.int64), None
        if forced:
            raise NotImplementedError("the Python rotation steps hold no AGV")
        hd = heading.tolist()
        if rule == "actions":
            esc = frozenset(np.flatnonzero(self._escaping[ids]).tolist())
            nxt, nh, _, esc = heading_pibt_step(graph.neighbors, cols, cfg, hd, tabs, pr, tl,
                                                esc, steps_of(graph.neighbors, cols),
                                                acyclic=acyclic)
            mask = np.zeros(len(ids), dtype=bool)
            mask[list(esc)] = True
            self._escaping[ids] = mask
            return np.asarray(nxt, dtype=np.int64), np.asarray(nh, dtype=np.int64)
        costs = [Facing(tabs[j], cfg[j], hd[j], cols) for j in range(len(cfg))]
        nxt = pibt_step(graph, cfg, costs, pr, tl, goals=goal.tolist(), acyclic=acyclic)
        acts = ["W"] * len(cfg)
        nxt = turn_first(cfg, nxt, hd, acts, cols)
        return np.asarray(nxt, dtype=np.int64), np.asarray(hd, dtype=np.int64)


def _paths(agents: Sequence[AgentRequest], tick: int, config: np.ndarray, nxt: np.ndarray,
           heading: np.ndarray | None, nh: np.ndarray | None) -> PlanResult:
    """Each AGV's path for the step: stay (one state) or move (two); with headings, a turn
    is two states on the cell with the old and the new heading."""
    result = PlanResult()
    paths = result.paths
    here_l, there_l = config.tolist(), nxt.tolist()
    if heading is None:
        for a, here, there in zip(agents, here_l, there_l, strict=True):
            states = ((here, here),) if here == there else ((here, here), (there, there))
            paths[a.agv] = TimedPath(a.agv, tick, states)
        return result
    assert nh is not None
    for a, here, there, h0, h1 in zip(agents, here_l, there_l, heading.tolist(), nh.tolist(),
                                      strict=True):
        if here != there:
            paths[a.agv] = TimedPath(a.agv, tick, ((here, here), (there, there)), (h0, h1))
        elif h0 != h1:
            paths[a.agv] = TimedPath(a.agv, tick, ((here, here), (here, here)), (h0, h1))
        else:
            paths[a.agv] = TimedPath(a.agv, tick, ((here, here),), (h0,))
    return result
