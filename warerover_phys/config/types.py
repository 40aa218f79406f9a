"""Limits, constrained field types and the base model the scenario schema is built from."""

from __future__ import annotations

import re
from typing import Annotated, Any

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
)

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


def _as_dict(value: Any) -> dict[str, Any]:
    if isinstance(value, dict):
        return dict(value)
    if isinstance(value, str):
        return {"name": value}
    return {}
