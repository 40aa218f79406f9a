"""One agent per line: ``lns`` (MAPF-LNS2 / EECBS / SMART paths) and ``timed`` (SMART).

``lns``::

    Agent 0:(1,0)->(2,0)->(2,0)->(3,0)->
    Agent 1:(5,5)->

``(row, col)`` per timestep (list index = timestep); a wait repeats the cell; the trailing
``->`` is optional. Lines may come in any order but the ids must be 0..n-1.

``timed``::

    Agent 0:(0,1,0)->(0,2,1)->(0,3,3)->
    Agent 1:(5,5,0)->

``(x, y, t)`` points with x = column by default (``xy=False``: ``(row, col, t)``); t must
strictly increase. A gap in t means the agent waited at the previous point, so the example's
agent 0 is at column 2 at t = 1 and t = 2 and at column 3 from t = 3; before its first point
an agent is at that point's cell. The writer emits only the points where the cell changes
(plus the first and the last), so waits are compressed.
"""

from __future__ import annotations

import re

from ._common import MAX_AGENTS, MAX_CELLS, MAX_TIMESTEP, diagnose, fail, ints_of, tuple_pattern
from .model import Plan

_AGENT = re.compile(r"Agent\s*(\d{1,7})\s*:(.*)", re.ASCII)


def _body(n: int) -> re.Pattern:
    item = tuple_pattern(n)
    return re.compile(r"\s*(?:" + item + r"\s*->\s*)*(?:" + item + r"\s*)?", re.ASCII)


_BODY = {2: _body(2), 3: _body(3)}


def _lines(text: str, source: str, n: int):
    """``(line_no, agent_id, ints)`` per non-blank line, checked."""
    seen: dict[int, int] = {}
    for no, raw in enumerate(text.split("\n"), 1):
        line = raw.strip()
        if not line:
            continue
        m = _AGENT.fullmatch(line)
        if m is None:
            fail(source, f"line {no}", "expected 'Agent <id>:' and a path", raw)
        aid, body = int(m.group(1)), m.group(2)
        if aid in seen:
            fail(source, f"line {no}", f"agent {aid} again (first on line {seen[aid]})", raw)
        seen[aid] = no
        if len(seen) > MAX_AGENTS or aid >= MAX_AGENTS:
            fail(source, f"line {no}", f"more than {MAX_AGENTS:,} agents", raw[:40])
        if _BODY[n].fullmatch(body) is None:
            message, bad = diagnose(body, n, "->")
            fail(source, f"line {no}", message, bad)
        ints = ints_of(body, "->")
        if not ints:
            fail(source, f"line {no}", f"agent {aid} has an empty path", raw)
        yield no, aid, ints
    if not seen:
        fail(source, None, "empty file: no 'Agent i:' lines")
    if len(seen) != max(seen) + 1:
        missing = min(set(range(len(seen) + 1)) - set(seen))
        fail(source, None, f"agent ids must be 0..{len(seen) - 1}: agent {missing} is missing")


def _ordered(found: dict[int, tuple]) -> tuple:
    return tuple(found[a] for a in range(len(found)))


def parse_lns(text: str, source: str) -> Plan:
    found: dict[int, tuple] = {}
    total = 0
    for no, aid, ints in _lines(text, source, 2):
        total += len(ints) // 2
        if total > MAX_CELLS:
            fail(source, f"line {no}", f"plan too large (more than {MAX_CELLS} cells)")
        found[aid] = tuple(zip(ints[0::2], ints[1::2], strict=True))
    return Plan(paths=_ordered(found), fmt="lns")


def parse_timed(text: str, source: str, *, xy: bool = True) -> Plan:
    found: dict[int, tuple] = {}
    total = 0
    for no, aid, ints in _lines(text, source, 3):
        path: list[tuple[int, int]] = []
        prev_t = -1
        for k in range(0, len(ints), 3):
            a, b, t = ints[k], ints[k + 1], ints[k + 2]
            if t <= prev_t:
                fail(source, f"line {no}", f"agent {aid}: timesteps must strictly increase "
                     f"(t={t} after t={prev_t})", f"({a},{b},{t})")
            if t > MAX_TIMESTEP:
                fail(source, f"line {no}", f"timestep too large (max {MAX_TIMESTEP})",
                     f"({a},{b},{t})")
            total += t - prev_t
            if total > MAX_CELLS:
                fail(source, f"line {no}", f"plan too large (more than {MAX_CELLS} cells)")
            cell = (b, a) if xy else (a, b)
            if t - prev_t > 1:
                path += [path[-1] if path else cell] * (t - prev_t - 1)
            path.append(cell)
            prev_t = t
        found[aid] = tuple(path)
    return Plan(paths=_ordered(found), fmt="timed")


def format_lns(plan: Plan) -> str:
    return "".join(f"Agent {i}:" + "".join(f"({int(r)},{int(c)})->" for r, c in path) + "\n"
                   for i, path in enumerate(plan.paths))


def format_timed(plan: Plan, *, xy: bool = True) -> str:
    out = []
    for i, path in enumerate(plan.paths):
        last = len(path) - 1
        points = []
        for t, (r, c) in enumerate(path):
            if t == 0 or t == last or path[t - 1] != (r, c):
                r, c = int(r), int(c)
                points.append(f"({c},{r},{t})->" if xy else f"({r},{c},{t})->")
        out.append(f"Agent {i}:" + "".join(points) + "\n")
    return "".join(out)
