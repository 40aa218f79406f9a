"""Loading a scenario: YAML files, ``--set`` overrides and validation errors as one clear line."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import yaml
from pydantic import (
    ValidationError,
)

from ..errors import ScenarioError
from ..util import safe_yaml
from .scenario import Scenario
from .types import _as_dict


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


def read_yaml(path: Path, what: str = "scenario") -> dict[str, Any]:
    """Read a YAML mapping, turning every failure into a one-line :class:`ScenarioError`."""
    from ..inputs import read_bytes

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
    from ..shipped import resolve_scenario

    path = resolve_scenario(path)
    data = read_yaml(path)
    try:
        return scenario_from_dict(data, source=str(path), overrides=overrides)
    except ScenarioError as err:
        raise err.with_file(str(path)) from None
