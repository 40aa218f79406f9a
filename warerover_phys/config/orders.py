"""Scenario schema: order streams and errand tasks."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import (
    Field,
    model_validator,
)

from .types import Cell, NonNegFloat, NonNegInt, NonNegTicks, PosFloat, PosInt, Prob, Ticks, _Model


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


class TasksSpec(_Model):
    pick_ticks: NonNegTicks = 2
    handover_ticks: NonNegTicks = 2
    place_ticks: NonNegTicks = 2
    stops: Literal["nearest", "order_ids"] = "nearest"
    """Order of a trip's station stops: ``nearest`` visits each station once, nearest first
    (loaded distances); ``order_ids`` makes one stop per order in order-id order (the same
    station twice in a row is one stop), as WareRover does."""
