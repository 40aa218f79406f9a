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

from .algorithms import (  # noqa: F401
    PlannerSpec,
    SchedulerSpec,
    parse_invoke,
    parse_latency,
)
from .executor import (  # noqa: F401
    DelaySpec,
    ExecutorSpec,
    FaultsSpec,
    RandomFaultsSpec,
    ScheduledFaultSpec,
)
from .fleet import (  # noqa: F401
    AgvGroupSpec,
    AgvTypeSpec,
    FleetSpec,
)
from .layout import (  # noqa: F401
    GeneratorSpec,
    InventorySpec,
    LayoutSpec,
    RectSpec,
    ShelfBlockSpec,
)
from .loading import (  # noqa: F401
    _field_path,
    _from_validation_error,
    apply_overrides,
    load_scenario,
    parse_override,
    read_yaml,
    scenario_from_dict,
)
from .orders import (  # noqa: F401
    BurstSpec,
    ConstantSpec,
    ErrandsSpec,
    HotspotSpec,
    OneshotSpec,
    OrdersSpec,
    TasksSpec,
    WaveSpec,
)
from .scenario import (  # noqa: F401
    MAX_STEPS_PER_TICK,
    MAX_TICKS_PER_MOVE,
    WHEEL_BASE_SHARE,
    Scenario,
    _orders_bound,
    diffdrive_preset,
)
from .types import (  # noqa: F401
    ENTRY_POINT_NAME,
    MAX_CELLS,
    MAX_COUNT,
    MAX_FLOAT,
    MAX_ORDERS,
    MAX_SIDE,
    MAX_TICKS,
    NAME,
    PLUGIN_PATH,
    Bool,
    Budget,
    Cell,
    ExecutorName,
    Int,
    NonNegFloat,
    NonNegInt,
    NonNegTicks,
    Params,
    PlannerName,
    PosFloat,
    PosInt,
    Prob,
    SchedulerName,
    Seed,
    Side,
    Ticks,
    _as_dict,
    _builtin_or_plugin,
    _Model,
    _named,
    _not_bool_or_text,
)

__all__ = [
    "AgvTypeSpec", "AgvGroupSpec", "FleetSpec", "ShelfBlockSpec", "RectSpec", "InventorySpec",
    "GeneratorSpec", "LayoutSpec", "ErrandsSpec", "OrdersSpec", "SchedulerSpec", "PlannerSpec", "ExecutorSpec",
    "FaultsSpec", "TasksSpec", "Scenario", "load_scenario", "scenario_from_dict",
    "apply_overrides", "parse_override", "diffdrive_preset",
]
