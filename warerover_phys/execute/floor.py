"""The floor and the fleet of ``warerover execute``: a map, layout or scenario file, the AGV
types (:func:`load_floor`, :func:`load_fleet`), and :class:`PlanError`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..config import AgvTypeSpec
from ..errors import ScenarioError, WareroverError
from ..layout import CellType, Layout

DEFAULT_TYPE = AgvTypeSpec(body_m=(0.7, 0.7), max_speed_mps=1.0)
"""The AGV of ``execute`` when no fleet is given: 1x1, 0.7 m body, 1 m/s."""


class PlanError(WareroverError):
    """A plan that cannot be executed on this floor with this fleet."""

    def __init__(self, message: str, *, file: str | None = None, agent: int | None = None,
                 timestep: int | None = None, cells: tuple = ()) -> None:
        self.file, self.agent, self.timestep, self.cells = file, agent, timestep, cells
        where = f"{file}: " if file else ""
        parts = [f"agent {agent}" if agent is not None else "",
                 f"timestep {timestep}" if timestep is not None else ""]
        at = ", ".join(p for p in parts if p)
        super().__init__(f"{where}{at + ': ' if at else ''}{message}")


def load_floor(path: str | Path) -> tuple[Layout, dict[str, AgvTypeSpec] | None, list[str]]:
    """The floor in ``path`` (``.map``, layout YAML or scenario YAML), the AGV types it
    names (scenarios only) and the type of each of its AGVs (scenarios only)."""
    from ..inputs import check_regular_file

    path = check_regular_file(path, "floor")
    if path.suffix == ".map":
        from ..problems.movingai import read_map

        m = read_map(path)
        grid = np.where(m.obstacles, CellType.OBSTACLE, CellType.FLOOR).astype(np.int8)
        layout = Layout(grid=grid, cell_m=1.0, shelves=(), stations=(), parking=(),
                        access_points=(), num_skus=0, name=path.stem)
        return layout, None, []
    from ..config import LayoutSpec, load_scenario, read_yaml
    from ..layout import build_layout

    data = read_yaml(path)
    if isinstance(data, dict) and ("fleet" in data or "layout" in data):
        sc = load_scenario(path)
        layout = build_layout(sc.layout, fleet_size=sc.fleet.size, file=str(path), name=sc.name)
        kinds = [g.type for g in sc.fleet.agvs for _ in range(g.count)]
        return layout, dict(sc.fleet.types), kinds
    try:
        spec = LayoutSpec.model_validate({k: v for k, v in data.items() if k != "name"})
    except Exception as err:  # noqa: BLE001 - pydantic's error, named below
        raise ScenarioError(f"not a layout or scenario ({str(err).splitlines()[0]})",
                            file=str(path)) from None
    if isinstance(spec.map, str):
        spec = spec.model_copy(update={"map": str((path.parent / spec.map).resolve())})
    return build_layout(spec, file=str(path), name=path.stem), None, []


def load_fleet(path: str | Path | None, n: int, scenario_types: dict[str, AgvTypeSpec] | None,
               scenario_kinds: list[str]) -> list[AgvTypeSpec]:
    """The AGV type of each of ``n`` agents.

    ``FLEET.yaml`` is either one type for every agent (``{footprint: 1, body_m: [0.7, 0.7],
    max_speed_mps: 1.0, ...}``) or ``{types: {NAME: {...}}, agents: [NAME, ...]}`` (one name
    per agent, or a single name for all). Without a file: the scenario's fleet if the floor
    is a scenario with ``n`` AGVs, else :data:`DEFAULT_TYPE`.
    """
    if path is None:
        if scenario_types and len(scenario_kinds) == n:
            return [scenario_types[k] for k in scenario_kinds]
        return [DEFAULT_TYPE] * n
    from pydantic import ValidationError

    from ..config import read_yaml

    src = str(path)
    data = read_yaml(Path(path))
    if not isinstance(data, dict):
        raise ScenarioError("a fleet file is a mapping", file=src, value=data)
    try:
        if "types" not in data:
            return [AgvTypeSpec.model_validate(data)] * n
        if not isinstance(data["types"], dict) or not data["types"]:
            raise ScenarioError("expected a mapping of type names to AGV types", file=src,
                                field="types", value=data["types"])
        types = {k: AgvTypeSpec.model_validate(v) for k, v in data["types"].items()}
    except ValidationError as err:
        e = err.errors()[0]
        raise ScenarioError(e["msg"], file=src, field=".".join(map(str, e["loc"])),
                            value=e.get("input")) from None
    agents = data.get("agents", next(iter(types), None))
    if not isinstance(agents, str | list):
        raise ScenarioError("expected a type name or a list of them", file=src,
                            field="agents", value=agents)
    names = [agents] * n if isinstance(agents, str) else agents
    if len(names) != n:
        raise ScenarioError(f"lists {len(names)} agents but the plan has {n}", file=src,
                            field="agents", value=len(names))
    for i, name in enumerate(names):
        if not isinstance(name, str) or name not in types:
            raise ScenarioError(f"unknown AGV type (choose from {sorted(types)})", file=src,
                                field=f"agents[{i}]", value=name)
    return [types[name] for name in names]
