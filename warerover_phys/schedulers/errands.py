"""The errand-task scheduler: assigns errand tasks (``orders.pattern: errands``) to free
AGVs by the rule of ``orders.errands.assign`` (:mod:`warerover_phys.problems.errands`):

- ``roundrobin``: each released task names its AGV (``Order.for_agv``);
- ``greedy``: free AGVs in id order take the pending tasks in id order;
- ``pool``: free AGVs in id order each take the pending task whose first errand is nearest
  (Manhattan distance on the grid; ties go to the task released first), the start kit's
  default scheduler of 2024 and later. All free AGVs x open tasks are costed in one array
  pass (compiled with numba when it imports).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .base import Assignment

if TYPE_CHECKING:
    from ..config import SchedulerSpec
    from .base import SchedulerView

__all__ = ["ErrandScheduler", "nearest_first"]


class ErrandScheduler:
    name = "errands"

    def __init__(self, spec: SchedulerSpec) -> None:
        self.spec = spec

    def assign(self, world: SchedulerView, rng: np.random.Generator) -> list[Assignment]:
        pending = world.pending_orders()
        if not pending:
            return []
        idle = world.idle_agvs()
        if not idle:
            return []
        rule = world.errand_rule
        if rule == "roundrobin":
            mine = {o.for_agv: o.id for o in pending}
            return [Assignment(a.id, -1, (mine[a.id],)) for a in idle if a.id in mine]
        if rule == "greedy":
            return [Assignment(a.id, -1, (o.id,)) for a, o in zip(idle, pending, strict=False)]
        cols = world.layout.cols
        first = np.fromiter((o.errands[0] for o in pending), dtype=np.int64, count=len(pending))
        here = np.fromiter((a.node for a in idle), dtype=np.int64, count=len(idle))
        pick = nearest_first(first // cols, first % cols, here // cols, here % cols)
        out = []
        for a, j in zip(idle, pick.tolist(), strict=True):
            if j < 0:
                break
            out.append(Assignment(a.id, -1, (pending[j].id,)))
        return out


def nearest_first(fr: np.ndarray, fc: np.ndarray, rr: np.ndarray, rc: np.ndarray) -> np.ndarray:
    """For robots at ``(rr, rc)`` in turn, the index of the nearest still-open task (first
    errand at ``(fr, fc)``, Manhattan; the lowest index among equals), -1 once none is left."""
    try:
        from ..planning.pibt.kernels import AVAILABLE, nearest_open
    except ImportError:  # pragma: no cover - numba is a dependency
        AVAILABLE = False
    if AVAILABLE:
        return nearest_open(fr, fc, rr, rc)
    out = np.full(len(rr), -1, dtype=np.int64)
    taken = np.zeros(len(fr), dtype=bool)
    far = np.iinfo(np.int64).max
    for i in range(len(rr)):
        d = np.abs(fr - rr[i]) + np.abs(fc - rc[i])
        d[taken] = far
        if not len(d):
            break
        j = int(np.argmin(d))
        if taken[j]:
            break
        taken[j] = True
        out[i] = j
    return out
