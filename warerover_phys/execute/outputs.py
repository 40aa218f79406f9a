"""What an execution writes (:func:`write_execution`) and the executed plan."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..config import AgvTypeSpec
from ..layout import Layout
from ..plans.model import Plan
from .run import ExecutionResult


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

    from ..outputs import _savez
    from ..util.atomic import write_set

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
    from ..executors.grid_record import grid_execution, state_array
    from ..poses import states_poses

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
