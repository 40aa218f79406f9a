"""Scenario schema: the scheduler and the planner (with invoke and latency settings)."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import (
    field_validator,
)

from .types import (
    MAX_FLOAT,
    MAX_TICKS,
    Budget,
    Params,
    PlannerName,
    PosFloat,
    PosInt,
    SchedulerName,
    Ticks,
    _Model,
)


class SchedulerSpec(_Model):
    name: SchedulerName = "ta"
    """``rd``, ``ta``, an entry point, or a plugin class ``package.module:ClassName``."""
    params: Params = {}
    """Parameters of a plug-in scheduler (its ``Params`` model)."""
    max_orders_per_trip: PosInt = 4
    """Orders one shelf trip may serve (TA batches orders of the shelf's SKUs)."""
    candidate_shelves: PosInt = 3
    """TA: nearest shelves per SKU considered when costing an AGV x group pair."""
    ta_cost: Literal["per_order", "trip"] = "per_order"
    """TA: cost of an (AGV, SKU group) pair: its trip length divided by the orders it serves
    (``per_order``), or the trip length alone (``trip``, as WareRover: small groups are then
    preferred)."""


def parse_invoke(text: str) -> tuple[str, float]:
    """``planner.invoke`` as (``every_tick`` | ``periodic`` | ``event``, its number)."""
    if not isinstance(text, str):
        raise ValueError("expected every_tick, periodic:S or event:K")
    kind, _, num = text.partition(":")
    if kind == "every_tick" and not num:
        return kind, 0.0
    try:
        value = float(num)
    except ValueError:
        value = math.nan
    if kind == "periodic" and math.isfinite(value) and 0 < value <= MAX_FLOAT:
        return kind, value
    if kind == "event" and value.is_integer() and 1 <= value <= MAX_TICKS:
        return kind, value
    raise ValueError(f"expected every_tick, periodic:S (seconds > 0) or event:K (ticks >= 1), "
                     f"got {text!r}")


def parse_latency(text: str) -> tuple[str, float]:
    """``planner.latency`` as (``none`` | ``measured`` | ``fixed``, seconds)."""
    if text in ("none", "measured"):
        return text, 0.0
    kind, _, num = text.partition(":") if isinstance(text, str) else ("", "", "")
    try:
        value = float(num)
    except ValueError:
        value = math.nan
    if kind == "fixed" and math.isfinite(value) and 0 <= value <= MAX_FLOAT:
        return kind, value
    raise ValueError(f"expected none, measured or fixed:S (seconds >= 0), got {text!r}")


class PlannerSpec(_Model):
    name: PlannerName = "astar"
    """``astar``, ``cbs``, ``pibt``, ``lacam``, an entry point, or a plugin class
    ``package.module:ClassName``."""
    params: Params = {}
    """Parameters of a plug-in planner (its ``Params`` model)."""
    weights: str | None = None
    """``learned``: path of its weights (``.npz``); default the shipped ones."""
    timing: Literal["unit", "motion"] = "unit"
    """How a plan's time is reckoned. ``unit``: one cell move per tick (``ticks_per_move``
    ticks for slow AGVs), turns free, as the planners plan. ``motion``: the same plan timed
    by each AGV type's motion model over the action dependency graph
    (:mod:`~warerover_phys.planning.timing`: runs from rest to rest at the acceleration
    limit, turns in place at the turn rate, dwells, every dependency kept); the open-loop
    gap then takes its planned figures from that schedule (the unit ones beside them as
    ``*_unit``). The closed loop plans in ticks either way."""
    replan_blocked_ticks: Ticks = 3
    """Replan an AGV that could not follow its plan for this many ticks."""
    max_expansions: Budget = 50_000
    """Node budget of one single-agent search; past it the AGV waits and retries."""
    horizon_ticks: Ticks = 20
    """CBS: conflicts between jointly planned AGVs are resolved this many ticks ahead."""
    max_nodes: Budget = 2_000
    """CBS: constraint-tree nodes before falling back to prioritized A* (counted)."""
    max_iterations: Budget = 2_000
    """LaCAM: high-level iterations per planning call before the documented fallback (one
    PIBT step, counted in ``planner_budget_hits``). A work budget: same result on any
    machine."""
    max_call_expansions: Budget = 100_000
    """CBS: low-level A* expansions per planning call (all its searches together) before
    falling back to prioritized A* (counted). A work budget: same result on any machine."""
    time_budget_s: PosFloat = 10.0
    """CBS / LaCAM: a wall-clock safety stop per planning call (seconds). The work budgets
    above decide results; when this stop ends a search first it is counted in
    ``planner_budget_hits`` and logged, as the result then depends on machine speed."""
    invoke: str = "every_tick"
    """When the loop calls the planner: ``every_tick``; ``periodic:S`` (every ``S`` seconds of
    simulated time, rounded to whole ticks); ``event:K`` (when some AGV whose committed path
    does not end on its goal has fewer than ``K`` ticks of it left). Step planners (PIBT)
    then plan ``window_ticks`` steps a call (windowed PIBT). See :mod:`warerover_phys.invoke`."""
    latency: str = "none"
    """How long the planner's computation takes in simulated time: ``none`` (the world waits
    for it, as planners are usually studied), ``measured`` (its wall-clock time) or
    ``fixed:S`` (``S`` seconds). With a latency the world keeps moving while it plans: it
    plans from where the committed paths end at the tick the plan is expected to take
    effect, and the new plan takes effect at the first tick after it is ready (the committed
    prefix of the old plan stays)."""
    window_ticks: Ticks | None = None
    """Steps a step planner plans per call (windowed PIBT). Default: 1 with ``every_tick``,
    twice the period (``periodic``) or ``2 K`` (``event``)."""
    rotation_rule: Literal["cascade", "actions", "turn-first"] = "cascade"
    """How lifelong PIBT meets rotations (``rotations: true``). ``cascade``: the
    footprint-aware step of :mod:`~warerover_phys.planning.pibt.footprint` (any fleet).
    ``actions``: PIBT over the actions forward / turn a quarter / wait, ranked by the
    cost-to-go of the cell and heading each leads to (:mod:`~warerover_phys.planning.
    pibt_heading`); ``turn-first``: PIBT on cells, then AGVs whose cell is not ahead turn
    towards it instead. ``actions`` and ``turn-first`` are the Robot Runners rules: 1x1 AGVs
    that move a cell and turn a quarter in one tick each, compiled (:mod:`~warerover_phys.
    planning.pibt_numba`)."""
    dist_budget_mb: PosFloat = 1024.0
    """Lifelong PIBT of 1x1 fleets (:mod:`~warerover_phys.planning.pibt.compiled`): MiB its
    distance tables (one per goal cell, shared by every AGV) may hold; least recently used
    go first."""
    ties: Literal["low_id", "high_id"] = "low_id"
    """Lifelong PIBT: which AGV goes first among those whose goals are equally old (Robot
    Runners problems: ``high_id``, as the league's runner this project had)."""
    @field_validator("invoke")
    @classmethod
    def _invoke(cls, value: str) -> str:
        parse_invoke(value)
        return value

    @field_validator("latency")
    @classmethod
    def _latency(cls, value: str) -> str:
        parse_latency(value)
        return value

    rotations: bool = False
    """Rotation-aware planning (issue 15): differential-drive AGVs are planned over states
    (cell, heading), move only along their heading and turn in place by quarter turns that
    take the ticks the physics executor needs (``planning.rotation.turn_ticks``: ceil of
    ``quarters x (pi / 2) / max_turn_rate_radps / tick_s``); omnidirectional AGVs are
    unchanged. False (default): turns are free, as in one-cell-per-tick MAPF."""
