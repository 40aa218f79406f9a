"""The open-loop gap: one fixed plan executed unchanged on physics, compared action by
action, with every AGV's lost time split into causes.

:func:`execute_timed` drives an executor with a :class:`~.gap_plan.TimedPlan` as
:func:`warerover_phys.execute.execute_plan` does a MAPF plan (no scheduler, no planner, no
replanning; the physics executor follows the action dependency graph), and tells it the
plan's dwells (``TickView.dwells``) so that every pick, hand-over, place and parking takes
at least its planned time. :func:`compare` turns the executor's per-action record
(:class:`~.executors.causes.CauseLog`) into the report.

**Lost time.** AGV i's lost time is its executed finish minus its planned finish (seconds;
negative when it runs ahead of the plan). Its executed timeline is cut into *intervals*, one
per action: from the finish of the previous action (or time 0) to the finish of this one.
Every physics step of an interval carries one label (``drive``, ``turn``, ``dependency``,
``control``, ``injected``, ``failed``, ``dwell``, see :mod:`.executors.causes`). The planned
interval of the same action is its dwell ``d``, its plain waits ``w`` and its move ``p``
(ticks x ``tick_s``). The action's lost time (executed interval - planned interval) is split
by crediting the planned durations against the labelled time:

- ``accel_decel`` = max(0, drive - p) and ``faster_than_plan`` = min(0, drive - p): the move
  took longer (starting, braking) or less (a body faster than one cell per tick) than planned;
- ``dwell_overrun`` = dwell - d (0 when holds work: a dwell lasts exactly its planned time);
- the planned waits ``w`` are credited against the standing time in the order dependency,
  turning, control, injected, failures (a wait the plan had anyway costs nothing); what is
  left of each is its part (``dependency``, ``turning``, ``control``, ``injected``,
  ``failures``), and planned waits that nothing used are ``plan_waits_skipped`` (<= 0: the
  dependency graph skips waits the plan did not need);
- ``freeze_recovery``: 0 (a fixed plan on the dependency graph cannot freeze; kept so the
  columns are the same as the closed loop's);
- ``reorder_gain`` (<= 0; ``executor.reorder``, :mod:`.executors.reorder`): minus the
  dependency wait that switched edges saved the AGV, as estimated when each was switched.
  ``dependency`` is then the wait under the plan's passing order: the measured wait plus
  the saved wait, credited against planned waits as above; the two together are the
  measured wait. (The wait a switch adds to the AGV that now passes second is measured,
  in its ``dependency``.) 0 without reordering;
- ``rotation_repair`` (per AGV, not per action): ticks the rotation repair
  (:func:`.gap_plan.repair_rotations`) added to the AGV's planned finish. Executed are the
  repaired plan's actions, compared with the repaired plan; the planned side of the figures
  (finish, makespan, sum of costs, orders) stays the plan as given, so this part is what
  the repair put between the two (the ``repaired_*`` figures are beside). Ticks the repair
  inserted that the dependency graph does not need come back as ``plan_waits_skipped``.

The parts of an action add up to its lost time exactly (integer physics steps), and the
sum over an AGV's actions telescopes to its lost time (plus a trailing dwell, held exactly,
and ``rotation_repair``).
Per AGV the dependency waits are also given per blocker (executed seconds, before crediting).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np

from ..executors.base import AgvBody, ExecutorSetup, TickView, record_report
from ..executors.causes import (
    CONTROL,
    DEPENDENCY,
    DRIVE_L,
    DWELL,
    FAILED,
    INJECTED,
    TURN_L,
    CauseLog,
)
from .ideal_plan import PlannedAction, TimedPlan

__all__ = ["PARTS", "OpenLoopRun", "execute_timed", "compare", "open_loop_report"]

PARTS = ("dependency", "accel_decel", "turning", "control", "injected", "failures",
         "rotation_repair", "freeze_recovery", "dwell_overrun", "reorder_gain",
         "faster_than_plan", "plan_waits_skipped")
"""The parts of lost time (seconds), in report order; the last three are <= 0."""
_CREDIT = ((DEPENDENCY, "dependency"), (TURN_L, "turning"), (CONTROL, "control"),
           (INJECTED, "injected"), (FAILED, "failures"))


@dataclass
class OpenLoopRun:
    """What :func:`execute_timed` measured."""

    plan: TimedPlan
    executed: dict[int, list[tuple[int, int]]]
    """Executed state per tick per AGV, from tick 0."""
    ticks: int
    completed: bool
    summary: dict[str, Any]
    """The executor's figures."""
    log: CauseLog | None
    trajectory: dict | None
    wall_s: float
    events: list[dict]


def execute_timed(plan: TimedPlan, executor_spec, *, seed: int = 0,
                  max_ticks: int | None = None,
                  progress: Callable[[int, int], None] | None = None,
                  before_tick: Callable[[int, Any], None] | None = None) -> OpenLoopRun:
    """Execute ``plan`` unchanged on the executor ``executor_spec`` (an ``ExecutorSpec``;
    its delays, dt and parameters apply). ``seed``: the episode seed whose ``delays``
    stream the executor draws from, as in the closed loop. ``before_tick(tick, executor)``
    is called before each tick's step (a test injects a delay of its choosing there)."""
    from ..registry import build
    from ..world import make_rngs

    ex = build("executor", executor_spec)
    n = plan.num_agents
    paths = plan.paths
    ex.bind(ExecutorSetup(layout=plan.layout, tick_s=plan.tick_s, rng=make_rngs(seed)["delays"],
                          agvs=tuple(AgvBody(i, t.footprint, t, paths[i].states[0])
                                     for i, t in enumerate(plan.types))))
    horizon = max((len(p.states) - 1 for p in paths.values()), default=0)
    limit = max_ticks if max_ticks is not None else max(100, 10 * horizon + 200)
    plans = MappingProxyType(dict(paths))
    dwells = plan.dwell_view
    final = {i: p.states[-1] for i, p in paths.items()}
    acts = {i: plan.actions(i) for i in range(n)}
    tracker = _Progress(plan, acts)
    executed = {i: [paths[i].states[0]] for i in range(n)}
    behind = [0] * n
    events: list[dict] = []
    down = _down_by_tick(plan)
    wall0 = time.perf_counter()
    tick = 0
    done = False
    while tick < limit:
        loaded, carried, task = tracker.cargo(tick)
        failed = down.get(tick, frozenset())
        if failed:
            task = tuple(7 if i in failed else s for i, s in enumerate(task))  # FAILED
        view = TickView(tick=tick, plans=plans, behind=tuple(behind), failed=failed,
                        loaded=loaded, carried=carried, task_state=task, dwells=dwells)
        if before_tick is not None:
            before_tick(tick, ex)
        report = ex.step(view)
        record_report(report, tick, executed, behind, events)
        tick += 1
        tracker.update(tick, report.states)
        if progress is not None:
            progress(tick, horizon)
        if tick >= 1 and all(executed[i][-1] == final[i] for i in range(n)) and \
                not any(ex.remaining(i) for i in range(n)):
            done = True
            break
    wall = time.perf_counter() - wall0
    log = ex.cause_log() if hasattr(ex, "cause_log") else None
    return OpenLoopRun(plan=plan, executed=executed, ticks=tick, completed=done,
                       summary=ex.summary(), log=log, trajectory=ex.trajectory(),
                       wall_s=wall, events=events)


def _down_by_tick(plan: TimedPlan) -> dict[int, frozenset[int]]:
    """AGVs down at each tick: the plan's failures (those of its grid run) replayed at the
    same ticks for the same number of ticks, whatever the AGV is doing then."""
    out: dict[int, set[int]] = {}
    for f in plan.failures:
        for t in range(f.tick, f.tick + f.ticks):
            out.setdefault(t, set()).add(f.agv)
    return {t: frozenset(s) for t, s in out.items()}


class _Progress:
    """Where each AGV is in its plan (from the executed states), to tell the executor its
    cargo and task state at the plan's matching tick while it runs ahead or behind."""

    def __init__(self, plan: TimedPlan, acts: dict[int, list[PlannedAction]]) -> None:
        self.plan, self.acts = plan, acts
        n = plan.num_agents
        self.done = [0] * n
        self.running = [False] * n
        self.since = [0] * n  # executed tick it last stood still after a move
        self.last = (plan.task_state.shape[0] - 1) if plan.task_state is not None else 0

    def update(self, tick: int, states: dict[int, tuple[int, int]]) -> None:
        for i, (a, b) in states.items():
            acts, k = self.acts[i], self.done[i]
            if a != b:
                for j in range(k, min(k + 64, len(acts))):
                    if acts[j].src == a and acts[j].dst == b:
                        self.done[i], self.running[i] = j, True
                        break
            else:
                for j in range(k, min(k + 64, len(acts)) + 1):
                    node = acts[j - 1].dst if j else self.plan.paths[i].states[0][0]
                    if node == a:
                        if j != k or self.running[i]:
                            self.since[i] = tick
                        self.done[i], self.running[i] = j, False
                        break

    def _tau(self, i: int, tick: int) -> int:
        """The plan tick whose cargo the AGV has during executed tick ``tick``. A standing
        AGV is one tick ahead of its time on the cell: its dwell may end within this tick
        and its next move start, and that move must carry the plan's cargo at its start
        (a shelf put down stays behind, a shelf picked up comes along); a tick early is
        harmless while it stands."""
        acts, k = self.acts[i], self.done[i]
        if self.running[i]:
            return acts[k].tick + 1
        start = acts[k - 1].finish if k else 0
        stop = acts[k].tick if k < len(acts) else self.last
        return max(0, min(start + (tick - self.since[i]) + 1, stop))

    def cargo(self, tick: int) -> tuple[tuple, tuple, tuple]:
        plan = self.plan
        n = plan.num_agents
        if plan.task_state is None:
            return (False,) * n, (None,) * n, (0,) * n
        taus = [min(self._tau(i, tick), self.last) for i in range(n)]
        loaded = tuple(bool(plan.loaded[t, i]) for i, t in enumerate(taus))
        carried = tuple(None if plan.carried[t, i] < 0 else int(plan.carried[t, i])
                        for i, t in enumerate(taus))
        task = tuple(int(plan.task_state[t, i]) for i, t in enumerate(taus))
        return loaded, carried, task


# ----------------------------------------------------------------------------- comparison

def _blockers(log, n: int) -> dict[int, list[tuple[int, float]]]:
    """Each AGV's blockers ``[(blocker, seconds), ...]``, most first."""
    blockers: dict[int, list[tuple[int, float]]] = {i: [] for i in range(n)}
    for (i, b), steps in log.blockers.items():
        blockers[i].append((b, steps * log.dt_s))
    for i in blockers:
        blockers[i].sort(key=lambda x: (-x[1], x[0]))
    return blockers


def _action_parts(a, c, spt: int) -> dict[str, int]:
    """One action's lost physics steps split into :data:`PARTS` (``c``: its cause counts);
    their sum is the action's interval lost."""
    p, d, w = a.ticks * spt, a.dwell * spt, a.wait * spt
    drive = int(c[DRIVE_L])
    ap = dict.fromkeys(PARTS, 0)
    ap["accel_decel"] = max(0, drive - p)
    ap["faster_than_plan"] = min(0, drive - p)
    ap["dwell_overrun"] = int(c[DWELL]) - d
    credit = w
    for lab, name in _CREDIT:
        used = min(credit, int(c[lab]))
        ap[name] = int(c[lab]) - used
        credit -= used
    ap["plan_waits_skipped"] = -credit
    return ap


def compare(run: OpenLoopRun) -> tuple[list[dict], list[dict], dict[int, list[tuple]]]:
    """Per-AGV rows, per-action rows and per-AGV blockers ``[(blocker, seconds), ...]``
    (most first) of an open-loop run (see the module docstring for the parts)."""
    plan, log = run.plan, run.log
    n = plan.num_agents
    tick_s = plan.tick_s
    if log is None:
        raise ValueError("the executor keeps no per-action record (cause_log): the open-"
                         "loop split of lost time needs the physics executor")
    spt, dt = log.steps_per_tick, log.dt_s
    order = np.lexsort((log.seq, log.agv))
    by_agv: dict[int, list[int]] = {i: [] for i in range(n)}
    for r in order.tolist():
        by_agv[int(log.agv[r])].append(r)
    blockers = _blockers(log, n)
    agents, actions = [], []
    for i in range(n):
        acts = plan.actions(i)
        rows = by_agv[i]
        parts = dict.fromkeys(PARTS, 0)  # integer steps
        complete = len(rows) == len(acts)
        prev_exec = 0
        for a, r in zip(acts, rows, strict=False):
            c = log.counts[r]
            gain = int(log.reorder_gain[r]) if log.reorder_gain is not None else 0
            if gain:  # the wait the plain order would have had (module doc)
                c = c.copy()
                c[DEPENDENCY] += gain
            fin = int(log.finish_step[r])
            ap = _action_parts(a, c, spt)
            ap["reorder_gain"] = -gain
            interval_lost = (fin - prev_exec) - (a.ticks + a.wait + a.dwell) * spt
            assert sum(ap.values()) == interval_lost, (i, a.seq, ap, interval_lost)
            for k, v in ap.items():
                parts[k] += v
            actions.append({
                "agv": i, "seq": a.seq, "src": list(divmod(a.src, plan.layout.cols)),
                "dst": list(divmod(a.dst, plan.layout.cols)),
                "planned_start_tick": a.tick, "planned_finish_tick": a.finish,
                "planned_dwell_ticks": a.dwell, "planned_wait_ticks": a.wait,
                "executed_start_s": int(log.start_step[r]) * dt,
                "executed_finish_s": fin * dt,
                "lost_s": fin * dt - a.finish * tick_s,
                "interval_lost_s": interval_lost * dt,
                "dependency_wait_s": (int(c[DEPENDENCY]) - gain) * dt,
                **{f"lost_{k}_s": v * dt for k, v in ap.items()}})
            prev_exec = fin
        trailing = plan.trailing_dwell(i)
        planned = plan.given_planned_finish(i)
        # ticks a rotation repair added to the plan (0 for a plan as given)
        parts["rotation_repair"] = (plan.planned_finish(i) - planned) * spt
        if complete:
            executed_s = prev_exec * dt + trailing * tick_s
            lost_steps = prev_exec - (acts[-1].finish if acts else 0) * spt \
                + parts["rotation_repair"]
            lost_s = lost_steps * dt
        else:
            executed_s = math.nan
            lost_s = math.nan
        t = plan.types[i]
        row: dict[str, Any] = {
            "agv": i, "footprint": t.footprint, "max_speed_mps": t.max_speed_mps,
            "actions": len(acts), "completed": complete,
            "planned_finish_s": planned * tick_s, "executed_finish_s": executed_s,
            "repaired_planned_finish_s": plan.planned_finish(i) * tick_s,
            "lost_s": lost_s,
            **{f"lost_{k}_s": v * dt for k, v in parts.items()},
            "dependency_wait_s": sum(s for _, s in blockers[i]),
            "top_blockers": [[b, round(s, 6)] for b, s in blockers[i][:3]],
        }
        agents.append(row)
    return agents, actions, blockers


def _stat(values: list[float]) -> tuple[float, float]:
    arr = np.asarray([v for v in values if not math.isnan(v)], dtype=float)
    return (float(arr.sum()), float(arr.mean())) if len(arr) else (0.0, 0.0)


def open_loop_report(run: OpenLoopRun) -> tuple[dict, list[dict], list[dict]]:
    """The report of an open-loop run: a flat dict of figures (plus ``grid`` and
    ``physics``), the per-AGV rows and the per-action rows."""
    plan = run.plan
    tick_s = plan.tick_s
    agents, actions, _ = compare(run)
    n = len(agents)
    pf = [a["planned_finish_s"] for a in agents]
    ef = [a["executed_finish_s"] for a in agents]
    p_ms, e_ms = max(pf, default=0.0), max(ef, default=0.0)
    p_soc, e_soc = sum(pf), sum(ef)
    out: dict[str, Any] = {
        "mode": "open-loop", "source": plan.source, "agents": n, "tick_s": tick_s,
        "completed": run.completed and all(a["completed"] for a in agents),
        "planned_makespan_s": p_ms, "executed_makespan_s": e_ms,
        "makespan_ratio": e_ms / p_ms if p_ms else 1.0,
        "planned_sum_of_costs_s": p_soc, "executed_sum_of_costs_s": e_soc,
        "sum_of_costs_ratio": e_soc / p_soc if p_soc else 1.0,
        "makespan_grid_ticks": int(round(p_ms / tick_s)),
        "makespan_physics_ticks": int(math.ceil(e_ms / tick_s - 1e-9)) if e_ms == e_ms else None,
    }
    out.update(_order_figures(run, agents, actions))
    out.update(_repair_figures(plan, agents))
    out["failures"] = len(plan.failures)
    out["failure_down_ticks"] = sum(f.ticks for f in plan.failures)
    lost = [a["lost_s"] for a in agents]
    out["lost_s_fleet_total"], out["lost_s_per_agv_mean"] = _stat(lost)
    out["lost_s_per_agv_max"] = max((v for v in lost if v == v), default=0.0)
    for k in PARTS:
        tot, mean = _stat([a[f"lost_{k}_s"] for a in agents])
        out[f"lost_{k}_s_fleet_total"], out[f"lost_{k}_s_per_agv_mean"] = tot, mean
    out["actions"] = len(actions)
    out["actions_late"] = sum(1 for a in actions if a["lost_s"] > 1e-9)
    out["action_lost_s_mean"] = float(np.mean([a["lost_s"] for a in actions])) if actions \
        else 0.0
    out["replans"] = 0
    summ = run.summary
    for key in ("agv_contacts", "static_contacts", "min_clearance_m", "min_separation_m",
                "limit_violations", "deadlocks",
                "delay_dependency_wait_s", "delay_kinematic_s", "delay_turns_s",
                "delay_injected_s", "real_time_factor"):
        out[key] = summ.get(key)
    out["physics"] = {**summ, "ticks": out["makespan_physics_ticks"],
                      "ticks_run": run.ticks, "open_loop_wall_s": run.wall_s}
    out["grid"] = plan.grid_metrics
    return out, agents, actions


def _repair_figures(plan: TimedPlan, agents: list[dict]) -> dict:
    """The rotation repairs of the plan (:func:`.gap_plan.repair_rotations`): how many,
    which AGVs, ticks added, and the repaired plan's makespan and sum of costs beside the
    plan as given (the planned figures stay those of the plan as given)."""
    rf = [a["repaired_planned_finish_s"] for a in agents]
    added = [round((a["repaired_planned_finish_s"] - a["planned_finish_s"]) / plan.tick_s)
             for a in agents]
    return {"cycle_repairs": len(plan.repairs),
            "cycle_repair_moves": sum(r.moves for r in plan.repairs),
            "cycle_repair_agvs": len({i for r in plan.repairs for i in r.agents}),
            "cycle_repair_added_ticks": int(sum(added)),
            "repaired_makespan_s": max(rf, default=0.0),
            "repaired_sum_of_costs_s": sum(rf),
            "cycle_repairs_detail": [r.as_dict() for r in plan.repairs],
            "cycle_repair_added_ticks_by_agv": {str(a["agv"]): t
                                                for a, t in zip(agents, added, strict=True)
                                                if t}}


def _order_figures(run: OpenLoopRun, agents: list[dict], actions: list[dict]) -> dict:
    """Orders of a recorded plan: each completes at the end of a hand-over dwell; executed,
    that dwell starts when the AGV arrives (finish of the move before it)."""
    plan = run.plan
    if not plan.orders:
        return {}
    tick_s = plan.tick_s
    fin: dict[tuple[int, int], float] = {(a["agv"], a["seq"]): a["executed_finish_s"]
                                         for a in actions}
    ends: dict[int, list[tuple[int, float]]] = {}  # agv -> [(planned end tick, executed)]
    for i in range(plan.num_agents):
        acts = plan.actions(i)
        for d in plan.dwells.get(i, ()):
            if d.kind != "handover":
                continue
            k = sum(1 for a in acts if a.tick < d.tick)  # moves before the dwell
            arrive = fin.get((i, k - 1), 0.0) if k else 0.0
            ends.setdefault(i, []).append((d.tick + d.ticks, arrive + d.ticks * tick_s))
    planned, executed, lat_p, lat_e = [], [], [], []
    for o in plan.orders:
        # The latest hand-over dwell of its AGV that began before the completion (the grid
        # record may log the completion a tick after the AGV has left: it is shifted alike).
        cands = [(end, e) for end, e in ends.get(o["agv"], ()) if end - 1 < o["completed_tick"]]
        if not cands:
            continue
        end, e = max(cands)
        e += (o["completed_tick"] - end) * tick_s
        given = o.get("given_completed_tick", o["completed_tick"])  # before a repair
        planned.append(given * tick_s)
        executed.append(e)
        lat_p.append(given * tick_s - o["arrival_tick"] * tick_s)
        lat_e.append(e - o["arrival_tick"] * tick_s)
    if not planned:
        return {}
    pm, em = max(planned), max(executed)
    return {"orders": len(planned), "planned_orders_makespan_s": pm,
            "executed_orders_makespan_s": em,
            "orders_makespan_ratio": em / pm if pm else 1.0,
            "tp_ratio": pm / em if em else None,
            "latency_ratio": float(np.mean(lat_e) / np.mean(lat_p)) if np.mean(lat_p) else None}


# ----------------------------------------------------------------------------- motion timing

MOTION_UNIT_KEYS = ("planned_makespan_s", "makespan_ratio", "planned_sum_of_costs_s",
                    "sum_of_costs_ratio", "planned_orders_makespan_s", "orders_makespan_ratio",
                    "tp_ratio", "latency_ratio", "lost_s_fleet_total", "lost_s_per_agv_mean",
                    "lost_s_per_agv_max", "actions_late", "action_lost_s_mean")
"""Report figures that motion timing takes from the schedule; their unit values are kept
as ``KEY_unit``."""


def motion_timed(report: dict, agents: list[dict], actions: list[dict], plan: TimedPlan,
                 sched) -> tuple[dict, list[dict], list[dict]]:
    """The open-loop report, per-AGV and per-action rows with the *planned* side timed by
    ``sched`` (a :class:`~warerover_phys.planning.timing.Schedule` of ``plan``;
    ``planner.timing: motion``): planned finish, makespan, sum of costs and the orders'
    completion come from the schedule, and every ratio and lost time is against it. The
    unit figures stay beside them (``KEY_unit``, per AGV ``planned_finish_unit_s`` and
    ``lost_unit_s``, per action ``lost_unit_s``). The split of lost time into causes stays
    the unit plan's: the parts add up to ``lost_unit_s`` (``lost_parts_timing``)."""
    new_agents = []
    for a in agents:
        i = a["agv"]
        planned = float(sched.finish_s[i])
        done = a["executed_finish_s"]
        new_agents.append({**a, "planned_finish_s": planned,
                           "planned_finish_unit_s": a["planned_finish_s"],
                           "lost_s": done - planned if a["completed"] else math.nan,
                           "lost_unit_s": a["lost_s"]})
    new_actions = []
    for act in actions:
        t = sched.actions[act["agv"]][act["seq"]]
        new_actions.append({**act, "planned_start_s": t.start_s, "planned_finish_s": t.finish_s,
                            "planned_turn_s": t.turn_s,
                            "lost_s": act["executed_finish_s"] - t.finish_s,
                            "lost_unit_s": act["lost_s"]})
    out = dict(report)
    for k in MOTION_UNIT_KEYS:
        if k in report:
            out[f"{k}_unit"] = report[k]
    pf = [a["planned_finish_s"] for a in new_agents]
    p_ms, p_soc = max(pf, default=0.0), sum(pf)
    e_ms, e_soc = report["executed_makespan_s"], report["executed_sum_of_costs_s"]
    out.update({"timing": "motion", "lost_parts_timing": "unit",
                "planned_makespan_s": p_ms, "makespan_ratio": e_ms / p_ms if p_ms else 1.0,
                "planned_sum_of_costs_s": p_soc,
                "sum_of_costs_ratio": e_soc / p_soc if p_soc else 1.0,
                "schedule_splits": sched.splits, "schedule_dependencies": sched.dependencies})
    out.update(_motion_order_figures(plan, sched, report))
    lost = [a["lost_s"] for a in new_agents]
    out["lost_s_fleet_total"], out["lost_s_per_agv_mean"] = _stat(lost)
    out["lost_s_per_agv_max"] = max((v for v in lost if v == v), default=0.0)
    out["actions_late"] = sum(1 for a in new_actions if a["lost_s"] > 1e-9)
    out["action_lost_s_mean"] = float(np.mean([a["lost_s"] for a in new_actions])) \
        if new_actions else 0.0
    return out, new_agents, new_actions


def _motion_order_figures(plan: TimedPlan, sched, report: dict) -> dict:
    """The orders' planned completion in the schedule: the end of the hand-over dwell that
    completes each order, from the scheduled arrival of the move before it (as
    :func:`_order_figures` reckons the executed side)."""
    if not plan.orders or "executed_orders_makespan_s" not in report:
        return {}
    tick_s = plan.tick_s
    ends: dict[int, list[tuple[int, float]]] = {}
    for i in range(plan.num_agents):
        acts = plan.actions(i)
        timed = sched.actions[i]
        for d in plan.dwells.get(i, ()):
            if d.kind != "handover":
                continue
            k = sum(1 for a in acts if a.tick < d.tick)
            arrive = timed[k - 1].finish_s if k else 0.0
            ends.setdefault(i, []).append((d.tick + d.ticks, arrive + d.ticks * tick_s))
    planned, lat, lat_unit = [], [], []
    for o in plan.orders:
        cands = [(end, p) for end, p in ends.get(o["agv"], ()) if end - 1 < o["completed_tick"]]
        if not cands:
            continue
        end, p = max(cands)
        p += (o["completed_tick"] - end) * tick_s
        planned.append(p)
        lat.append(p - o["arrival_tick"] * tick_s)
        given = o.get("given_completed_tick", o["completed_tick"])  # as _order_figures
        lat_unit.append((given - o["arrival_tick"]) * tick_s)
    if not planned:
        return {}
    pm, em = max(planned), report["executed_orders_makespan_s"]
    out = {"planned_orders_makespan_s": pm, "orders_makespan_ratio": em / pm if pm else 1.0,
           "tp_ratio": pm / em if em else None}
    ratio_unit = report.get("latency_ratio")
    if ratio_unit is not None and np.mean(lat_unit) and np.mean(lat):
        # the executed mean latency is the unit ratio times the unit planned mean
        out["latency_ratio"] = float(ratio_unit * np.mean(lat_unit) / np.mean(lat))
    return out
