"""Anytime refinement of a one-shot MAPF plan by large-neighbourhood search (MAPF-LNS).

After a first solution (LaCAM or PIBT), the time left is spent lowering its sum of costs
(Li et al., "Anytime Multi-Agent Path Finding via Large Neighborhood Search", IJCAI 2021):

1. pick a *neighbourhood*, a few agents (1, 2, 4 or 8) chosen by one of three rules:
   ``random``; ``agent`` — the most delayed agent (cost minus its shortest-path length) not
   picked lately, with the agents found on the cells of a shortest path of it around the
   ticks it would pass them (those in its way); ``map`` — a random crossing of the map (a
   cell with three or more neighbours) and the agents that pass through the cells nearest
   to it;
2. take their paths out and re-plan them one after the other, in a random order, with
   space-time A* against everybody else's paths (prioritized planning: vertex and swap
   conflicts with every path kept or already re-planned, and no cell on which an agent
   already stands on its goal for good). By default the search is compiled with numba
   (:mod:`~.refine_nb`: space-time A* over a dense occupancy table kept up to date as
   paths are taken out and put back; at 700 agents on warehouse-10-20-10-2-1, 3,100-4,300
   neighbourhoods in 20 s of CPU against 380-530 with the Python search below; it looks at
   the deadline only between searches, each bounded by ``max_expansions``). In Python (``search="sipp"``,
   and where numba is missing) it runs over safe intervals (SIPP,
   :func:`_sipp`: waiting folded into intervals) and finds the same costs as the plain
   search over (cell, tick) states (:func:`_astar`, kept as the reference the tests compare
   it with). Both order states by ``f = max(t + h, earliest)``, ``earliest`` the tick from
   which the goal stays free for good (no path ends before it; the bound stays admissible
   and consistent): when the goal is busy until late, the search heads for it and waits
   instead of trying every detour that arrives no later (at 700 agents on
   warehouse-10-20-10-2-1, about 4x less CPU per neighbourhood than with the bound applied
   at the goal alone, as ``_sipp`` had it);
3. keep the new paths if their sum of costs is lower, else put the old ones back. A search
   may not exceed the cost that would make the neighbourhood's total no better
   (``old - 1 - new so far - shortest lengths of those still to plan``), which prunes it.

The rule and the size are chosen at random with adaptive weights (ALNS: a choice that
improves gains weight by the SoC gained per state the searches expanded, one that does not
loses weight). The plan stays valid at every step (every kept path avoids all the others),
so stopping at any time is safe.

Costs: an agent's cost is the tick from which it stands on its goal for good; the plan's sum
of costs (SoC) is their sum. Determinism: everything random comes from ``rng``, so two runs
with the same seed and the same ``max_iterations`` give the same plan; under a time limit
alone the plan is the same as far as both runs got (iterations done are a prefix of the same
sequence). Deadlines are ``time.monotonic()`` values.
"""

from __future__ import annotations

import heapq
import time
from bisect import bisect_left
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = ["RefineResult", "refine", "RULES"]

RULES = ("random", "agent", "map")
"""The neighbourhood rules, in the order of their ALNS weights."""
SIZES = (1, 2, 4, 8)
"""Neighbourhood sizes chosen among (ALNS weights) unless one is given."""
REACTION = 0.1
"""The ALNS reaction factor: a choice's weight moves this share towards its latest reward."""


@dataclass
class RefineResult:
    """The refined plan: per agent its node list up to its cost (then it stays on its goal),
    the costs, and the SoC after each improvement as ``(seconds since start, SoC)``."""

    paths: list[list[int]]
    costs: list[int]
    history: list[tuple[float, int]] = field(default_factory=list)
    stats: dict = field(default_factory=dict)

    @property
    def sum_of_costs(self) -> int:
        return sum(self.costs)


def _trim(path: Sequence[int], goal: int) -> list[int]:
    """The path up to the tick from which it stays on ``goal``."""
    t = len(path) - 1
    while t > 0 and path[t - 1] == goal:
        t -= 1
    return list(path[:t + 1])


class _Plan:
    """Space-time occupancy of all kept paths: ``occ[t * n + v]`` = the agent at node v at
    tick t (up to its cost tick); ``parked[v]`` = the tick from which an agent stands on its
    goal v for good; ``visits[v]`` the ticks at which some path is at v (before parking)."""

    def __init__(self, num_nodes: int, paths: list[list[int]]) -> None:
        self.n = num_nodes
        self.paths: list[list[int]] = [[] for _ in paths]
        self.occ: dict[int, int] = {}
        self.parked: dict[int, int] = {}
        self.visits: dict[int, list[int]] = {}
        self.safe: dict[int, list[tuple[int, int]]] = {}
        """Safe intervals per node (:func:`_intervals`), dropped when a path there changes."""
        self.safe_hi: dict[int, list[int]] = {}
        """The ends of ``safe[v]``'s intervals (ascending: a bisection finds the first
        interval still open at a tick); valid while ``safe[v]`` is there."""
        for i, p in enumerate(paths):
            self.add(i, p)

    def add(self, i: int, path: list[int]) -> None:
        n, occ, visits, safe = self.n, self.occ, self.visits, self.safe
        for t, v in enumerate(path):
            occ[t * n + v] = i
            visits.setdefault(v, []).append(t)
            safe.pop(v, None)
        self.parked[path[-1]] = len(path) - 1
        self.paths[i] = path

    def who(self, t: int, v: int) -> int | None:
        """The agent at node v at tick t (None if nobody's path is there then)."""
        return self.occ.get(t * self.n + v)

    def ticks_at(self, v: int) -> list[int]:
        """The ticks at which some kept path is at v (before parking), ascending."""
        return sorted(self.visits.get(v, ()))

    def remove(self, i: int) -> list[int]:
        path = self.paths[i]
        n, occ, visits, safe = self.n, self.occ, self.visits, self.safe
        for t, v in enumerate(path):
            del occ[t * n + v]
            visits[v].remove(t)
            safe.pop(v, None)
        del self.parked[path[-1]]
        return path


def _astar(neighbors: Sequence[Sequence[int]], plan: _Plan, start: int, goal: int,
           dist: Sequence[int], ub: int, deadline: float, max_expansions: int,
           ) -> list[int] | None:
    """Shortest space-time path from ``start`` (tick 0) to ``goal`` (staying there for good)
    of cost at most ``ub`` that avoids every path in ``plan``; None if there is none (or at
    ``deadline`` / after ``max_expansions``)."""
    n, occ, parked = plan.n, plan.occ, plan.parked
    ticks = plan.visits.get(goal)
    earliest = max(ticks) + 1 if ticks else 0
    if dist[start] > ub:
        return None
    # Entries (f, h, -t, node, parent key): among equal f, nearer the goal, then later
    # (when the goal is free only late, f is flat and this keeps the search goal-directed).
    heap = [(max(dist[start], earliest), dist[start], 0, start, -1)]
    closed: dict[int, int] = {}
    push, pop = heapq.heappush, heapq.heappop
    expanded = 0
    while heap:
        _f, _h, neg_t, v, par = pop(heap)
        t = -neg_t
        key = t * n + v
        if key in closed:
            continue
        closed[key] = par
        if v == goal and t >= earliest:
            path = [v]
            while par != -1:
                path.append(par % n)
                par = closed[par]
            path.reverse()
            return path
        expanded += 1
        if expanded > max_expansions or (expanded & 255 == 0 and time.monotonic() > deadline):
            return None
        t1 = t + 1
        base = t1 * n
        for u in (*neighbors[v], v):
            k1 = base + u
            if k1 in closed or k1 in occ:
                continue
            p = parked.get(u)
            if p is not None and t1 >= p:
                continue
            if u != v:
                j = occ.get(t * n + u)
                if j is not None and occ.get(base + v) == j:
                    continue  # swap with agent j
            h = dist[u]
            f1 = t1 + h
            if f1 < earliest:
                f1 = earliest
            if f1 > ub:
                continue
            push(heap, (f1, h, -t1, u, key))
    return None


_INF = 1 << 40


def _intervals(plan: _Plan, v: int) -> list[tuple[int, int]]:
    """Safe intervals of node v: maximal runs of ticks ``(lo, hi)`` (inclusive) at which no
    kept path is at v; the last one runs to ``_INF`` unless an agent parks on v."""
    park = plan.parked.get(v)
    out = []
    lo = 0
    for b in sorted(plan.visits.get(v, ())):
        if park is not None and b >= park:
            break
        if b > lo:
            out.append((lo, b - 1))
        lo = b + 1
    hi = _INF if park is None else park - 1
    if lo <= hi:
        out.append((lo, hi))
    return out


def _sipp(neighbors: Sequence[Sequence[int]], plan: _Plan, start: int, goal: int,
          dist: Sequence[int], ub: int, deadline: float, max_expansions: int,
          work: list[int] | None = None) -> list[int] | None:
    """Space-time A* over safe intervals (SIPP, Phillips and Likhachev 2011): the same
    paths as :func:`_astar` (shortest, avoiding every kept path, cost at most ``ub``) with
    waiting folded into intervals. Ties go to later ticks, so a state (node, interval) can
    be reached late first: it is expanded again when reached earlier (without that the
    search missed shorter paths, a case hypothesis found).
    ``work[0]`` (if given) grows by the number of states expanded."""
    if work is None:
        work = [0]
    n, occ = plan.n, plan.occ
    cache, his = plan.safe, plan.safe_hi
    earliest = _sipp_ends(plan, start, goal)
    if earliest is None:
        return None
    f0 = max(dist[start], earliest)
    if f0 > ub:
        return None
    # entries (f, h, -t, node, interval index, parent state key); states keyed node, interval
    heap = [(f0, dist[start], 0, start, 0, -1)]
    closed: dict[int, tuple[int, int]] = {}  # state key -> (parent state key, arrival tick)
    push, pop = heapq.heappush, heapq.heappop
    expanded = 0
    while heap:
        _f, _h, neg_t, v, k, par = pop(heap)
        key = (v << 16) | k
        t = -neg_t
        seen = closed.get(key)
        if seen is not None and seen[1] <= t:
            continue  # reached no later already (ties prefer later ticks: it can happen)
        closed[key] = (par, t)
        hi_v = cache[v][k][1]
        if v == goal and hi_v == _INF:
            work[0] += expanded
            return _unwind(closed, key, n)
        expanded += 1
        if expanded > max_expansions or (expanded & 127 == 0 and time.monotonic() > deadline):
            work[0] += expanded
            return None
        last = hi_v + 1  # the latest arrival at a neighbour (leaving v at hi_v)
        t1 = t + 1
        for u in neighbors[v]:
            ivs = cache.get(u)
            if ivs is None:
                ivs = cache[u] = _intervals(plan, u)
                hs = his[u] = [iv[1] for iv in ivs]
            else:
                hs = his[u]
            h = dist[u]
            ukey = u << 16
            # the intervals that end before t1 cannot be entered: start after them
            for k2 in range(bisect_left(hs, t1), len(ivs)):
                lo, hi = ivs[k2]
                if lo > last:
                    break
                t2 = lo if lo > t1 else t1
                f = t2 + h
                if f > ub:
                    break  # later intervals only arrive later
                # a swap: some agent goes u -> v while we go v -> u; leave a tick later
                while t2 <= hi and t2 <= last:
                    j = occ.get((t2 - 1) * n + u)
                    if j is None or occ.get(t2 * n + v) != j:
                        break
                    t2 += 1
                if t2 > hi or t2 > last:
                    continue
                seen = closed.get(ukey | k2)
                if seen is not None and seen[1] <= t2:
                    continue
                f = t2 + h
                if f < earliest:
                    f = earliest  # nobody finishes before the goal is free for good
                if f > ub:
                    continue
                push(heap, (f, h, -t2, u, k2, key))
    work[0] += expanded
    return None


def _safe_intervals(plan: _Plan, v: int) -> list[tuple[int, int]]:
    """``v``'s safe intervals, from the plan's cache (computed and cached when missing)."""
    ivs = plan.safe.get(v)
    if ivs is None:
        ivs = plan.safe[v] = _intervals(plan, v)
        plan.safe_hi[v] = [iv[1] for iv in ivs]
    return ivs


def _sipp_ends(plan: _Plan, start: int, goal: int) -> int | None:
    """For :func:`_sipp`: the tick from which the goal is free for good, or None when it
    never is or the start is not free from tick 0."""
    goal_iv = _safe_intervals(plan, goal)
    if not goal_iv or goal_iv[-1][1] != _INF:
        return None
    s_iv = _safe_intervals(plan, start)
    if not s_iv or s_iv[0][0] != 0:
        return None
    return goal_iv[-1][0]


def _unwind(closed: dict[int, tuple[int, int]], key: int, n: int) -> list[int]:
    """The node list of the path that ends in state ``key`` (waits spelt out)."""
    steps = []
    while key != -1:
        par, t = closed[key]
        steps.append((key >> 16, t))
        key = par
    steps.reverse()
    path: list[int] = []
    for (v, t), nxt in zip(steps, steps[1:] + [None], strict=True):
        leave = t if nxt is None else nxt[1] - 1
        path.extend([v] * (leave - t + 1))
    return path


def refine(neighbors: Sequence[Sequence[int]], paths: Sequence[Sequence[int]],
           goals: Sequence[int], dists: Sequence[np.ndarray], deadline: float,
           rng: np.random.Generator, *, size: int | None = None,
           max_iterations: int | None = None,
           max_expansions: int = 200_000,
           on_improve: Callable[[float, int], None] | None = None,
           search: str = "auto") -> RefineResult:
    """Refine a valid plan (``paths``: node lists from the starts to ``goals``, any length)
    until ``deadline`` (``time.monotonic()``) or ``max_iterations`` neighbourhoods.

    ``dists[i]`` is the table of moves to agent i's goal (from every node); ``size`` the
    number of agents per neighbourhood (default: chosen among :data:`SIZES` with adaptive
    weights, like the rules); ``on_improve(seconds, soc)`` is called after each
    improvement. The returned plan is valid whenever the given one is, and its SoC is never
    higher. ``search``: ``"nb"`` the compiled space-time A* over a dense occupancy table
    (:mod:`~.refine_nb`), ``"sipp"`` the Python interval search (:func:`_sipp`), ``"auto"``
    the first where numba is there. Both find the same costs; the paths may differ among
    equals, so the two give different (each deterministic) runs.
    """
    if search == "auto":
        from . import kernels as refine_nb
        search = "nb" if refine_nb.AVAILABLE else "sipp"
    if search not in ("nb", "sipp"):
        raise ValueError(f"search must be 'nb', 'sipp' or 'auto', not {search!r}")
    t0 = time.monotonic()
    num = len(paths)
    num_nodes = len(neighbors)
    trimmed = [_trim(p, g) for p, g in zip(paths, goals, strict=True)]
    plan, ptr, idx = _new_plan(search, neighbors, trimmed)
    # distance tables as lists (sipp) or int32 arrays (nb), made when an agent is first
    # re-planned
    lists: list = [None] * num
    lb = [int(dists[i][trimmed[i][0]]) for i in range(num)]
    costs = [len(p) - 1 for p in trimmed]
    soc = sum(costs)
    history = [(0.0, soc)]
    tally = _Tally([max(1, min(k, num)) for k in (SIZES if size is None else (size,))])
    floor = sum(lb)
    tabu: set[int] = set()
    crossings = [v for v in range(num_nodes) if len(neighbors[v]) >= 3]
    it = 0
    stopped = "time"
    while True:
        if max_iterations is not None and it >= max_iterations:
            stopped = "iterations"
            break
        if time.monotonic() > deadline:
            break
        if soc == floor:
            stopped = "optimal"
            break
        it += 1
        rule, which = tally.pick(rng)
        group = _neighbourhood(rule, plan, dists, costs, lb, tabu, tally.sizes[which], rng,
                               neighbors, crossings)
        old_cost = sum(costs[a] for a in group)
        olds = {a: plan.remove(a) for a in group}
        order = [group[k] for k in rng.permutation(len(group)).tolist()]
        work = [0]
        ok, news, new_cost = _replan(order, plan, olds, old_cost, lb, lists, dists, goals,
                                     search, (ptr, idx), neighbors, deadline, max_expansions,
                                     work)
        if ok and new_cost < old_cost:
            for a, p in news.items():
                costs[a] = len(p) - 1
            soc -= old_cost - new_cost
            tally.improved(rule, which, old_cost - new_cost, work[0])
            elapsed = time.monotonic() - t0
            history.append((elapsed, soc))
            if on_improve is not None:
                on_improve(elapsed, soc)
        else:
            for a in news:
                plan.remove(a)
            for a in group:
                plan.add(a, olds[a])
            tally.failed(rule, which)
    stats = {"iterations": it, "improvements": len(history) - 1, "stopped": stopped,
             **tally.stats(), "wall_s": time.monotonic() - t0}
    return RefineResult(list(plan.paths), costs, history, stats)


class _Tally:
    """The adaptive choice of :func:`refine`: a weight per rule (:data:`RULES`) and per
    neighbourhood size, each moved by :data:`REACTION` towards the reward of its
    improvements (or down on a failure), and what each was tried, won and gained."""

    def __init__(self, sizes: list[int]) -> None:
        self.sizes = sizes
        self.size_w = [1.0] * len(sizes)
        self.weights = [1.0] * len(RULES)
        self.tried = [0] * len(RULES)
        self.won = [0] * len(RULES)
        self.gained = [0] * len(RULES)
        self.size_tried = [0] * len(sizes)
        self.size_won = [0] * len(sizes)

    def pick(self, rng: np.random.Generator) -> tuple[int, int]:
        """A rule and a size index, drawn by weight (and counted as tried)."""
        total_w = sum(self.weights)
        rule = int(rng.choice(len(RULES), p=[w / total_w for w in self.weights]))
        total_w = sum(self.size_w)
        which = int(rng.choice(len(self.sizes), p=[w / total_w for w in self.size_w]))
        self.tried[rule] += 1
        self.size_tried[which] += 1
        return rule, which

    def improved(self, rule: int, which: int, gained: int, work: int) -> None:
        reaction = REACTION
        self.won[rule] += 1
        self.gained[rule] += gained
        self.size_won[which] += 1
        # reward: SoC gained per 1,000 states expanded (a cost measure that does not
        # depend on the machine, so the choices stay deterministic)
        gain = 1000.0 * gained / (work + 100)
        self.weights[rule] = (1 - reaction) * self.weights[rule] + reaction * gain
        self.size_w[which] = (1 - reaction) * self.size_w[which] + reaction * gain

    def failed(self, rule: int, which: int) -> None:
        reaction = REACTION
        self.weights[rule] = max(1e-3, (1 - reaction) * self.weights[rule])
        self.size_w[which] = max(1e-3, (1 - reaction) * self.size_w[which])

    def stats(self) -> dict:
        return {"sizes": {str(k): {"tried": self.size_tried[j], "improved": self.size_won[j],
                                   "weight": round(self.size_w[j], 4)}
                          for j, k in enumerate(self.sizes)},
                "rules": {r: {"tried": self.tried[k], "improved": self.won[k],
                              "gained": self.gained[k], "weight": round(self.weights[k], 4)}
                          for k, r in enumerate(RULES)}}


def _new_plan(search: str, neighbors: Sequence[Sequence[int]], trimmed: list[list[int]]):
    """The kept paths as ``search`` needs them: a dense occupancy table and the graph as
    CSR arrays (``"nb"``), or the interval search's table (``"sipp"``; no arrays)."""
    if search == "nb":
        from .kernels import DensePlan, csr
        ptr, idx = csr(neighbors)
        return DensePlan(len(neighbors), trimmed), ptr, idx
    return _Plan(len(neighbors), trimmed), None, None


def _neighbourhood(rule: int, plan, dists: Sequence[np.ndarray], costs: list[int],
                   lb: list[int], tabu: set[int], size: int, rng: np.random.Generator,
                   neighbors: Sequence[Sequence[int]], crossings: list[int]) -> list[int]:
    """The agents ``rule`` picks to re-plan together (:data:`RULES`), topped up at random
    to at least two."""
    num = len(costs)
    if rule == 1:
        group = _agent_based(plan, dists, costs, lb, tabu, size, rng, neighbors)
    elif rule == 2 and crossings:
        group = _map_based(plan, crossings, neighbors, size, rng)
    else:
        group = rng.choice(num, size, replace=False).tolist()
    if len(group) < 2 and num > 1:
        # too few to gain anything: top up at random
        extra = [a for a in rng.permutation(num).tolist() if a not in group]
        group += extra[:size - len(group)]
    return group


def _replan(order: list[int], plan, olds: dict, old_cost: int, lb: list[int], lists: list,
            dists: Sequence[np.ndarray], goals: Sequence[int], search: str, csr_arrays,
            neighbors: Sequence[Sequence[int]], deadline: float, max_expansions: int,
            work: list[int]) -> tuple[bool, dict[int, list[int]], int]:
    """Re-plan the removed agents in ``order``, each added to ``plan`` as found, each under
    the cost that can still beat ``old_cost``: (all found, the new paths, their cost)."""
    ptr, idx = csr_arrays
    rest_lb = sum(lb[a] for a in order)
    new_cost = 0
    news: dict[int, list[int]] = {}
    for a in order:
        rest_lb -= lb[a]
        ub = old_cost - 1 - new_cost - rest_lb
        d = lists[a]
        if search == "nb":
            if d is None:
                d = lists[a] = np.ascontiguousarray(dists[a], dtype=np.int32)
            # a compiled search does not look at the clock: look before each one
            path = None if time.monotonic() > deadline else plan.search(
                ptr, idx, olds[a][0], goals[a], d, ub, max_expansions, work)
        else:
            if d is None:
                d = lists[a] = dists[a].tolist()
            path = _sipp(neighbors, plan, olds[a][0], goals[a], d, ub, deadline,
                         max_expansions, work)
        if path is None:
            return False, news, new_cost
        news[a] = path
        new_cost += len(path) - 1
        plan.add(a, path)
    return True, news, new_cost


def _agent_based(plan, dists: Sequence[np.ndarray], costs: list[int],
                 lb: list[int], tabu: set[int], size: int, rng: np.random.Generator,
                 neighbors: Sequence[Sequence[int]]) -> list[int]:
    """The most delayed agent outside ``tabu`` and the agents in its way: those at the
    cells of one of its shortest paths within the ticks it could pass them."""
    delays = [c - b for c, b in zip(costs, lb, strict=True)]
    best, best_delay = -1, 0
    for a, dl in enumerate(delays):
        if dl > best_delay and a not in tabu:
            best, best_delay = a, dl
    if best < 0:
        tabu.clear()
        return rng.choice(len(costs), size, replace=False).tolist()
    tabu.add(best)
    group = [best]
    seen = {best}
    who = plan.who
    d = dists[best]
    v = plan.paths[best][0]
    t = 0
    # walk a shortest path (random among equals) and look around the ideal tick
    while len(group) < size:
        for dt in range(best_delay + 1):
            j = who(t + dt, v)
            if j is not None and j not in seen:
                seen.add(j)
                group.append(j)
                if len(group) >= size:
                    break
        if d[v] == 0:
            break
        steps = [u for u in neighbors[v] if d[u] < d[v]]
        v = steps[int(rng.integers(len(steps)))]
        t += 1
    return group


def _map_based(plan, crossings: list[int], neighbors: Sequence[Sequence[int]],
               size: int, rng: np.random.Generator) -> list[int]:
    """Agents that pass a random crossing or the cells nearest to it (breadth first)."""
    start = crossings[int(rng.integers(len(crossings)))]
    who = plan.who
    group: list[int] = []
    seen: set[int] = set()
    frontier, marked = [start], {start}
    budget = 64
    while frontier and len(group) < size and budget > 0:
        nxt: list[int] = []
        for v in frontier:
            budget -= 1
            for t in plan.ticks_at(v):
                j = who(int(t), v)
                if j is not None and j not in seen:
                    seen.add(j)
                    group.append(j)
                    if len(group) >= size:
                        return group
            for u in neighbors[v]:
                if u not in marked:
                    marked.add(u)
                    nxt.append(u)
        frontier = nxt
    return group
