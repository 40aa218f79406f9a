"""The receding-horizon program of ``executor.reorder: milp`` (Berndt et al. 2020).

At a decision the candidate switches (:class:`~.reorder_types.Estimate`) are split into
independent problems: candidates that share an AGV go together. For each problem:

- **AGVs**: those of its candidates, and the AGVs whose visits come right behind theirs
  at the cells they enter in the window (the first to feel a switch);
- **window**: each AGV's next ``reorder_horizon`` actions, and at least those of the
  switchable cells;
- **variables**: a start time per action of the window (seconds), a binary ``b`` per
  candidate (1: switch);
- **constraints**: an AGV's actions in order, each after the previous one's motion-model
  duration and the turn or dwell before it, the first after the AGV is ready
  (:meth:`~.reorder.Reorderer.times`); an action that enters a cell starts after the
  visit ahead of it in the queue has left (its leaving action finished): for an AGV
  outside the problem that time is a constant (its own estimate), for one inside whose
  leaving action is beyond its window it is after the window's end; at a switchable cell
  the order of the two visits (and of those between them) is ``b``'s (big-M), and the visits
  before and after the
  pair wait for / come before both;
- **objective**: the sum over the AGVs of the start of their window's last action, plus
  ``reorder_margin_s`` per switch (a switch must pay for itself, as in greedy), less the
  stop a switch saves a driving AGV (:attr:`~.reorder_types.Estimate.brake_s`).

A problem of one candidate whose estimated gain is further than ``reorder_milp_band_s``
from the margin is clear-cut and decided by the greedy rule without a program, and so is
a problem whose program would have more than ``reorder_milp_max_vars`` variables.
Solved with :func:`scipy.optimize.milp` (HiGHS) within ``reorder_node_limit``
branch-and-bound nodes (and ``reorder_time_limit_s`` if set); a problem without a proved
optimum falls back to the greedy rule. A feasible schedule has no cycle within the window;
each chosen switch is still checked on the whole graph when it is made.
"""

from __future__ import annotations

from itertools import islice
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .adg import _Visit
    from .reorder_types import Decider, Estimate

__all__ = ["choose", "components"]


def components(ests: list[Estimate]) -> list[list[Estimate]]:
    """The candidates split into groups that share no AGV (in order of their first)."""
    parent: dict[int, int] = {}

    def root(a: int) -> int:
        while parent.setdefault(a, a) != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for e in ests:
        for u, _ in e.group.pairs:
            parent[root(u.agv)] = root(e.group.second)
    out: dict[int, list[Estimate]] = {}
    for e in ests:
        out.setdefault(root(e.group.second), []).append(e)
    return list(out.values())


def choose(r: Decider, ests: list[Estimate], t: float) -> list[Estimate]:
    """The candidates to switch (see the module doc). A candidate whose waiting AGV's
    first cell lies beyond the window of the AGV it would pass (``2 x reorder_horizon``
    actions) is left to the greedy rule; of the others' cells those within the window are
    modelled (the rest are switched with them). A lone candidate whose estimated gain is
    further than ``reorder_milp_band_s`` from the margin is clear-cut: greedy decides it
    (most candidates; a program costs milliseconds)."""
    chosen: list[Estimate] = []
    cap = 2 * r.horizon
    sg = r.graph

    def idx(action) -> int:
        return sg.pending_index(sg.step_of(action))

    for comp in components(ests):
        inside: list[tuple[Estimate, list]] = []
        for e in comp:
            pairs = [(u, w) for u, w in e.group.pairs
                     if idx(u.leave) < cap and idx(w.leave) < cap]
            first = idx(e.group.pairs[0][1].enter)  # (0, or a driving AGV's first unclaimed)
            if any(idx(w.enter) == first and (u, w) not in pairs for u, w in e.group.pairs):
                chosen += [e] if r.worth(e) else []
            else:
                inside.append((e, pairs))
        if not inside:
            continue
        if len(inside) == 1 and r.milp_band_s is not None \
                and abs(inside[0][0].gain_s - r.margin_s) > r.milp_band_s:
            r.milp_clear += 1  # clear-cut: the greedy rule's answer
            chosen += [e for e, _ in inside if r.worth(e)]
            continue
        prog = _Program(r, inside, t)
        if r.milp_max_vars is not None and len(prog.col) + prog.nb > r.milp_max_vars:
            r.milp_large += 1  # too large: the greedy rule's answer
            chosen += [e for e, _ in inside if r.worth(e)]
            continue
        picked = prog.solve()
        if picked is None:
            r.milp_fallbacks += 1
            picked = [e for e, _ in inside if r.worth(e)]
        chosen += picked
    return sorted(chosen, key=lambda e: e.group.second)


class _Program:
    """One problem's program (module doc)."""

    def __init__(self, r: Decider, inside: list[tuple[Estimate, list]], t: float) -> None:
        self.r, self.t = r, t
        self.comp = [e for e, _ in inside]
        sg = r.graph
        self.idx = lambda action: sg.pending_index(sg.step_of(action))
        self.role: dict[int, tuple[int, str, _Visit]] = {}
        """id(visit) -> (candidate, 'u' or 'w', partner)."""
        need: dict[int, int] = {}
        for c, (_, pairs) in enumerate(inside):
            for u, w in pairs:
                self.role[id(u)] = (c, "u", w)
                self.role[id(w)] = (c, "w", u)
                for a, act in ((u.agv, u.leave), (w.agv, w.leave)):
                    need[a] = max(need.get(a, 0), self.idx(act) + 1)
        adg = r.adg
        self.win: dict[int, int] = {}
        for a, n in sorted(need.items()):
            self.win[a] = min(max(n, r.horizon), len(adg._agents[a].pending))
        for a in sorted(need):  # followers: right behind the group AGVs' visits
            for step in islice(adg._agents[a].pending, self.win[a]):
                for v in step.enter_visits:
                    q = adg._queues[v.cell]
                    i = q.index(v)
                    if i + 1 < len(q) and q[i + 1].agv not in self.win:
                        f = q[i + 1]
                        k = self.idx(f.enter) if f.enter is not None else -1
                        if 0 <= k < 2 * r.horizon:
                            self.win[f.agv] = min(max(k + 1, 1), len(
                                adg._agents[f.agv].pending))
        self.agvs = sorted(self.win)
        self.col: dict[tuple[int, int], int] = {}
        self.times: dict[int, tuple[list[float], list[float]]] = {}
        for a in self.agvs:
            # (waits on the graph are the program's constraints, not the estimate's)
            self.times[a] = r.times(a, self.win[a] - 1, t, r.wait_depth)
            for k in range(self.win[a]):
                self.col[(a, k)] = len(self.col)
        self.nb = len(self.comp)
        self.rows: list[tuple[dict[int, float], float]] = []
        self.lower = np.zeros(len(self.col) + self.nb)
        for a in self.agvs:
            self.lower[self.col[(a, 0)]] = self.times[a][0][0]

    # ----------------------------------------------------------------- building

    def dur(self, a: int, k: int) -> float:
        s, e = self.times[a]
        return e[k] - s[k]

    def _ge(self, coef: dict[int, float], rhs: float) -> None:
        """``sum coef x >= rhs``."""
        self.rows.append((coef, rhs))

    def _after(self, a: int, k: int, p: _Visit,
               cond: tuple[int, int] | None = None) -> None:
        """Action ``k`` of ``a`` starts after visit ``p`` has left its cell; with
        ``cond = (column, value)`` only when that binary takes that value (big-M)."""
        if p.leave is None or p.agv == a:
            return
        kp = self.idx(p.leave)
        coef = {self.col[(a, k)]: 1.0}
        if p.agv in self.win:
            kp = min(kp, self.win[p.agv] - 1)
            if kp < 0:
                return
            coef[self.col[(p.agv, kp)]] = -1.0
            rhs = self.dur(p.agv, kp)
        elif kp < 0:
            rhs = self.r.ready_s(p.agv, self.t)[0]
        elif kp < 2 * self.r.horizon:
            rhs = self.r.times(p.agv, kp, self.t)[1][kp]
        else:
            return
        if cond is not None:
            col, value = cond
            coef[col] = self.big if value == 0 else -self.big
            rhs -= 0.0 if value == 0 else self.big
        elif len(coef) == 1:
            me = self.col[(a, k)]
            self.lower[me] = max(self.lower[me], rhs)
            return
        self._ge(coef, rhs)

    def _pair(self, a: int, k: int, w: _Visit, c: int, u: _Visit) -> None:
        """Candidate ``c``'s cell: ``w`` (action ``k`` of ``a``) after ``u`` and the
        visits between them unless switched, they after ``w`` if switched; the visit
        before ``u`` before all of them."""
        q = self.r.adg._queues[w.cell]
        iu, iw = q.index(u), q.index(w)
        b = len(self.col) + c
        for x in q[iu:iw]:
            self._after(a, k, x, (b, 0))
            if x.agv in self.win and x.enter is not None:
                kx = self.idx(x.enter)
                if 0 <= kx < self.win[x.agv]:
                    self._after(x.agv, kx, w, (b, 1))
        if iu >= 1:
            self._after(a, k, q[iu - 1])

    def build(self) -> None:
        adg = self.r.adg
        span = max((e[-1] for _, e in self.times.values() if e), default=self.t)
        self.big = 4.0 * (span - self.t) + 1000.0
        for a in self.agvs:
            s = self.times[a][0]
            for k in range(1, self.win[a]):
                self._ge({self.col[(a, k)]: 1.0, self.col[(a, k - 1)]: -1.0}, s[k] - s[k - 1])
            for k, step in enumerate(islice(adg._agents[a].pending, self.win[a])):
                for v in step.enter_visits:
                    q = adg._queues[v.cell]
                    i = q.index(v)
                    got = self.role.get(id(v))
                    if got is not None:
                        c, role, partner = got
                        if role == "w":
                            self._pair(a, k, v, c, partner)
                        elif i >= 1:  # u: (its order with w comes with w's)
                            self._after(a, k, q[i - 1])
                        continue
                    if i == 0:
                        continue
                    self._after(a, k, q[i - 1])
                    prev = self.role.get(id(q[i - 1]))
                    if prev is not None and prev[1] == "w" and i >= 2:
                        self._after(a, k, q[i - 2])  # behind a pair: after both

    # ----------------------------------------------------------------- solving

    def solve(self) -> list[Estimate] | None:
        """The candidates the optimum switches; None without a proved optimum."""
        from scipy.optimize import Bounds, LinearConstraint, milp
        from scipy.sparse import csr_matrix

        r = self.r
        self.build()
        n = len(self.col) + self.nb
        c = np.zeros(n)
        for a in self.agvs:
            c[self.col[(a, self.win[a] - 1)]] = 1.0
        # a switch must pay the margin; one that keeps a driving AGV from stopping saves
        # its stop too (Estimate.brake_s)
        c[len(self.col):] = [r.margin_s - e.brake_s for e in self.comp]
        data, ri, ci, lb = [], [], [], []
        for row, (coef, rhs) in enumerate(self.rows):
            for j, v in sorted(coef.items()):
                data.append(v)
                ri.append(row)
                ci.append(j)
            lb.append(rhs)
        upper = np.full(n, np.inf)
        upper[len(self.col):] = 1.0
        integrality = np.zeros(n)
        integrality[len(self.col):] = 1
        cons = []
        if self.rows:
            a = csr_matrix((data, (ri, ci)), shape=(len(self.rows), n))
            cons.append(LinearConstraint(a, np.array(lb), np.full(len(lb), np.inf)))
        options = {"node_limit": r.node_limit, "disp": False}
        if r.time_limit_s is not None:
            options["time_limit"] = float(r.time_limit_s)
        r.milp_solves += 1
        res = milp(c, integrality=integrality, bounds=Bounds(self.lower, upper),
                   constraints=cons, options=options)
        if res.status != 0 or res.x is None:
            return None
        b = res.x[len(self.col):]
        return [e for e, x in zip(self.comp, b, strict=True) if x > 0.5]
