"""``lacam``: the MAPF-visualizer text format that LaCAM, LaCAM* and lacam3 write.

::

    agents=2
    map_file=random-32-32-10.map
    solver=planner
    soc=3
    makespan=2
    starts=(1,0),(5,5),
    goals=(3,0),(5,5),
    solution=
    0:(1,0),(5,5),
    1:(2,0),(5,5),
    2:(3,0),(5,5),

``key=value`` header lines, then ``solution=``, then one line per timestep ``t:(x,y),...``
with one ``(x, y)`` per agent, x = column, y = row (trailing comma optional). Every agent
appears on every line, so waits and the time after an agent's arrival repeat its cell.
"""

from __future__ import annotations

import re

from ._common import MAX_AGENTS, MAX_CELLS, diagnose, excerpt, fail, ints_of, scalar, tuple_pattern
from .model import Plan

_KEY = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-]*", re.ASCII)
_PAIR = tuple_pattern(2)
_BODY = re.compile(r"\s*(?:" + _PAIR + r"\s*,\s*)*(?:" + _PAIR + r"\s*)?", re.ASCII)
_STEP = re.compile(r"(\d{1,8})\s*:(.*)", re.ASCII)
_OWNED = ("agents", "map_file", "width", "height", "soc", "makespan", "solution", "starts",
          "goals")


def _cells(body: str, source: str, where: str) -> list[int]:
    """The integers of a ``(x,y),(x,y),...`` list, flat (x0, y0, x1, y1, ...)."""
    if _BODY.fullmatch(body) is None:
        message, bad = diagnose(body, 2, ",")
        fail(source, where, message, bad)
    return ints_of(body, ",")


def parse(text: str, source: str) -> Plan:
    lines = text.split("\n")
    meta, key_line, agents, rows, cols, map_name, solution_at = _parse_header(lines, source)
    flat, steps, agents = _parse_solution(lines, solution_at, agents, source)
    ms = meta.get("makespan")
    if steps and type(ms) is int and ms != steps - 1:
        fail(source, f"line {key_line['makespan']}", f"makespan={ms} but the solution has "
             f"{steps} timestep lines (expected makespan={steps - 1}; truncated file?)")
    if agents and not steps and "agents" in key_line:
        meta["agents"] = agents  # an unsolved instance: keep its size
    width = 2 * (agents or 0)
    paths = tuple(tuple(zip(flat[2 * a + 1::width], flat[2 * a::width], strict=True))
                  for a in range(agents or 0)) if steps else ()
    return Plan(paths=paths, rows=rows, cols=cols, map_name=map_name, meta=meta, fmt="lacam")


def _parse_header(lines: list[str], source: str):
    """The header lines up to ``solution=`` (or a bare solution): the other keys' values,
    the line of each key, agents, rows, cols, the map's name and the solution's first
    line index."""
    meta: dict = {}
    key_line: dict[str, int] = {}
    agents = rows = cols = None
    map_name = None
    i, n_lines = 0, len(lines)
    solution_at = None
    while i < n_lines:
        raw = lines[i]
        line = raw.strip()
        i += 1
        if not line:
            continue
        if _STEP.match(line) and not key_line:  # a bare solution without a header
            solution_at = i - 1
            break
        key, sep, value = line.partition("=")
        key, value = key.strip(), value.strip()
        if not sep and _STEP.match(line):
            fail(source, f"line {i}", "a timestep line before 'solution='", raw)
        if not sep or _KEY.fullmatch(key) is None:
            fail(source, f"line {i}", "expected a 'key=value' header line or 'solution='", raw)
        if key in key_line:
            fail(source, f"line {i}", f"duplicate header key '{key}' (first on line "
                 f"{key_line[key]})", raw)
        key_line[key] = i
        if key == "solution":
            if value:
                fail(source, f"line {i}", "'solution=' must be alone on its line", raw)
            solution_at = i
            break
        if key == "agents":
            if not value.isascii() or not value.isdigit() or len(value) > 7:
                fail(source, f"line {i}", "agents= must be a non-negative integer", raw)
            agents = int(value)
            if agents > MAX_AGENTS:
                fail(source, f"line {i}", f"more than {MAX_AGENTS:,} agents", raw)
        elif key in ("width", "height"):
            if not value.isascii() or not value.isdigit() or len(value) > 7 or int(value) < 1:
                fail(source, f"line {i}", f"{key}= must be a positive integer", raw)
            if key == "width":
                cols = int(value)
            else:
                rows = int(value)
        elif key == "map_file":
            map_name = value
        elif key in ("starts", "goals"):
            flat = _cells(value, source, f"line {i}")
            meta[key] = [[flat[k + 1], flat[k]] for k in range(0, len(flat), 2)]
        else:
            meta[key] = scalar(value)
    if solution_at is None:
        if not key_line:
            fail(source, None, "empty file: no header and no 'solution=' line")
        fail(source, f"line {n_lines}", "no 'solution=' line (truncated file?)")
    for key in ("starts", "goals"):
        if key in meta and agents is not None and len(meta[key]) != agents:
            fail(source, f"line {key_line[key]}", f"{key}= lists {len(meta[key])} cells but "
                 f"agents={agents}")
    return meta, key_line, agents, rows, cols, map_name, solution_at


def _parse_solution(lines: list[str], solution_at: int, agents: int | None, source: str):
    """The timestep lines from ``solution_at``: the cells as one flat list (col, row per
    agent per timestep), the number of timesteps and the number of agents."""
    n_lines = len(lines)
    flat: list[int] = []
    steps = 0
    for j in range(solution_at, n_lines):
        line = lines[j].strip()
        if not line:
            continue
        if line.count("(") > MAX_AGENTS:  # counted before the line is parsed
            fail(source, f"line {j + 1}", f"more than {MAX_AGENTS:,} agents on one line")
        m = _STEP.fullmatch(line)
        if m is None:
            fail(source, f"line {j + 1}", "expected a timestep line 't:(x,y),(x,y),...'",
                 lines[j])
        if int(m.group(1)) != steps:
            fail(source, f"line {j + 1}", f"timestep out of order: expected {steps}",
                 lines[j])
        ints = _cells(m.group(2), source, f"line {j + 1}")
        k = len(ints) // 2
        if agents is None:
            agents = k
        if k != agents:
            fail(source, f"line {j + 1}", f"{k} cells on the line but {agents} agents "
                 "(truncated line?)", excerpt(lines[j][-60:]))
        flat += ints
        steps += 1
        if steps * agents > MAX_CELLS:
            fail(source, f"line {j + 1}", f"plan too large (more than {MAX_CELLS} cells)")
    return flat, steps, agents


def _header_value(value) -> str | None:
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        return None
    if isinstance(value, float):
        return repr(value) if value == value and abs(value) != float("inf") else None
    text = str(value)
    return None if "\n" in text or "\r" in text else text


def format_plan(plan: Plan, source: str) -> str:
    n = plan.num_agents
    out = [f"agents={n if n or 'agents' not in plan.meta else plan.meta['agents']}"]
    if plan.map_name is not None:
        if "\n" in plan.map_name or "\r" in plan.map_name:
            fail(source, "map_name", "a map name on one line", plan.map_name)
        out.append(f"map_file={plan.map_name}")
    if plan.cols is not None:
        out.append(f"width={int(plan.cols)}")
    if plan.rows is not None:
        out.append(f"height={int(plan.rows)}")
    for key, value in plan.meta.items():
        text = _header_value(value)
        if key not in _OWNED and text is not None and _KEY.fullmatch(str(key)):
            out.append(f"{key}={text}")
    out.append(f"soc={plan.sum_of_costs}")
    out.append(f"makespan={plan.makespan}")
    for key in ("starts", "goals"):
        cells = plan.meta.get(key)
        if isinstance(cells, list) and len(cells) == n and all(
                isinstance(c, list | tuple) and len(c) == 2 for c in cells):
            out.append(f"{key}=" + "".join(f"({int(c)},{int(r)})," for r, c in cells))
    out.append("solution=")
    if n:
        horizon = plan.makespan + 1
        columns = []
        for path in plan.paths:
            col = [f"({int(c)},{int(r)})," for r, c in path]
            col += [col[-1]] * (horizon - len(col))
            columns.append(col)
        for t, cells in enumerate(zip(*columns, strict=True)):
            out.append(f"{t}:" + "".join(cells))
    return "\n".join(out) + "\n"
