"""The layout editor's server side: load a layout into the editor's form, turn the editor's
form back into layout YAML, and check it the way ``warerover check`` does.

The editor holds one character per cell (:class:`~.protocol.LayoutDoc`): ``.`` floor,
``#`` obstacle, ``S`` 1x1 shelf, ``R`` station, ``P`` parking, ``A`` maintenance access
point, and ``B`` for the four cells of a 2x2 shelf (whose top-left cells are listed in
``big_shelves``). Saved YAML uses the layout's own schema: ``grid`` rows plus
``shelf_blocks`` of ``size: 2`` for the 2x2 shelves.

>>> from warerover_phys.serve.protocol import LayoutDoc
>>> doc = LayoutDoc(rows=3, cols=4, cells="R..P" "S..P" "..AP")
>>> layout_dict(doc)["grid"]
['R..P', 'S..P', '..AP']
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from ..errors import WareroverError
from .protocol import LayoutDoc

__all__ = ["layout_dict", "doc_from_file", "check_doc", "scenario_for", "save_doc"]

_CELL_RE = re.compile(r"[\[(](\d+), *(\d+)[\])]")
_ROW_RE = re.compile(r"layout\.grid\[(\d+)\]")
EDITOR_CHARS = set(".#SRPAB")


def _rows(doc: LayoutDoc) -> list[str]:
    if len(doc.cells) != doc.rows * doc.cols:
        raise WareroverError(f"layout has {len(doc.cells)} cells, expected rows x cols = "
                             f"{doc.rows * doc.cols}")
    bad = set(doc.cells) - EDITOR_CHARS
    if bad:
        raise WareroverError(f"unknown cell characters {''.join(sorted(bad))!r} (use "
                             "'.#SRPAB')")
    return [doc.cells[r * doc.cols:(r + 1) * doc.cols] for r in range(doc.rows)]


def layout_dict(doc: LayoutDoc) -> dict[str, Any]:
    """The layout YAML mapping of an editor document."""
    rows = [row.replace("B", ".") for row in _rows(doc)]
    out: dict[str, Any] = {"cell_m": doc.cell_m, "grid": rows}
    if doc.big_shelves:
        out["shelf_blocks"] = [{"origin": [int(r), int(c)], "size": 2}
                               for r, c in doc.big_shelves]
    return out


def doc_from_file(path: Path) -> LayoutDoc:
    """Read a layout YAML (or a scenario YAML, whose layout is taken) into editor form."""
    from ..config import LayoutSpec, read_yaml
    from ..layout import build_layout

    data = read_yaml(path, "layout")
    if "layout" in data and "fleet" in data:          # a scenario: follow its layout
        lay = data["layout"]
        if isinstance(lay, str):
            path = (path.parent / lay).resolve()
            data = read_yaml(path, "layout")
        else:
            data = lay
    data = {k: v for k, v in data.items() if k != "name"}
    if isinstance(data.get("map"), str):
        data["map"] = str((path.parent / data["map"]).resolve())
    try:
        spec = LayoutSpec.model_validate(data)
    except Exception as err:  # pydantic's ValidationError: say it in one line
        raise WareroverError(f"{path.name}: not a layout ({str(err).splitlines()[0]})") \
            from None
    lay = build_layout(spec, fleet_size=0, file=str(path))
    rows = [list(r) for r in lay.to_ascii()]
    big = []
    for shelf in lay.shelves:
        if shelf.size == 2:
            r, c = shelf.anchor
            big.append((r, c))
            for dr in (0, 1):
                for dc in (0, 1):
                    rows[r + dr][c + dc] = "B"
        elif shelf.size > 2:
            raise WareroverError(f"{path.name}: shelves of size {shelf.size} cannot be edited "
                                 "(the editor knows 1x1 and 2x2)")
    return LayoutDoc(rows=lay.rows, cols=lay.cols, cell_m=float(lay.cell_m),
                     cells="".join("".join(r) for r in rows), big_shelves=big)


def scenario_for(doc: LayoutDoc, layout: dict | str) -> dict[str, Any]:
    """A scenario that runs on the layout: 1x1 AGVs, one per parking cell up to 10 (or
    ``doc.agvs``), plus one 2x2 AGV when there are 2x2 shelves; one-shot orders."""
    parking = doc.cells.count("P")
    large = 1 if doc.big_shelves else 0
    n = doc.agvs or max(1, min(10, parking - 4 * large))
    types: dict[str, Any] = {"small": {"footprint": 1, "body_m": [0.7, 0.7], "cargo_class": 1}}
    groups: list[dict[str, Any]] = [{"type": "small", "count": n}]
    if large:
        types["large"] = {"footprint": 2, "body_m": [1.6, 1.6], "cargo_class": 2,
                          "max_speed_mps": 0.75, "max_accel_mps2": 0.5, "drive": "omni"}
        groups.insert(0, {"type": "large", "count": large})
    return {"name": "edited", "seed": 0, "max_ticks": 1000, "tick_s": 1.0, "layout": layout,
            "fleet": {"types": types, "agvs": groups},
            "orders": {"pattern": "oneshot", "oneshot": {"count": 20}},
            "scheduler": "ta", "planner": "astar", "executor": "grid"}


def _cells_of(err: Exception, doc: LayoutDoc) -> list[list[int]]:
    """The cells an error names: ``[r, c]`` values and cells in the text, or a grid row."""
    text = str(err)
    cells = {(int(r), int(c)) for r, c in _CELL_RE.findall(text)}
    value = getattr(err, "value", None)
    if isinstance(value, list | tuple) and len(value) == 2 and all(
            isinstance(v, int) for v in value):
        cells.add((int(value[0]), int(value[1])))
    field = getattr(err, "field", None) or ""
    m = _ROW_RE.search(field) or _ROW_RE.search(text)
    if m and not cells:
        r = int(m.group(1))
        cells.update((r, c) for c in range(doc.cols))
    return [[r, c] for r, c in sorted(cells) if 0 <= r < doc.rows and 0 <= c < doc.cols]


def check_doc(doc: LayoutDoc) -> list[dict[str, Any]]:
    """What ``warerover check`` says about a scenario on this layout: ``[]`` when it is
    fine, else ``[{"message", "field", "cells"}]`` (cells the error names, ``[row, col]``)."""
    from ..config import scenario_from_dict
    from ..world import World

    try:
        scenario = scenario_from_dict(scenario_for(doc, layout_dict(doc)), source="layout")
        World.build(scenario)
    except WareroverError as err:
        return [{"message": str(err), "field": getattr(err, "field", None),
                 "cells": _cells_of(err, doc)}]
    except Exception as err:  # noqa: BLE001 - a checker reports, it does not crash
        return [{"message": f"{type(err).__name__}: {err}", "field": None, "cells": []}]
    return []


def save_doc(doc: LayoutDoc, path: Path, with_scenario: bool = True) -> list[Path]:
    """Write the layout YAML to ``path`` (and ``NAME.scenario.yaml`` that uses it)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    header = "# Drawn in the warerover serve layout editor.\n"
    path.write_text(header + yaml.safe_dump(layout_dict(doc), sort_keys=False,
                                            default_flow_style=None, width=10_000),
                    encoding="utf-8")
    out = [path]
    if with_scenario:
        stem = path.name.removesuffix(".yaml").removesuffix(".yml")
        scen = path.with_name(stem + ".scenario.yaml")
        scen.write_text(header + yaml.safe_dump(scenario_for(doc, path.name), sort_keys=False,
                                                default_flow_style=None, width=10_000),
                        encoding="utf-8")
        out.append(scen)
    return out
