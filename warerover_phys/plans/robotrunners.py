"""``robotrunners``: the output JSON of the League of Robot Runners start-kit.

::

    {"actionModel": "MAPF_T", "teamSize": 2,
     "start": [[1, 0, "S"], [5, 5, "E"]],
     "sumOfCost": 3, "makespan": 3,
     "actualPaths": ["F,F,W", "R"], "plannerPaths": ["F,F,W", "R"], ...}

``start[i] = [row, col, heading]`` with heading ``E`` (+col), ``S`` (+row), ``W`` (-col) or
``N`` (-row). ``actualPaths[i]`` / ``plannerPaths[i]``: one action per timestep, comma
separated: ``F`` one cell forward in the heading, ``R`` turn clockwise (E -> S -> W -> N),
``C`` turn counter-clockwise, ``W`` wait, ``T`` (newer start-kits: no action in time) wait.
A turn takes a timestep and keeps the cell, so the plan has headings. The reader reads
``actualPaths`` (``which="actual"``) or ``plannerPaths`` (``which="planner"``); every other
key except ``start`` and ``teamSize`` goes to ``Plan.meta``.

The 2026 start-kit writes segmented, run-length encoded paths instead, one string per
agent made of segments ``[(t0,row,col,heading,counter):(F 3,W 2,...)]`` (``outputSegmentSize``
ticks each), and an action takes ``agentMaxCounter`` execution ticks: each tick of ``F``,
``R`` or ``C`` advances the agent's counter, and the move or turn happens on the tick the
counter reaches ``agentMaxCounter`` (``W`` / ``T`` ticks leave the counter alone). The reader
expands these to one plan timestep per execution tick, from the first segment's state (the
start-kit prints the first segment's state in every segment header, so later headers are not
used; their ``t0`` must follow the ticks before them). The recorded actions are the executed
ones (after the start-kit's collision resolution), so the cells are where the robots were.

Writer: a plan with headings is written action by action (a step that is not a wait, a
quarter turn, or one cell forward in the current heading is an error). A plan without
headings is written as if each agent faced the direction of its first move and turned during
waits: a wait before a move in another direction becomes ``R`` or ``C`` (two waits for a
U-turn). A move in a direction the agent does not face yet (a turn with no wait before it)
cannot be written without changing the plan's timing, so it is a :class:`PlanFormatError`;
give the plan headings or waits before its turns. Both ``actualPaths`` and
``plannerPaths`` get the plan's actions; ``sumOfCost`` and ``makespan`` come from ``meta``
when the plan was read from such a file (the start-kit counts them its own way), else from the
plan; the other ``meta`` keys are written back as they are.
"""

from __future__ import annotations

import json
import re

from ._common import MAX_AGENTS, MAX_CELLS, MAX_COORD, check_int, fail
from .model import HEADING_NAMES, HEADING_STEPS, Plan

_OWNED = ("start", "teamSize", "actualPaths", "plannerPaths")
_HEADING = {"E": 0, "S": 1, "W": 2, "N": 3}
_ACTIONS = {"W": 0, "T": 0, "F": 1, "R": 2, "C": 3}


def _start(entry, source: str, where: str) -> tuple[int, int, int]:
    if not isinstance(entry, list) or len(entry) not in (3, 4):
        fail(source, where, "expected [row, col, heading]", json.dumps(entry)[:80])
    if len(entry) == 4 and entry[2:] != ["S", "W"]:  # start-kits that print "S" then "W"
        fail(source, where, "expected [row, col, heading]", json.dumps(entry)[:80])
    row = check_int(entry[0], source, f"{where}[0]", what="row")
    col = check_int(entry[1], source, f"{where}[1]", what="column")
    h = entry[2]
    if isinstance(h, str) and h in _HEADING:
        return row, col, _HEADING[h]
    if type(h) is int and 0 <= h <= 3:
        return row, col, h
    fail(source, f"{where}[2]", "heading must be one of E, S, W, N", h)


def parse(data: dict, source: str, *, which: str = "actual") -> Plan:
    key = {"actual": "actualPaths", "planner": "plannerPaths"}.get(which)
    if key is None:
        fail(source, None, "which must be 'actual' or 'planner'", which)
    for need in ("start", key):
        if need not in data:
            fail(source, need, "missing key")
    starts, strings = data["start"], data[key]
    if not isinstance(starts, list):
        fail(source, "start", "expected a list of [row, col, heading]", type(starts).__name__)
    if not isinstance(strings, list):
        fail(source, key, "expected a list of action strings", type(strings).__name__)
    if "teamSize" in data:
        team = check_int(data["teamSize"], source, "teamSize", what="team size")
        if team != len(starts):
            fail(source, "teamSize", f"teamSize={team} but start has {len(starts)} agents")
    if len(strings) != len(starts):
        fail(source, key, f"{len(strings)} paths but start has {len(starts)} agents")
    if len(starts) > MAX_AGENTS:
        fail(source, "start", f"more than {MAX_AGENTS:,} agents", len(starts))
    max_counter = 1
    if "agentMaxCounter" in data:
        max_counter = check_int(data["agentMaxCounter"], source, "agentMaxCounter", low=1,
                                high=1000, what="ticks per action")
    if data.get("actionModel") == "MAPF":
        return _parse_grid_moves(data, starts, strings, key, source)
    paths, headings = [], []
    total = 0
    steps = HEADING_STEPS
    for i, (entry, text) in enumerate(zip(starts, strings, strict=True)):
        r, c, h = _start(entry, source, f"start[{i}]")
        where = f"{key}[{i}]"
        if not isinstance(text, str):
            fail(source, where, "expected a string of comma-separated actions", text)
        if text.lstrip().startswith("["):
            cells, heads = _segmented(text, (r, c, h), max_counter, total, source, where)
            total += len(cells)
            paths.append(cells)
            headings.append(heads)
            continue
        actions = text.split(",") if text.strip() else []
        total += len(actions) + 1
        if total > MAX_CELLS:
            fail(source, where, f"plan too large (more than {MAX_CELLS} cells)")
        cells, heads = [(r, c)], [h]
        for k, a in enumerate(actions):
            op = _ACTIONS.get(a)
            if op is None:
                op = _ACTIONS.get(a.strip())
                if op is None:
                    fail(source, where, f"unknown action at position {k} (expected F, R, C, "
                         "W or T)", a)
            if op == 1:
                dr, dc = steps[h]
                r += dr
                c += dc
                if r < 0 or c < 0 or r > MAX_COORD or c > MAX_COORD:
                    fail(source, where, f"action {k} (F facing {HEADING_NAMES[h]}) leaves the "
                         f"map at ({r}, {c})", text[max(0, 2 * k - 20):2 * k + 20])
            elif op == 2:
                h = (h + 1) % 4
            elif op == 3:
                h = (h + 3) % 4
            cells.append((r, c))
            heads.append(h)
        paths.append(tuple(cells))
        headings.append(tuple(heads))
    meta = {k: v for k, v in data.items() if k not in _OWNED}
    return Plan(paths=tuple(paths), headings=tuple(headings), meta=meta, fmt="robotrunners")


_MOVES = {"W": (0, 0), "T": (0, 0), "U": (-1, 0), "D": (1, 0), "L": (0, -1), "R": (0, 1)}


def _parse_grid_moves(data: dict, starts: list, strings: list, key: str, source: str) -> Plan:
    """``actionModel: MAPF`` (our runs without rotations): ``U`` / ``D`` / ``L`` / ``R`` move
    one cell up (-row), down, left (-col) or right, ``W`` / ``T`` wait; no headings."""
    paths = []
    total = 0
    for i, (entry, text) in enumerate(zip(starts, strings, strict=True)):
        r, c, _ = _start(entry, source, f"start[{i}]")
        where = f"{key}[{i}]"
        if not isinstance(text, str):
            fail(source, where, "expected a string of comma-separated actions", text)
        actions = text.split(",") if text.strip() else []
        total += len(actions) + 1
        if total > MAX_CELLS:
            fail(source, where, f"plan too large (more than {MAX_CELLS} cells)")
        cells = [(r, c)]
        for k, a in enumerate(actions):
            step = _MOVES.get(a.strip())
            if step is None:
                fail(source, where, f"unknown action at position {k} (the MAPF action model "
                     "has U, D, L, R, W and T)", a)
            r += step[0]
            c += step[1]
            if r < 0 or c < 0 or r > MAX_COORD or c > MAX_COORD:
                fail(source, where, f"action {k} leaves the map at ({r}, {c})", a)
            cells.append((r, c))
        paths.append(tuple(cells))
    meta = {k: v for k, v in data.items() if k not in _OWNED}
    return Plan(paths=tuple(paths), meta=meta, fmt="robotrunners")


_SEGMENT = re.compile(r"\[\((\d{1,9}),(\d{1,7}),(\d{1,7}),([0-3]),(\d{1,4})\):\(([^()\[\]]*)\)\]",
                      re.ASCII)
_RUN = re.compile(r"\s*([FRCWT])\s+(\d{1,9})\s*", re.ASCII)


def _segmented(text: str, start: tuple[int, int, int], max_counter: int, total: int,
               source: str, where: str):
    """Cells and headings per execution tick of a segmented (2026) path string."""
    text = text.strip()
    pos = 0
    cells: list[tuple[int, int]] = []
    heads: list[int] = []
    r = c = h = count = 0
    while pos < len(text):
        m = _SEGMENT.match(text, pos)
        if m is None:
            fail(source, where, "expected a segment '[(t,row,col,heading,counter):(A n,...)]' "
                 f"at character {pos}", text[pos:])
        t0 = int(m.group(1))
        if pos == 0:
            r, c, h, count = int(m.group(2)), int(m.group(3)), int(m.group(4)), int(m.group(5))
            if (r, c, h) != start:
                fail(source, where, f"first segment starts at ({r}, {c}) facing "
                     f"{HEADING_NAMES[h]}, not at the agent's start", m.group(0))
            if count >= max_counter:
                fail(source, where, f"counter {count} must be below agentMaxCounter="
                     f"{max_counter}", m.group(0))
            cells.append((r, c))
            heads.append(h)
        if t0 != len(cells) - 1:
            fail(source, where, f"segment starts at tick {t0} but the segments before it "
                 f"cover {len(cells) - 1} ticks", m.group(0))
        body = m.group(6)
        for run in body.split(",") if body.strip() else ():
            rm = _RUN.fullmatch(run)
            if rm is None:
                fail(source, where, "expected 'A n' (action F, R, C, W or T and a tick count)",
                     run)
            a, n = rm.group(1), int(rm.group(2))
            total += n
            if total > MAX_CELLS:
                fail(source, where, f"plan too large (more than {MAX_CELLS} cells)")
            if a in "WT":
                cells += [(r, c)] * n
                heads += [h] * n
                continue
            for _ in range(n):
                count += 1
                if count >= max_counter:
                    count = 0
                    if a == "F":
                        r, c = r + HEADING_STEPS[h][0], c + HEADING_STEPS[h][1]
                        if r < 0 or c < 0 or r > MAX_COORD or c > MAX_COORD:
                            fail(source, where, f"F facing {HEADING_NAMES[h]} leaves the map "
                                 f"at ({r}, {c}) on tick {len(cells)}", m.group(0))
                    else:
                        h = (h + 1) % 4 if a == "R" else (h + 3) % 4
                cells.append((r, c))
                heads.append(h)
        pos = m.end()
    if not cells:
        fail(source, where, "empty segmented path", text)
    return tuple(cells), tuple(heads)


def _direction(a, b) -> int | None:
    step = (b[0] - a[0], b[1] - a[1])
    return HEADING_STEPS.index(step) if step in HEADING_STEPS else None


def _actions_from_headings(path, heads, i: int, source: str) -> list[str]:
    acts = []
    for t in range(len(path) - 1):
        h0, h1 = heads[t], heads[t + 1]
        if path[t] == path[t + 1]:
            if h1 == h0:
                acts.append("W")
            elif h1 == (h0 + 1) % 4:
                acts.append("R")
            elif h1 == (h0 + 3) % 4:
                acts.append("C")
            else:
                fail(source, f"headings[{i}][{t + 1}]", f"agent {i} turns 180 degrees in one "
                     "timestep", f"{HEADING_NAMES[h0]} -> {HEADING_NAMES[h1]}")
        elif h1 != h0 or _direction(path[t], path[t + 1]) != h0:
            fail(source, f"paths[{i}][{t + 1}]", f"agent {i} at t={t} does not move one cell "
                 f"forward facing {HEADING_NAMES[h0]} (or turns while moving)",
                 f"{path[t]} -> {path[t + 1]}, heading {HEADING_NAMES[h0]} -> "
                 f"{HEADING_NAMES[h1]}")
        else:
            acts.append("F")
    return acts


def _actions_inferred(path, i: int, source: str) -> tuple[int, list[str]]:
    n = len(path)
    nxt: list[int | None] = [None] * n
    d = None
    for t in range(n - 2, -1, -1):
        if path[t + 1] != path[t]:
            d = _direction(path[t], path[t + 1])
            if d is None:
                fail(source, f"paths[{i}][{t + 1}]", f"agent {i} jumps at t={t}: not a step to "
                     "a 4-neighbour", f"{path[t]} -> {path[t + 1]}")
        nxt[t] = d
    h0 = h = nxt[0] if nxt[0] is not None else 0
    acts = []
    for t in range(n - 1):
        d = nxt[t]
        if path[t + 1] != path[t]:
            if d != h:
                fail(source, f"paths[{i}][{t + 1}]", f"agent {i} moves {HEADING_NAMES[d]} at "
                     f"t={t} while facing {HEADING_NAMES[h]}: a Robot Runners turn takes a "
                     "timestep; give the plan headings or a wait before each turn",
                     f"{path[t]} -> {path[t + 1]}")
            acts.append("F")
        elif d is None or d == h:
            acts.append("W")
        elif d == (h + 3) % 4:
            acts.append("C")
            h = d
        else:
            acts.append("R")
            h = (h + 1) % 4
    return h0, acts


def format_plan(plan: Plan, source: str) -> str:
    starts, actions = [], []
    for i, path in enumerate(plan.paths):
        if plan.headings is not None:
            h0 = plan.headings[i][0]
            acts = _actions_from_headings(path, plan.headings[i], i, source)
        else:
            h0, acts = _actions_inferred(path, i, source)
        starts.append([int(path[0][0]), int(path[0][1]), HEADING_NAMES[h0]])
        actions.append(",".join(acts))
    doc = {"actionModel": "MAPF_T"}
    doc.update((k, v) for k, v in plan.meta.items() if k not in _OWNED)
    doc.setdefault("sumOfCost", plan.sum_of_costs)
    doc.setdefault("makespan", plan.makespan)
    doc.update({"teamSize": plan.num_agents, "start": starts, "actualPaths": actions,
                "plannerPaths": actions})
    try:
        return json.dumps(doc, allow_nan=False) + "\n"
    except (TypeError, ValueError) as err:
        fail(source, "meta", f"meta is not JSON-safe: {err}")
