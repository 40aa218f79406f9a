"""``paths_json``: the ``paths.json`` that ``warerover run`` writes (see ``outputs.py``).

::

    {"agvs": {"0": {"type": "small", "footprint": 1, "ticks_per_move": 1}},
     "planned": [{"agv": 0, "tick": 0, "states": [[[1, 0], [1, 0]], [[1, 0], [2, 0]],
                                                  [[2, 0], [2, 0]]]}],
     "actual": {"0": [[[1, 0], [1, 0]], [[1, 0], [2, 0]], [[2, 0], [2, 0]]]}}

A state is ``[from, to]``, both ``[row, col]`` anchor cells: ``from == to`` when the AGV
stands, ``from != to`` on the ticks of a move that takes several ticks (a slow AGV). Such a
moving state counts as cell ``from`` (the AGV has not arrived yet), so the example reads as
``(1, 0), (1, 0), (2, 0)``: a two-tick move. Anchors may also be flat node indices
(``row * cols + col``); they need the map width from a top-level ``cols`` key or the
``cols=`` argument.

``which="actual"`` reads the executed ``actual`` states (per AGV, one state per tick from
tick 0). ``which="planner"`` stitches ``planned``: the committed paths, in file order, each
replacing its AGV's earlier plan from its ``tick`` on (an AGV stays at its first planned
cell before its first plan, and at its last cell in any gap). Agents are the AGV ids in
increasing order; ``meta["agv_ids"]`` names them when they are not 0..n-1. Top-level
``rows``, ``cols`` and ``map_name`` (written by this module, not by ``warerover run``) give
the map; every other top-level key (``agvs`` ...) goes to ``Plan.meta``.

The writer writes one committed path per AGV from tick 0 and the same states as ``actual``,
all standing states ``[[r, c], [r, c]]``.
"""

from __future__ import annotations

import json

from ._common import MAX_AGENTS, MAX_CELLS, MAX_COORD, MAX_TIMESTEP, check_int, fail
from .model import Plan

_OWNED = ("planned", "actual", "rows", "cols", "map_name", "agv_ids")


def _anchor(value, source: str, where: str, cols: int | None) -> tuple[int, int]:
    if type(value) is list and len(value) == 2:
        return (check_int(value[0], source, f"{where}[0]", what="row"),
                check_int(value[1], source, f"{where}[1]", what="column"))
    if type(value) is int:
        if cols is None:
            fail(source, where, "a flat node index needs the map width: pass cols= or add a "
                 "top-level 'cols' key", value)
        node = check_int(value, source, where, what="node", high=MAX_COORD * cols)
        return divmod(node, cols)
    fail(source, where, "expected an anchor cell [row, col]", json.dumps(value)[:80])


def _cells(states, source: str, where: str, cols: int | None) -> list[tuple[int, int]]:
    """Cell per state (the ``from`` anchor), every state checked."""
    if type(states) is not list:
        fail(source, where, "expected a list of [from, to] states", json.dumps(states)[:80])
    out = []
    append = out.append
    for k, s in enumerate(states):
        if type(s) is list and len(s) == 2:  # fast path: [[r, c], [r, c]]
            a, b = s
            if type(a) is list and type(b) is list and len(a) == 2 and len(b) == 2:
                r, c = a
                r2, c2 = b
                if (type(r) is int and type(c) is int and type(r2) is int
                        and type(c2) is int and 0 <= r <= MAX_COORD and 0 <= c <= MAX_COORD
                        and 0 <= r2 <= MAX_COORD and 0 <= c2 <= MAX_COORD):
                    append((r, c))
                    continue
            append(_anchor(a, source, f"{where}[{k}][0]", cols))
            _anchor(b, source, f"{where}[{k}][1]", cols)
            continue
        fail(source, f"{where}[{k}]", "expected a state [from, to]", json.dumps(s)[:80])
    if not out:
        fail(source, where, "empty list of states")
    return out


def _agv_id(key, source: str, where: str) -> int:
    if isinstance(key, str):
        if not (key.isascii() and key.isdigit() and len(key) <= 9):
            fail(source, where, "AGV ids must be non-negative integers", key)
        if int(key) >= MAX_AGENTS:
            fail(source, where, f"AGV ids must be below {MAX_AGENTS:,}", key)
        return int(key)
    return check_int(key, source, where, what="AGV id", high=MAX_AGENTS - 1)


def _stitch(planned, source: str, cols: int | None) -> dict[int, list]:
    if type(planned) is not list:
        fail(source, "planned", "expected a list of committed paths", json.dumps(planned)[:80])
    stitched: dict[int, list] = {}
    total = 0
    for k, entry in enumerate(planned):
        where = f"planned[{k}]"
        if type(entry) is not dict:
            fail(source, where, "expected an object {agv, tick, states}", json.dumps(entry)[:80])
        for need in ("agv", "tick", "states"):
            if need not in entry:
                fail(source, f"{where}.{need}", "missing key")
        aid = _agv_id(entry["agv"], source, f"{where}.agv")
        tick = check_int(entry["tick"], source, f"{where}.tick", what="tick",
                         high=MAX_TIMESTEP)
        cells = _cells(entry["states"], source, f"{where}.states", cols)
        path = stitched.setdefault(aid, [])
        total += max(0, tick - len(path)) + len(cells)
        if total > MAX_CELLS:
            fail(source, where, f"plan too large (more than {MAX_CELLS} cells)")
        if tick > len(path):
            path += [path[-1] if path else cells[0]] * (tick - len(path))
        del path[tick:]
        path += cells
    return stitched


def parse(data: dict, source: str, *, which: str = "actual", cols: int | None = None) -> Plan:
    if which not in ("actual", "planner"):
        fail(source, None, "which must be 'actual' or 'planner'", which)
    rows = check_int(data["rows"], source, "rows", low=1, what="rows") if "rows" in data \
        else None
    if "cols" in data:
        file_cols = check_int(data["cols"], source, "cols", low=1, what="cols")
        if cols is not None and cols != file_cols:
            fail(source, "cols", f"the file says cols={file_cols} but cols={cols} was passed")
        cols = file_cols
    elif cols is not None:
        check_int(cols, source, "cols argument", low=1, what="cols")
    map_name = data.get("map_name")
    if map_name is not None and not isinstance(map_name, str):
        fail(source, "map_name", "expected a string", map_name)
    actual = data.get("actual")
    if actual is not None and type(actual) is not dict:
        fail(source, "actual", "expected an object {agv id: states}", json.dumps(actual)[:80])
    if which == "actual":
        if actual is None:
            fail(source, "actual", "missing key")
        found = {_agv_id(k, source, f"actual.{k}"): v for k, v in actual.items()}
        if len(found) != len(actual):
            fail(source, "actual", "the same AGV id twice")
        total = 0
        for aid, states in found.items():
            found[aid] = _cells(states, source, f"actual.{aid}", cols)
            total += len(found[aid])
            if total > MAX_CELLS:
                fail(source, "actual", f"plan too large (more than {MAX_CELLS} cells)")
    else:
        if "planned" not in data:
            fail(source, "planned", "missing key")
        found = _stitch(data["planned"], source, cols)
        agvs = data.get("agvs")
        for key in agvs if type(agvs) is dict else ():
            aid = _agv_id(key, source, f"agvs.{key}")
            if aid not in found and actual is not None and str(aid) in actual:
                found[aid] = _cells(actual[str(aid)], source, f"actual.{aid}", cols)[:1]
    ids = sorted(found)
    meta = {k: v for k, v in data.items() if k not in _OWNED}
    if ids != list(range(len(ids))):
        meta["agv_ids"] = ids
    return Plan(paths=tuple(tuple(found[a]) for a in ids), rows=rows, cols=cols,
                map_name=map_name, meta=meta, fmt="paths_json")


def format_plan(plan: Plan, source: str) -> str:
    n = plan.num_agents
    ids = plan.meta.get("agv_ids")
    if not (isinstance(ids, list) and len(ids) == n and len(set(ids)) == n
            and all(type(i) is int and i >= 0 for i in ids)):
        ids = list(range(n))
    agvs = plan.meta.get("agvs")
    if not (isinstance(agvs, dict) and set(agvs) == {str(i) for i in ids}):
        agvs = {str(i): {"footprint": 1, "ticks_per_move": 1} for i in ids}
    states = [[[[int(r), int(c)], [int(r), int(c)]] for r, c in path] for path in plan.paths]
    doc: dict = {}
    if plan.rows is not None:
        doc["rows"] = int(plan.rows)
    if plan.cols is not None:
        doc["cols"] = int(plan.cols)
    if plan.map_name is not None:
        doc["map_name"] = plan.map_name
    doc.update((k, v) for k, v in plan.meta.items() if k not in _OWNED and k != "agvs")
    doc["agvs"] = agvs
    doc["planned"] = [{"agv": i, "tick": 0, "states": s} for i, s in zip(ids, states,
                                                                          strict=True)]
    doc["actual"] = {str(i): s for i, s in zip(ids, states, strict=True)}
    try:
        return json.dumps(doc, separators=(",", ":"), allow_nan=False) + "\n"
    except (TypeError, ValueError) as err:
        fail(source, "meta", f"meta is not JSON-safe: {err}")
