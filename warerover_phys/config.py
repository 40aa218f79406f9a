"""Scenario schema: one YAML file describes a whole episode.

The schema is closed (unknown keys are errors) and frozen (nothing mutates a scenario after it
is built). Units are in the field names: ``_m`` metres, ``_s`` seconds, ``_mps`` m/s,
``_mps2`` m/s^2, ``_radps`` rad/s, ``_ticks`` planning ticks.

>>> from warerover_phys.config import scenario_from_dict
>>> sc = scenario_from_dict({"layout": {"grid": ["P..R"]}, "fleet": {"agvs": [{"count": 1}]}})
>>> sc.scheduler.name, sc.planner.name, sc.executor.name
('ta', 'astar', 'grid')
"""

from __future__ import annotations

import copy
import math
import re
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from .errors import ScenarioError
from .util import safe_yaml

__all__ = [
    "AgvTypeSpec", "AgvGroupSpec", "FleetSpec", "ShelfBlockSpec", "RectSpec", "InventorySpec",
    "GeneratorSpec", "LayoutSpec", "ErrandsSpec", "OrdersSpec", "SchedulerSpec", "PlannerSpec", "ExecutorSpec",
    "FaultsSpec", "TasksSpec", "Scenario", "load_scenario", "scenario_from_dict",
    "apply_overrides", "parse_override", "diffdrive_preset",
]

MAX_COUNT = 1_000_000
"""Largest count of anything (orders per batch, AGVs per group, shelves per block, ...)."""
MAX_TICKS = 10_000_000
"""Largest tick count (``max_ticks``, ``duration_ticks``, every ``*_ticks`` field)."""
MAX_SIDE = 4_096
"""Largest layout side, cells."""
MAX_CELLS = 4_000_000
"""Largest layout, cells (rows x cols)."""
MAX_ORDERS = 1_000_000
"""Largest number of orders an order stream may generate."""
MAX_FLOAT = 1e6
"""Largest value of a float field (metres, seconds, kg, m/s, ...); all must be finite."""


def _not_bool_or_text(value: Any) -> Any:
    """Numbers only: ``true`` or ``"1.5"`` are not numbers (strict ints and floats)."""
    if isinstance(value, bool | str | bytes):
        raise ValueError("Input should be a number")
    return value


Int = Annotated[int, Field(strict=True)]
Cell = tuple[Int, Int]
PosInt = Annotated[int, Field(ge=1, le=MAX_COUNT, strict=True)]
NonNegInt = Annotated[int, Field(ge=0, le=MAX_COUNT, strict=True)]
Ticks = Annotated[int, Field(ge=1, le=MAX_TICKS, strict=True)]
NonNegTicks = Annotated[int, Field(ge=0, le=MAX_TICKS, strict=True)]
Seed = Annotated[int, Field(ge=0, le=2**63 - 1, strict=True)]
Side = Annotated[int, Field(ge=1, le=MAX_SIDE, strict=True)]
PosFloat = Annotated[float, BeforeValidator(_not_bool_or_text),
                     Field(gt=0, le=MAX_FLOAT, allow_inf_nan=False)]
NonNegFloat = Annotated[float, BeforeValidator(_not_bool_or_text),
                        Field(ge=0, le=MAX_FLOAT, allow_inf_nan=False)]
Prob = Annotated[float, BeforeValidator(_not_bool_or_text),
                 Field(ge=0.0, le=1.0, allow_inf_nan=False)]
Bool = Annotated[bool, Field(strict=True)]
Budget = Annotated[int, Field(ge=1, le=10**9, strict=True)]
"""A work budget (search nodes, expansions, iterations)."""
NAME = re.compile(r"[\w][\w .+=,-]{0,127}")
"""A scenario name: it becomes part of file names, so no path separators, no leading dot."""


PLUGIN_PATH = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*[:.][A-Za-z_]\w*")
"""A user class named by import path, ``package.module:ClassName`` (a plugin)."""
ENTRY_POINT_NAME = re.compile(r"[A-Za-z_][\w-]*")
"""The name of an installed entry point (resolved when the scenario is loaded)."""


def _builtin_or_plugin(*builtins: str) -> AfterValidator:
    """A built-in name, or a plugin class as ``package.module:ClassName`` (imported when the
    scenario runs, see :func:`warerover_phys.registry.lookup`)."""
    choices = ", ".join(repr(n) for n in builtins[:-1]) + f" or {builtins[-1]!r}"

    def check(value: str) -> str:
        if value in builtins or PLUGIN_PATH.fullmatch(value) or \
                ENTRY_POINT_NAME.fullmatch(value):
            return value  # entry points and plug-ins are resolved by check_plugins
        raise ValueError(f"Input should be {choices}, an entry point name, or a plugin "
                         "class as 'package.module:ClassName'")

    return AfterValidator(check)


SchedulerName = Annotated[str, _builtin_or_plugin("rd", "ta", "errands")]
PlannerName = Annotated[str, _builtin_or_plugin("astar", "cbs", "pibt", "lacam", "learned")]
ExecutorName = Annotated[str, _builtin_or_plugin("grid", "physics")]
Params = dict[str, Any]
"""A plug-in's own parameters, validated against its ``Params`` model when loaded."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def _named(value: Any) -> Any:
    """Allow ``scheduler: ta`` as a shorthand for ``scheduler: {name: ta}``."""
    return {"name": value} if isinstance(value, str) else value


# --------------------------------------------------------------------------------- fleet


class AgvTypeSpec(_Model):
    """One kind of AGV. Defaults follow RAWSim-O (0.35 m radius, 1.5 m/s, 1 m/s^2)."""

    footprint: PosInt = 1
    """Side of the square cell footprint: 1 = 1x1 cells, 2 = 2x2 cells."""
    body_m: tuple[PosFloat, PosFloat] = (0.7, 0.7)
    """Body length and width in metres; must fit in the footprint."""
    mass_kg: PosFloat = 100.0
    max_speed_mps: PosFloat = 1.5
    max_accel_mps2: PosFloat = 1.0
    max_turn_rate_radps: PosFloat = 2.5
    cargo_class: PosInt | None = None
    """Largest container / shelf size class the AGV may carry (default: its footprint)."""
    drive: Literal["diff", "omni"] = "diff"
    payload_kg: NonNegFloat = 0.0
    """Mass of the shelf it carries (kg). Physics with ``executor.payload: true``: a loaded
    AGV's acceleration limit is its drive force over the loaded mass,
    ``mass_kg x max_accel_mps2 / (mass_kg + payload_kg)``; 0 (default) = no change."""

    wheel_base_m: PosFloat | None = None
    """Differential drive: distance between the two drive wheels (metres), at most the body's
    width. With ``max_wheel_speed_mps`` each wheel's speed ``|v +- omega x wheel_base_m / 2|``
    is a limit of the no-slip drive (physics, ``executor.no_slip``). None: no wheel limit."""
    max_wheel_speed_mps: PosFloat | None = None
    """Differential drive: top speed of each drive wheel (m/s). It must allow the type's top
    speed driving straight and its turn rate in place (at least ``max_speed_mps`` and
    ``max_turn_rate_radps x wheel_base_m / 2``), so it binds only when the AGV turns while it
    drives (steering back onto its path)."""

    @model_validator(mode="after")
    def _wheel_limits(self) -> AgvTypeSpec:
        base, wheel = self.wheel_base_m, self.max_wheel_speed_mps
        if (base is None) != (wheel is None):
            raise ValueError("wheel_base_m and max_wheel_speed_mps go together: give both "
                             "or neither")
        if base is None or wheel is None:
            return self
        if self.drive == "omni":
            raise ValueError("wheel_base_m / max_wheel_speed_mps are differential-drive "
                             "limits (drive: diff)")
        if base > self.body_m[1] + 1e-9:
            raise ValueError(f"wheel_base_m {base:g} is wider than the body "
                             f"(body_m width {self.body_m[1]:g})")
        need = max(self.max_speed_mps, self.max_turn_rate_radps * base / 2)
        if wheel < need - 1e-9:
            raise ValueError(f"max_wheel_speed_mps {wheel:g} is below what driving straight "
                             f"at max_speed_mps and turning in place at max_turn_rate_radps "
                             f"need ({need:.4g}): lower those or raise it")
        return self

    @property
    def loaded_accel_mps2(self) -> float:
        """Acceleration limit while carrying a shelf (m/s^2), when payloads count."""
        return self.mass_kg * self.max_accel_mps2 / (self.mass_kg + self.payload_kg)

    @property
    def carries(self) -> int:
        return self.cargo_class if self.cargo_class is not None else self.footprint

    def can_carry(self, shelf_size: int) -> bool:
        """It lifts a shelf from under it: the shelf must match its footprint and cargo
        class."""
        return shelf_size == self.footprint and shelf_size <= self.carries

    def ticks_per_move(self, cell_m: float, tick_s: float) -> int:
        """Ticks one cell move takes at top speed (at least 1).

        A tiny tolerance keeps 1.0 m at 1.0 m/s with 1.0 s ticks at exactly one tick.
        """
        return max(1, math.ceil(cell_m / (self.max_speed_mps * tick_s) - 1e-9))


class AgvGroupSpec(_Model):
    type: str = "default"
    count: PosInt = 1
    starts: list[Cell] | None = None
    """Explicit start anchors (row, col); default: free parking spots in row-major order."""

    @model_validator(mode="after")
    def _starts_match_count(self) -> AgvGroupSpec:
        if self.starts is not None and len(self.starts) != self.count:
            raise ValueError(f"starts lists {len(self.starts)} cells for count {self.count}")
        return self


class FleetSpec(_Model):
    types: dict[str, AgvTypeSpec] = Field(default_factory=lambda: {"default": AgvTypeSpec()})
    agvs: list[AgvGroupSpec] = Field(min_length=1)

    @model_validator(mode="after")
    def _types_known(self) -> FleetSpec:
        for i, group in enumerate(self.agvs):
            if group.type not in self.types:
                raise ValueError(
                    f"agvs[{i}].type {group.type!r} is not one of {sorted(self.types)}")
        return self

    @property
    def size(self) -> int:
        return sum(g.count for g in self.agvs)


# --------------------------------------------------------------------------------- layout


class RectSpec(_Model):
    """A rectangle of cells: top-left ``origin`` (row, col) and its size in cells."""

    origin: Cell
    rows: PosInt = 1
    cols: PosInt = 1


class ShelfBlockSpec(_Model):
    """A block of ``rows`` x ``cols`` shelves, each ``size`` x ``size`` cells, packed tight."""

    origin: Cell
    rows: PosInt = 1
    cols: PosInt = 1
    size: PosInt = 1


class InventorySpec(_Model):
    """Which SKUs each shelf holds. Drawn once from ``seed`` (fixed with the layout)."""

    num_skus: PosInt | None = None
    """Number of distinct SKUs (default: 2 x number of shelves)."""
    skus_per_shelf: Annotated[PosInt, Field(le=10_000)] = 4
    seed: Seed = 0


class GeneratorSpec(_Model):
    """Parametric warehouse: a grid of shelf blocks with aisles, stations on one side."""

    block_rows: PosInt = 4
    block_cols: PosInt = 4
    block_shape: tuple[PosInt, PosInt] = (2, 4)
    """Shelves per block (rows, cols)."""
    shelf_size: PosInt = 1
    aisle_width: PosInt = 1
    cross_aisle_width: PosInt = 1
    border: PosInt = 2
    """Free cells between the outer wall of blocks and the station / parking sides."""
    stations: PosInt = 8
    station_side: Literal["left", "right", "top", "bottom"] = "left"
    parking: NonNegInt = 0
    """Parking cells (0: one per AGV in the fleet, filled in at load)."""
    parking_side: Literal["left", "right", "top", "bottom"] = "bottom"
    walls: Bool = True


class LayoutSpec(_Model):
    """Where the cells come from: exactly one of ``grid``, ``map`` or ``generator``.

    ``grid`` is ASCII rows (``.`` floor, ``#`` obstacle, ``S`` shelf, ``R`` receiving
    station, ``P`` parking, ``A`` maintenance access point); ``size`` with the lists below
    builds a structured layout on an empty floor; ``map`` reads a MovingAI ``.map`` file
    (``@ O T W`` are obstacles). Shelf blocks, stations, parking, obstacles and access points
    listed here are placed on top of whichever base was chosen.
    """

    cell_m: PosFloat = 1.0
    size: tuple[Side, Side] | None = None
    """(rows, cols) of an empty floor for a structured layout."""
    grid: list[str] | None = None
    map: str | None = None
    generator: GeneratorSpec | None = None
    shelf_blocks: list[ShelfBlockSpec] = Field(default_factory=list)
    stations: list[Cell] = Field(default_factory=list)
    parking: list[RectSpec] = Field(default_factory=list)
    obstacles: list[RectSpec] = Field(default_factory=list)
    access_points: list[Cell] = Field(default_factory=list)
    inventory: InventorySpec = InventorySpec()

    @field_validator("grid", mode="before")
    @classmethod
    def _split_grid(cls, value: Any) -> Any:
        if isinstance(value, str):
            return [line for line in value.strip("\n").splitlines()]
        return value

    @field_validator("grid")
    @classmethod
    def _grid_size(cls, value: list[str] | None) -> list[str] | None:
        if value is not None and (len(value) > MAX_SIDE or
                                  any(len(row) > MAX_SIDE for row in value)):
            raise ValueError(f"grid is larger than {MAX_SIDE} x {MAX_SIDE} cells")
        return value

    @model_validator(mode="after")
    def _one_base(self) -> LayoutSpec:
        bases = [n for n in ("size", "grid", "map", "generator") if getattr(self, n) is not None]
        if len(bases) != 1:
            raise ValueError(
                "give exactly one of size, grid, map, generator"
                + (f" (found {', '.join(bases)})" if bases else ""))
        return self


# --------------------------------------------------------------------------------- orders


class OneshotSpec(_Model):
    count: PosInt = 20


class ConstantSpec(_Model):
    batch: PosInt = 10
    every_ticks: Ticks = 50


class WaveSpec(_Model):
    base: PosInt = 10
    min_mult: Annotated[NonNegFloat, Field(le=100)] = 0.3
    max_mult: Annotated[NonNegFloat, Field(le=100)] = 3.0
    cycle_ticks: Ticks = 80
    every_ticks: Ticks = 20
    shape: Literal["sine", "square"] = "sine"

    @model_validator(mode="after")
    def _order(self) -> WaveSpec:
        if self.min_mult > self.max_mult:
            raise ValueError(f"min_mult {self.min_mult} > max_mult {self.max_mult}")
        return self


class HotspotSpec(_Model):
    alpha: Annotated[PosFloat, Field(ge=0.5)] = 2.0
    """Pareto shape (>= 0.5; batches are cut at 1,000 x ``scale``)."""
    scale: Annotated[PosFloat, Field(le=10_000)] = 10.0
    every_ticks: Ticks = 30
    hot_fraction: Annotated[PosFloat, Field(lt=1)] = 0.2
    hot_share: Annotated[PosFloat, Field(lt=1)] = 0.8


class BurstSpec(_Model):
    base: PosInt = 10
    every_ticks: Ticks = 60
    start_prob: Prob = 0.05
    burst_orders: PosInt = 50
    burst_every_ticks: Ticks = 5
    burst_ticks: Ticks = 20
    """How long a burst lasts once it starts."""


class ErrandsSpec(_Model):
    """Errand tasks (``orders.pattern: errands``): each task is a list of cells that one
    AGV visits in order, as in the League of Robot Runners (a task is done with its last
    errand; an errand is done when the AGV stands at rest on its cell, any heading) or a
    MovingAI map with a task stream. Tasks come from ``file``, from ``tasks`` or, with
    neither, are drawn uniformly over the free cells with the orders generator
    (``errands_per_task`` errands each). Task ``k`` is the ``k mod count``-th of the list
    (the list wraps around, as the league's does).

    ``assign`` is the release and assignment rule (scheduler ``errands`` applies it):

    - ``roundrobin``: AGV ``i`` does tasks ``i``, ``i + n``, ``i + 2n``, ... (``n`` AGVs),
      each released when the AGV is free (Robot Runners 2023, ``roundrobin`` and
      ``roundrobin-fixed``);
    - ``greedy``: a free AGV takes the next task of the list (2023, ``greedy``);
    - ``pool``: ``max(1, int(reveal x n))`` tasks are open at the start and one more is
      released for every task finished; free AGVs, in id order, each take the open task
      whose first errand is nearest (Manhattan) (2024 and later: the start kit's default
      scheduler). A plug-in scheduler may assign the open tasks instead.
    """

    file: str | None = None
    """A Robot Runners task file (an optional ``# version`` line, the count, then one task
    per line: its errands' linearised cells ``row * cols + col``, comma-separated), relative
    to the scenario file."""
    tasks: list[Annotated[list[Cell], Field(min_length=1)]] | None = None
    """Tasks given inline: each a list of ``[row, col]`` errand cells."""
    errands_per_task: tuple[PosInt, PosInt] = (1, 1)
    """Random tasks: the fewest and most errands of a task (drawn uniformly)."""
    assign: Literal["roundrobin", "greedy", "pool"] = "pool"
    reveal: PosFloat = 1.0
    """``pool``: open tasks per AGV (``numTasksReveal`` of a 2024+ problem)."""
    idle: Literal["stay", "home"] = "stay"
    """Where an AGV without a task goes: it stays where it is (Robot Runners), or drives
    to its start cell."""

    @model_validator(mode="after")
    def _one_source(self) -> ErrandsSpec:
        if self.file is not None and self.tasks is not None:
            raise ValueError("give the tasks either in a file or inline, not both")
        if self.errands_per_task[1] < self.errands_per_task[0]:
            raise ValueError(f"errands_per_task: the most ({self.errands_per_task[1]}) is "
                             f"below the fewest ({self.errands_per_task[0]})")
        return self


class OrdersSpec(_Model):
    """The order stream. Parameters of every pattern have defaults (WareRover's)."""

    pattern: Literal["oneshot", "constant", "wave", "hotspot", "burst", "errands"] = "oneshot"
    duration_ticks: Ticks = 400
    """Streaming patterns generate orders in ticks [0, duration_ticks)."""
    large_fraction: Prob | None = None
    """Share of orders needing a size-2 container (default: share of size-2 SKUs)."""
    oneshot: OneshotSpec = OneshotSpec()
    constant: ConstantSpec = ConstantSpec()
    wave: WaveSpec = WaveSpec()
    hotspot: HotspotSpec = HotspotSpec()
    burst: BurstSpec = BurstSpec()
    errands: ErrandsSpec = ErrandsSpec()
    stations_by_size: dict[PosInt, Annotated[list[NonNegInt], Field(min_length=1)]] | None = None
    """Size class -> indices (into the layout's stations) of the stations its orders go to,
    drawn uniformly; a class not listed uses every station. WareRover's heterogeneous floor
    has sized stations: ``{1: [0, 2, 4, 5, 6, 7], 2: [1, 3]}``. Default: every station."""
    requeue_after_ticks: Ticks | None = None
    """WareRover's ``order_processing_timeout`` (30 there): an order not handed over this many
    ticks after it was assigned goes back to pending, while the trip that has it carries on
    and may still hand it over. A re-queued order may be sent out again to its shelf even
    while that shelf is out on the first trip: that second trip is *blind* (the AGV drives
    the whole trip empty-handed and hands over nothing), as in WareRover. Default: never."""


# --------------------------------------------------------------------------------- modules


class TasksSpec(_Model):
    pick_ticks: NonNegTicks = 2
    handover_ticks: NonNegTicks = 2
    place_ticks: NonNegTicks = 2
    stops: Literal["nearest", "order_ids"] = "nearest"
    """Order of a trip's station stops: ``nearest`` visits each station once, nearest first
    (loaded distances); ``order_ids`` makes one stop per order in order-id order (the same
    station twice in a row is one stop), as WareRover does."""


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


class DelaySpec(_Model):
    """Random execution delays (the Robot Runners 2026 ``delayConfig`` model): each tick,
    each AGV draws a delay event (``bernoulli``: with probability ``prob``; ``poisson``:
    a Poisson(``prob``) count, any count > 0 starts one); a delay stops the AGV for a
    duration in ticks drawn ``uniform`` from [``min_ticks``, ``max_ticks``] or ``gaussian``
    (``mean_ticks``, ``std_ticks``, rounded, clipped to [``min_ticks``, ``max_ticks``])."""

    model: Literal["none", "bernoulli", "poisson"] = "none"
    prob: Prob = 0.0
    duration: Literal["uniform", "gaussian"] = "uniform"
    min_ticks: Ticks = 1
    max_ticks: Ticks = 10
    mean_ticks: PosFloat = 5.0
    std_ticks: NonNegFloat = 2.0

    @model_validator(mode="after")
    def _range(self) -> DelaySpec:
        if self.max_ticks < self.min_ticks:
            raise ValueError(f"max_ticks {self.max_ticks} is below min_ticks {self.min_ticks}")
        return self


class ExecutorSpec(_Model):
    """How plans are carried out: ``grid`` (ideal discrete moves) or ``physics`` (pymunk
    rigid bodies with kinematic limits, following an action dependency graph)."""

    name: ExecutorName = "grid"
    """``grid``, ``physics``, an entry point, or a plugin class ``package.module:ClassName``."""
    params: Params = {}
    """Parameters of a plug-in executor (its ``Params`` model)."""
    dt_s: PosFloat = 0.02
    """Physics step (seconds); the planning tick is ``tick_s``."""
    adg: Bool = True
    """Follow the action dependency graph; ``false`` = naive time-indexed following (an
    action starts at its planned tick whatever the other AGVs do)."""
    delays: DelaySpec = DelaySpec()
    speed_scale: tuple[PosFloat, PosFloat] = (1.0, 1.0)
    """Each AGV's top speed is scaled by a factor drawn uniformly from this range."""
    deviation_m: PosFloat = 0.35
    """An AGV farther than this from its path is stopped and replanned."""
    trajectory_hz: PosFloat = 10.0
    """Rate at which executed poses are recorded (``trajectories.npz``), in Hz: every
    ``round(1 / (trajectory_hz x dt))`` th physics step; at most the physics rate
    ``1 / dt_s`` (that value records every step)."""
    freeze_s: NonNegFloat = 30.0
    """Physics: a freeze is found when AGVs make no progress towards their goals for this
    many simulated seconds while nothing they wait on can still move (``freeze.py``); it
    is counted in ``deadlocks`` / ``freezes``, logged (``freeze`` event) and the AGVs are
    replanned from where they stand. 0 turns the detector off."""
    payload: Bool = False
    """Physics: a loaded AGV's acceleration limit drops to
    ``mass_kg x max_accel_mps2 / (mass_kg + payload_kg)`` of its type (and its body's mass
    grows by ``payload_kg``) while it carries a shelf; the command limiter, the braking
    profile and the measured-limit checks use the limit in force."""
    no_slip: Bool = False
    """Physics: differential-drive AGVs cannot move sideways: the unicycle law of
    :mod:`~warerover_phys.executors.diffdrive` commands velocity only along the body's
    heading, turns in place where the path turns, corrects lateral error by steering and
    keeps speed, acceleration, turn rate and wheel speeds (``wheel_base_m``,
    ``max_wheel_speed_mps``) within their limits at every step (``robot: diffdrive`` sets
    it). Off: the default controller also pulls sideways (``peak_lateral_speed_mps`` shows
    how much)."""
    comm_latency_s: NonNegFloat = 0.0
    """Physics with ``adg: true``: seconds before an AGV hears that another AGV's action it
    depends on is done (the dependency graph's messages arrive late): an action whose
    dependency finished at time t starts at t + latency at the earliest."""
    shelf_contacts: Bool = False
    """Physics: a loaded AGV's collision shape includes its carried shelf (a square
    ``0.9 x shelf size x cell_m`` with sides along the grid, as in ``min_clearance_m``);
    contacts of a carried shelf with another AGV or its shelf count as AGV contacts, with a
    wall as static contacts."""
    shelf_sweeps: Bool = False
    """Physics: a turn in place whose disc reaches the shelf a *neighbour* may carry (but
    not its body: an 0.8 m body next to a 0.9 m shelf on 1 m cells, 1.6 cm deep) waits in
    the dependency graph until that neighbour carries no shelf
    (:attr:`~warerover_phys.planning.sweep.Sweep.shelf_cells`). The planners do not reserve
    these cells yet, so AGVs often block each other: on the padded paper floors with 0.8 m
    bodies the shelf overlaps fell from 177-548 samples per episode to 0-10, but success
    fell from 1.0 to 0.15-0.35 (``tools/README.md``). ``false`` (default): such a turn
    goes ahead, the overlap is reported in ``min_clearance_m``. No effect on bodies whose
    disc stays clear of neighbours' shelves (the default 0.7 m)."""
    turn_in_place: Bool = False
    """Physics: a differential-drive AGV whose committed plan only stands on its cell and
    changes its heading (``TimedPath.headings``) turns in place to the plan's last heading
    at once, at its turn rate (if its turn sweeps no cell beyond its own). ``false``
    (default): plan headings are not followed; the AGV turns when its next move comes. The
    environments (``warerover_phys.envs``) turn it on for their turn actions."""
    park: Bool = True
    """Physics: an AGV that stands still on its hold point (within 1 mm, at rest, facing its
    heading) has its drive joints taken out of the pymunk world until it moves again, so
    the solver does not iterate over them (most of pymunk's step at 1,000 AGVs). Nothing
    can move a parked body: AGV-AGV contacts are not solved. ``false``: every joint always
    in the world (for comparison; figures agree to within the 1 mm)."""

    reorder: Literal["none", "greedy", "milp"] = "none"
    """Physics with ``adg: true``: reorder the dependency graph while executing (switchable
    action dependency graph, Berndt et al. 2020; ``executors/reorder.py``). ``none``: the
    plan's passing order at every shared cell (the plain graph). ``greedy``: an AGV that
    waits at a cell reserved for another AGV that has not reached it yet passes first
    when the motion model says it clears the cells they share sooner than the other's
    delay lasts. ``milp``: the order at the switchable cells of a receding window chosen
    by a mixed-integer program (scipy ``milp``, HiGHS), greedy where it finds no optimum
    within its node limit. Every switch keeps the graph acyclic (checked)."""
    reorder_every_s: PosFloat = 0.5
    """Simulated seconds between reorder decisions (rounded up to the follower's
    decisions, every 0.1 s)."""
    reorder_margin_s: NonNegFloat = 0.5
    """A switch must win at least this many estimated seconds."""
    reorder_horizon: PosInt = 8
    """``milp``: actions per AGV in the program's window (at least those of the cells
    it may switch)."""
    reorder_node_limit: PosInt = 500
    """``milp``: branch-and-bound nodes per program; without a proved optimum within them
    the decision falls back to greedy. A node limit, not a clock: the same seed gives
    the same result on any machine."""
    reorder_time_limit_s: PosFloat | None = None
    """``milp``: wall-clock seconds per program as well (None: none). Set, results may
    depend on the machine's speed."""
    reorder_milp_band_s: NonNegFloat | None = 2.0
    """``milp``: a lone candidate (no other shares an AGV with it) whose estimated gain is
    further than this from the margin is decided by the greedy rule, without a program
    (None: every candidate goes to the program)."""

    @model_validator(mode="after")
    def _physics_fields(self) -> ExecutorSpec:
        lo, hi = self.speed_scale
        if lo > hi:
            raise ValueError(f"speed_scale [{lo}, {hi}] must be [low, high]")
        return self


class RandomFaultsSpec(_Model):
    prob_per_tick: Prob = 0.0
    repair_ticks: Ticks = 40
    repair_ticks_max: Ticks | None = None
    """If set, repair time is drawn uniformly from [repair_ticks, repair_ticks_max]."""
    max_down: PosInt | None = None


class ScheduledFaultSpec(_Model):
    agv: NonNegInt
    tick: NonNegTicks
    repair_ticks: Ticks = 40


class FaultsSpec(_Model):
    """Failures, their repairs and the safety corridors around failed AGVs (see
    ``faults/model.py``)."""

    random: RandomFaultsSpec = RandomFaultsSpec()
    scheduled: list[ScheduledFaultSpec] = Field(default_factory=list)
    corridor_width_m: PosFloat = 1.0
    corridor_margin_m: NonNegFloat = 0.2
    orders_of_failed: Literal["reassign", "wait"] = "reassign"
    exit_time_s: PosFloat | None = None
    """Seconds an AGV caught inside a corridor when it opens may take to leave it before
    its time inside counts as intrusion. None: derived per AGV when the corridor opens
    (cells to drive out at the plan's move time plus one move, a half turn, speeding up and
    braking, plus ``exit_margin_s``; see ``faults/intrusion_log.py``)."""
    exit_margin_s: NonNegFloat = 2.0
    """Seconds added to the derived exit time (replanning waits for a tick boundary)."""
    checker: Literal["fcl", "numpy"] = "numpy"
    """How the physics executor finds the AGV bodies in the corridors' margins each step:
    ``numpy`` (bounding boxes against every rectangle) or ``fcl`` (python-fcl's AABB trees
    and boolean box-box collide); the closed form of ``faults/intrusion.py`` measures
    the pairs either finds, so both give the same intrusions and depths. ``numpy`` is the
    default: faster in ``tools/bench_intrusion.py`` (1,000 AGVs x 50 corridors)."""

    @property
    def enabled(self) -> bool:
        return self.random.prob_per_tick > 0 or bool(self.scheduled)


# --------------------------------------------------------------------------------- scenario

MAX_TICKS_PER_MOVE = 1_000
"""Longest one cell move may take, ticks (``cell_m / (max_speed_mps * tick_s)``)."""
MAX_STEPS_PER_TICK = 10_000
"""Most physics steps per tick (``tick_s / executor.dt_s``)."""


def _orders_bound(orders: OrdersSpec, max_ticks: int) -> int:
    """An upper bound of the orders a stream generates in ``max_ticks`` ticks (hotspot:
    batches taken as 1,000 x ``scale``, where ``orders.py`` cuts its Pareto draws)."""
    ticks = min(orders.duration_ticks, max_ticks)

    def batches(every: int) -> int:
        return -(-ticks // every)

    p = orders.pattern
    if p == "errands":  # released one per free AGV or per finished task: see World
        return 0
    if p == "oneshot":
        return orders.oneshot.count
    if p == "constant":
        return batches(orders.constant.every_ticks) * orders.constant.batch
    if p == "wave":
        w = orders.wave
        return batches(w.every_ticks) * math.ceil(w.base * w.max_mult)
    if p == "hotspot":
        return batches(orders.hotspot.every_ticks) * math.ceil(1000 * orders.hotspot.scale)
    b = orders.burst
    return batches(b.every_ticks) * b.base + batches(b.burst_every_ticks) * b.burst_orders



WHEEL_BASE_SHARE = 0.85
"""``robot: diffdrive``: the wheel base it gives an AGV type, as a share of the body's width."""


def diffdrive_preset(data: dict[str, Any]) -> dict[str, Any]:
    """The raw scenario ``data`` with ``robot: diffdrive`` spelt out: ``executor.no_slip:
    true`` and, for each differential-drive AGV type without wheel limits, ``wheel_base_m``
    (:data:`WHEEL_BASE_SHARE` of its width) and ``max_wheel_speed_mps`` (the least that its
    top speed and turn rate need). Values it cannot read are left for validation."""
    out = dict(data)
    executor = _as_dict(out.get("executor"))
    if executor.get("no_slip") is False:
        raise ScenarioError("robot: diffdrive drives without side slip; executor.no_slip: "
                            "false contradicts it (drop one of them)",
                            file=out.get("source"), field="executor.no_slip", value=False)
    out["executor"] = {**executor, "no_slip": True}
    fleet = out.get("fleet")
    if not isinstance(fleet, dict):
        return out
    types = fleet.get("types", {"default": {}})
    if not isinstance(types, dict):
        return out
    fields = AgvTypeSpec.model_fields
    filled = {}
    for name, spec in types.items():
        if isinstance(spec, dict) and spec.get("drive", "diff") == "diff" and \
                "wheel_base_m" not in spec and "max_wheel_speed_mps" not in spec:
            body = spec.get("body_m", fields["body_m"].default)
            speed = spec.get("max_speed_mps", fields["max_speed_mps"].default)
            turn = spec.get("max_turn_rate_radps", fields["max_turn_rate_radps"].default)
            try:
                base = round(WHEEL_BASE_SHARE * float(body[1]), 6)
                wheel = max(float(speed), float(turn) * base / 2)
            except (TypeError, ValueError, IndexError, KeyError):
                filled[name] = spec
                continue
            spec = {**spec, "wheel_base_m": base, "max_wheel_speed_mps": wheel}
        filled[name] = spec
    out["fleet"] = {**fleet, "types": filled}
    return out


class Scenario(_Model):
    """A whole episode: layout, fleet, orders, algorithms, seed and time."""

    name: str = "scenario"
    robot: Literal["default", "diffdrive"] = "default"
    """A robot-model preset. ``diffdrive``: differential drive without side slip, as real
    warehouse AGVs drive (physics: :mod:`~warerover_phys.executors.diffdrive`):
    ``executor.no_slip: true`` and wheel limits for the ``drive: diff`` types that give none
    (:func:`diffdrive_preset`). It does not pick the executor: run it on ``physics``."""
    seed: Seed = 0
    max_ticks: Ticks = 2000
    tick_s: PosFloat = 1.0
    layout: LayoutSpec
    fleet: FleetSpec
    orders: OrdersSpec = OrdersSpec()
    tasks: TasksSpec = TasksSpec()
    scheduler: SchedulerSpec = SchedulerSpec()
    planner: PlannerSpec = PlannerSpec()
    executor: ExecutorSpec = ExecutorSpec()
    faults: FaultsSpec = FaultsSpec()
    source: str | None = Field(default=None, exclude=True)
    """The file the scenario was read from (for error messages and relative paths)."""

    @field_validator("scheduler", "planner", "executor", mode="before")
    @classmethod
    def _shorthand(cls, value: Any) -> Any:
        return _named(value)

    @model_validator(mode="before")
    @classmethod
    def _robot_preset(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("robot") == "diffdrive":
            return diffdrive_preset(data)
        return data

    @model_validator(mode="after")
    def _faults_name_real_agvs(self) -> Scenario:
        for i, fault in enumerate(self.faults.scheduled):
            if fault.agv >= self.fleet.size:
                raise ScenarioError(f"AGV {fault.agv} does not exist (the fleet has "
                                    f"{self.fleet.size}: ids 0..{self.fleet.size - 1})",
                                    file=self.source, field=f"faults.scheduled[{i}].agv",
                                    value=fault.agv)
        return self

    @model_validator(mode="after")
    def _work_fits_the_boxes(self) -> Scenario:
        """Errand tasks need a scheduler that assigns them (``errands`` or a plug-in), shelf
        orders one that fetches shelves; the compiled rotation rules need 1x1 AGVs that
        move a cell and turn a quarter within one tick."""
        errands = self.orders.pattern == "errands"
        name = self.scheduler.name
        if errands and name in ("ta", "rd"):
            raise ScenarioError(f"scheduler {name!r} fetches shelves for orders; errand tasks "
                                "(orders.pattern: errands) need scheduler 'errands' (or a "
                                "plug-in)", file=self.source, field="scheduler.name",
                                value=name)
        if not errands and name == "errands":
            raise ScenarioError("scheduler 'errands' assigns errand tasks: set "
                                "orders.pattern: errands, or use 'ta' or 'rd'",
                                file=self.source, field="scheduler.name", value=name)
        rule = self.planner.rotation_rule
        if rule != "cascade":
            for tname, spec in self.fleet.types.items():
                quarter = math.pi / 2 / spec.max_turn_rate_radps
                if spec.footprint != 1 or spec.ticks_per_move(self.layout.cell_m,
                                                              self.tick_s) != 1 \
                        or quarter > self.tick_s + 1e-9:
                    raise ScenarioError(
                        f"planner.rotation_rule {rule!r} plans 1x1 AGVs that move one cell "
                        f"and turn a quarter in one tick; type {tname!r} (footprint "
                        f"{spec.footprint}, {spec.max_speed_mps} m/s, "
                        f"{spec.max_turn_rate_radps} rad/s, tick_s {self.tick_s}) does not: "
                        "use rotation_rule 'cascade'", file=self.source,
                        field="planner.rotation_rule", value=rule)
        return self

    @field_validator("name")
    @classmethod
    def _safe_name(cls, value: str) -> str:
        if not NAME.fullmatch(value) or value.strip() != value:
            raise ValueError("name must be 1-128 letters, digits, spaces or _ . + = , - "
                             "(it becomes part of file names: no path separators, no leading "
                             "dot)")
        return value

    @model_validator(mode="after")
    def _within_limits(self) -> Scenario:
        """Cross-field limits: the physics step fits in a tick, one move takes at most
        ``MAX_TICKS_PER_MOVE`` ticks, the order stream stays under ``MAX_ORDERS``."""
        def fail(msg: str, field: str, value: Any) -> ScenarioError:
            return ScenarioError(msg, file=self.source, field=field, value=value)

        if self.executor.dt_s > self.tick_s:
            raise fail(f"the physics step must not be longer than a tick (tick_s = "
                       f"{self.tick_s:g} s)", "executor.dt_s", self.executor.dt_s)
        if self.tick_s / self.executor.dt_s > MAX_STEPS_PER_TICK:
            raise fail(f"more than {MAX_STEPS_PER_TICK:,} physics steps per tick (tick_s = "
                       f"{self.tick_s:g} s)", "executor.dt_s", self.executor.dt_s)
        if self.executor.name == "physics":
            dt = self.tick_s / max(1, round(self.tick_s / self.executor.dt_s))
            if self.executor.trajectory_hz * dt > 1.0 + 1e-9:
                raise fail(f"poses can be recorded at most once per physics step "
                           f"(1 / dt = {1 / dt:g} Hz)", "executor.trajectory_hz",
                           self.executor.trajectory_hz)
        for name, spec in self.fleet.types.items():
            moves = self.layout.cell_m / (spec.max_speed_mps * self.tick_s)
            if moves > MAX_TICKS_PER_MOVE:
                raise fail(f"one cell move would take {moves:.3g} ticks (at most "
                           f"{MAX_TICKS_PER_MOVE}: raise the speed or tick_s)",
                           f"fleet.types.{name}.max_speed_mps", spec.max_speed_mps)
        if self.planner.rotations:
            for name, spec in self.fleet.types.items():
                r = math.hypot(*spec.body_m) / 2
                if spec.drive == "diff" and r > spec.footprint * self.layout.cell_m / 2 + 1e-9:
                    raise fail(f"planner.rotations: a {spec.body_m[0]} x {spec.body_m[1]} m "
                               f"body turning in place sweeps a disc of radius {r:.3f} m, "
                               f"beyond its {spec.footprint}x{spec.footprint} footprint on "
                               f"{self.layout.cell_m} m cells; rotation-aware planning "
                               "cannot reserve such turns (use a body whose half-diagonal "
                               f"is at most {spec.footprint * self.layout.cell_m / 2} m, "
                               "drive: omni, or planner.rotations: false)",
                               f"fleet.types.{name}.body_m", list(spec.body_m))
        orders = _orders_bound(self.orders, self.max_ticks)
        if orders > MAX_ORDERS:
            raise fail(f"the order stream could generate {orders:,} orders (at most "
                       f"{MAX_ORDERS:,})", f"orders.{self.orders.pattern}",
                       self.orders.pattern)
        if self.layout.size is not None and self.layout.size[0] * self.layout.size[1] > \
                MAX_CELLS:
            raise fail(f"layout has more than {MAX_CELLS:,} cells", "layout.size",
                       list(self.layout.size))
        return self

    @property
    def base_dir(self) -> Path:
        return Path(self.source).parent if self.source else Path.cwd()

    def with_seed(self, seed: int) -> Scenario:
        return self.model_copy(update={"seed": seed})

    def with_executor(self, name: str) -> Scenario:
        """The same scenario on another executor (its physics settings kept)."""
        return self.model_copy(update={"executor": self.executor.model_copy(
            update={"name": name})})


# --------------------------------------------------------------------------------- loading


def _field_path(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def _from_validation_error(err: ValidationError, file: str | None) -> ScenarioError:
    first = err.errors()[0]
    loc = tuple(p for p in first["loc"] if not (isinstance(p, str) and "[" in p))
    msg = first["msg"]
    if first["type"] == "extra_forbidden":
        msg = "unknown key"
    elif first["type"] == "missing":
        msg = "required field is missing"
    for prefix in ("Value error, ", "Assertion failed, "):
        msg = msg.removeprefix(prefix)
    more = len(err.errors()) - 1
    if more:
        msg += f" (and {more} more problem{'s' if more > 1 else ''})"
    value = first.get("input", ScenarioError._MISSING)
    if first["type"] == "missing" or isinstance(value, dict):
        value = ScenarioError._MISSING
    return ScenarioError(msg, file=file, field=_field_path(loc) or None, value=value)


def parse_override(text: str, option: str = "--set") -> tuple[str, Any]:
    """``"orders.pattern=burst"`` -> ``("orders.pattern", "burst")``; values are YAML.
    Errors name ``option`` (the command line option the text came from)."""
    if "=" not in text:
        raise ScenarioError("expected field.path=value", field=option, value=text)
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key:
        raise ScenarioError("empty field path (expected field.path=value)", field=option,
                            value=text)
    try:
        value = safe_yaml.load(raw) if raw.strip() else ""
    except safe_yaml.YamlLimitError as err:
        raise ScenarioError(f"value YAML is {err.problem}", field=key, value=raw) from None
    except yaml.YAMLError:
        value = raw
    return key, value


def apply_overrides(data: dict[str, Any], overrides: list[tuple[str, Any]]) -> dict[str, Any]:
    """Return a copy of ``data`` with each dotted ``field.path`` set to its value.

    List items are addressed by index: ``fleet.agvs.0.count=5``.
    """
    data = copy.deepcopy(data)
    for key, value in overrides:
        node: Any = data
        parts = key.split(".")
        for depth, part in enumerate(parts):
            last = depth == len(parts) - 1
            if isinstance(node, list):
                if not part.isdigit() or int(part) >= len(node):
                    raise ScenarioError("no such list item", field=key, value=part)
                idx: Any = int(part)
            elif isinstance(node, dict):
                idx = part
            else:
                raise ScenarioError("cannot set a field inside a plain value",
                                    field=key, value=node)
            if last:
                if isinstance(node, dict) and part in ("scheduler", "planner", "executor") \
                        and isinstance(value, str) and depth == 0:
                    value = {**_as_dict(node.get(part)), "name": value}
                node[idx] = value
            else:
                if isinstance(node, dict) and (idx not in node or node[idx] is None):
                    node[idx] = {}
                elif isinstance(node, dict) and isinstance(node[idx], str) and \
                        idx in ("scheduler", "planner", "executor"):
                    node[idx] = {"name": node[idx]}
                node = node[idx]
    return data


def _as_dict(value: Any) -> dict[str, Any]:
    if isinstance(value, dict):
        return dict(value)
    if isinstance(value, str):
        return {"name": value}
    return {}


def read_yaml(path: Path, what: str = "scenario") -> dict[str, Any]:
    """Read a YAML mapping, turning every failure into a one-line :class:`ScenarioError`."""
    from .inputs import read_bytes

    raw = read_bytes(path, what, safe_yaml.MAX_BYTES)  # a regular file, size-limited
    try:
        data = safe_yaml.load(raw.decode("utf-8"))
    except safe_yaml.YamlLimitError as err:
        raise ScenarioError(f"YAML refused: {err.problem}", file=str(path)) from None
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise ScenarioError(f"invalid YAML: {where}{problem}", file=str(path)) from None
    except UnicodeDecodeError:
        raise ScenarioError("file is not UTF-8 text", file=str(path)) from None
    if data is None:
        raise ScenarioError(f"{what} file is empty", file=str(path))
    if not isinstance(data, dict):
        raise ScenarioError(f"{what} must be a YAML mapping at top level", file=str(path),
                            value=type(data).__name__)
    return data


def scenario_from_dict(data: dict[str, Any], *, source: str | None = None,
                       overrides: list[tuple[str, Any]] | None = None) -> Scenario:
    """Validate a scenario given as a dict. ``layout`` may be a path to a layout YAML."""
    overrides = list(overrides or [])
    layout_overrides: list[tuple[str, Any]] = []
    if isinstance(data.get("layout"), str):
        layout_overrides = [(k.removeprefix("layout."), v) for k, v in overrides
                            if k.startswith("layout.")]
        overrides = [(k, v) for k, v in overrides if not k.startswith("layout.")]
    data = apply_overrides(data, overrides)
    base = Path(source).parent if source else Path.cwd()
    if isinstance(data.get("layout"), str):
        layout_path = (base / data["layout"]).resolve()
        if not layout_path.exists():
            raise ScenarioError("layout file not found", file=source, field="layout",
                                value=data["layout"])
        layout_data = read_yaml(layout_path, "layout")
        layout_data = {k: v for k, v in layout_data.items() if k != "name"}
        if isinstance(layout_data.get("map"), str):
            layout_data["map"] = str((layout_path.parent / layout_data["map"]).resolve())
        data["layout"] = apply_overrides(layout_data, layout_overrides)
    elif isinstance(data.get("layout"), dict) and isinstance(data["layout"].get("map"), str):
        data["layout"] = {**data["layout"], "map": str((base / data["layout"]["map"]).resolve())}
    try:
        scenario = Scenario.model_validate({**data, "source": source})
    except ValidationError as err:
        raise _from_validation_error(err, source) from None
    return scenario


def load_scenario(path: str | Path, overrides: list[tuple[str, Any]] | None = None) -> Scenario:
    """Read, override and validate a scenario file (or a shipped scenario by bare name,
    ``"paper_homogeneous"``: :mod:`warerover_phys.shipped`).

    Raises :class:`ScenarioError` naming the file, the field path and the bad value.
    """
    from .shipped import resolve_scenario

    path = resolve_scenario(path)
    data = read_yaml(path)
    try:
        return scenario_from_dict(data, source=str(path), overrides=overrides)
    except ScenarioError as err:
        raise err.with_file(str(path)) from None
