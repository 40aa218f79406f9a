"""Scenario schema: the whole episode (:class:`Scenario`) and its cross-field checks."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Literal

from pydantic import (
    Field,
    field_validator,
    model_validator,
)

from ..errors import ScenarioError
from .algorithms import PlannerSpec, SchedulerSpec
from .executor import ExecutorSpec, FaultsSpec
from .fleet import AgvTypeSpec, FleetSpec
from .layout import LayoutSpec
from .orders import OrdersSpec, TasksSpec
from .types import MAX_CELLS, MAX_ORDERS, NAME, PosFloat, Seed, Ticks, _as_dict, _Model, _named

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
