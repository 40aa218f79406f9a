"""Plan files of the field, read and written.

Every reader returns a :class:`~warerover_phys.plans.model.Plan` in the project's convention
(cells ``(row, col)``, row 0 at the top, one entry per timestep, a wait repeats the cell);
every writer takes one. Malformed input raises :class:`~warerover_phys.errors.PlanFormatError`
and nothing else; its message is one line naming the file, the line or JSON key, and at most
about 80 characters of the offending text.

=============  ==========================  ====================  =============================
format         written by                  coordinates           waits
=============  ==========================  ====================  =============================
lacam          LaCAM, lacam3, MAPF         ``(x, y)``,           a line per timestep, every
               visualizer, ``warerover     x = column            agent on every line
               solve --out``
lns            MAPF-LNS2, EECBS, SMART     ``(row, col)``        list index = timestep, a wait
                                                                 repeats the cell
timed          SMART                       ``(x, y, t)``,        a gap in t = waiting at the
                                           ``xy=False``:         previous point
                                           ``(row, col, t)``
robotrunners   League of Robot Runners     ``start`` is          ``W`` / ``T`` actions; ``R``
               start-kit (output JSON;     ``[row, col, hdg]``   / ``C`` turns take a timestep
               2026 segmented paths                              (2026: ``agentMaxCounter``
               read too)                                         ticks per action)
paths_json     ``warerover run``           ``[row, col]``        one state per tick
               (``paths.json``)            anchors
=============  ==========================  ====================  =============================

Example lines (more in each format's module)::

    lacam         3:(12,4),(7,30),          agents 0 and 1 at (row 4, col 12), (row 30, col 7)
    lns           Agent 0:(4,12)->(4,13)->(4,13)->
    timed         Agent 0:(12,4,0)->(13,4,1)->(13,5,4)->
    robotrunners  "start": [[4, 12, "E"]], "actualPaths": ["F,R,W,F"]
    paths_json    "actual": {"0": [[[4, 12], [4, 12]], [[4, 12], [4, 13]], [[4, 13], [4, 13]]]}

Sizes are bounded so that no file can make the reader allocate absurd amounts: files over
512 MB, numbers over 9,999,999, timesteps over 1,000,000 and plans over 20,000,000 cells
(agents x timesteps) are refused. Reading is linear in the file size (1,000 agents x 1,000 timesteps: see
``tools/bench_plans.py``).

>>> plan = parse_plan("agents=1\\nsolution=\\n0:(3,1),\\n1:(4,1),\\n")
>>> plan.paths, plan.fmt
((((1, 3), (1, 4)),), 'lacam')
>>> print(format_plan(plan, "lns"), end="")
Agent 0:(1,3)->(1,4)->
"""

from __future__ import annotations

import gc
import json
import os
import re
from contextlib import contextmanager
from pathlib import Path

from ..errors import PlanFormatError, ScenarioError
from . import agentlines, lacam, pathsjson, robotrunners
from ._common import MAX_COORD, MAX_FILE_BYTES, excerpt, fail
from .model import Plan

__all__ = ["FORMATS", "detect_format", "parse_plan", "read_plan", "format_plan", "write_plan"]

FORMATS: tuple[str, ...] = ("lacam", "lns", "timed", "robotrunners", "paths_json")

_SAFETY_NET = True
"""Turn an unexpected exception inside a reader into a PlanFormatError (tests switch it off
to see reader bugs)."""

_AGENT_LINE = re.compile(r"Agent\s*\d+\s*:\s*\(([^()]*)\)", re.ASCII)
_LACAM_FIRST = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-]*\s*=|\d+\s*:\s*\(", re.ASCII)


@contextmanager
def _gc_paused():
    """Pause the cyclic garbage collector while a reader builds millions of tuples that hold
    no cycles (it would otherwise scan them again and again); restored on exit."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def check_format(fmt: str, option: str = "--format") -> str:
    """``fmt`` if it is a plan format, else a :class:`PlanFormatError` naming ``option``
    (for a command line option, checked before any work)."""
    if fmt not in FORMATS:
        raise PlanFormatError(f"unknown plan format (known: {', '.join(FORMATS)})",
                              file="<arguments>", field=option, value=fmt)
    return fmt


def _check_fmt(fmt: str) -> None:
    if fmt not in FORMATS:
        raise PlanFormatError(f"unknown plan format (known: {', '.join(FORMATS)})",
                              field="fmt", file="<arguments>", value=fmt)


def _load_json(text: str, source: str) -> dict:
    try:
        data = json.loads(text)
    except json.JSONDecodeError as err:
        fail(source, f"line {err.lineno}", f"not valid JSON: {err.msg}",
             text[err.pos:err.pos + 40] or "end of file")
    except (ValueError, RecursionError) as err:
        fail(source, None, f"not valid JSON: {excerpt(err)}")
    if type(data) is not dict:
        fail(source, None, "expected a JSON object", type(data).__name__)
    return data


def _json_format(data: dict, source: str) -> str:
    if any(k in data for k in ("actualPaths", "plannerPaths", "teamSize")):
        return "robotrunners"
    if "planned" in data or "actual" in data:
        return "paths_json"
    fail(source, None, "a JSON object with neither actualPaths (Robot Runners) nor "
         "planned / actual (paths.json)", ", ".join(list(data)[:8]))


def _detect(text: str, source: str) -> tuple[str, dict | None]:
    if "\x00" in text:
        fail(source, None, "binary data (NUL bytes), not a plan file")
    stripped = text.lstrip("\ufeff \t\r\n")
    if not stripped:
        fail(source, None, "empty file")
    if stripped[0] in "{[":
        data = _load_json(stripped, source)
        return _json_format(data, source), data
    first = stripped.split("\n", 1)[0].strip()
    line_no = text[: len(text) - len(stripped)].count("\n") + 1
    m = _AGENT_LINE.match(first)
    if m is not None:
        commas = m.group(1).count(",")
        if commas in (1, 2):
            return ("lns" if commas == 1 else "timed"), None
        fail(source, f"line {line_no}", "cannot tell lns (row,col) from timed (x,y,t)", first)
    if _LACAM_FIRST.match(first):
        return "lacam", None
    fail(source, f"line {line_no}", "not a known plan format (expected 'key=value' (lacam), "
         "'Agent 0:(...)' (lns, timed) or a JSON object)", first)


def detect_format(text: str, *, source: str = "<string>") -> str:
    """The format of a plan file's ``text``, from its content.

    >>> detect_format("Agent 0:(1,2)->(1,3)->")
    'lns'
    """
    try:
        return _detect(text, source)[0]
    except PlanFormatError:
        raise
    except Exception as err:  # noqa: BLE001 - the promise: only PlanFormatError
        if not _SAFETY_NET:
            raise
        fail(source, None, f"unreadable plan ({type(err).__name__}: {excerpt(err)})")


def parse_plan(text: str, fmt: str | None = None, *, source: str = "<string>", xy: bool = True,
               which: str = "actual", cols: int | None = None) -> Plan:
    """Read a plan from ``text``; ``fmt=None`` detects the format.

    ``xy`` (``timed`` only): ``True`` if points are ``(x = column, y = row, t)``, ``False`` if
    ``(row, col, t)``. ``which`` (``robotrunners``, ``paths_json``): ``"actual"`` (executed)
    or ``"planner"`` paths. ``cols`` (``paths_json`` with flat node indices): map width.
    """
    if fmt is not None:
        _check_fmt(fmt)
    if which not in ("actual", "planner"):
        raise PlanFormatError("must be 'actual' or 'planner'", field="which", file="<arguments>",
                              value=which)
    if len(text) > MAX_FILE_BYTES:
        fail(source, None, f"text too large ({len(text)} characters; max {MAX_FILE_BYTES})")
    with _gc_paused():
        return _parse(text, fmt, source, xy, which, cols)


def _parse(text: str, fmt: str | None, source: str, xy: bool, which: str,
           cols: int | None) -> Plan:
    try:
        data = None
        if fmt is None:
            fmt, data = _detect(text, source)
        elif "\x00" in text:
            fail(source, None, "binary data (NUL bytes), not a plan file")
        if fmt == "lacam":
            return lacam.parse(text.lstrip("\ufeff"), source)
        if fmt == "lns":
            return agentlines.parse_lns(text.lstrip("\ufeff"), source)
        if fmt == "timed":
            return agentlines.parse_timed(text.lstrip("\ufeff"), source, xy=xy)
        if data is None:
            if not text.strip():
                fail(source, None, "empty file")
            data = _load_json(text.lstrip("\ufeff"), source)
        if fmt == "robotrunners":
            return robotrunners.parse(data, source, which=which)
        return pathsjson.parse(data, source, which=which, cols=cols)
    except PlanFormatError:
        raise
    except Exception as err:  # noqa: BLE001 - the promise: only PlanFormatError
        if not _SAFETY_NET:
            raise
        fail(source, None, f"unreadable plan ({type(err).__name__}: {excerpt(err)})")


def _decode(data: bytes, source: str) -> str:
    nul = data.find(b"\x00")
    if nul >= 0:
        fail(source, f"byte {nul}", "binary data (NUL bytes), not a plan file")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        fail(source, f"byte {err.start}", "not UTF-8 text (a binary file?)",
             repr(data[err.start:err.start + 16]))


def read_plan(path: str | Path, fmt: str | None = None, *, xy: bool = True,
              which: str = "actual", cols: int | None = None) -> Plan:
    """Read the plan file at ``path`` (see :func:`parse_plan` for the options)."""
    source = str(path)
    p = Path(path)
    from ..inputs import check_regular_file

    try:
        check_regular_file(p, "plan")  # not a FIFO nor a device: they would never end
    except ScenarioError as err:
        fail(source, None, err.message)
    try:
        with open(p, "rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)
    except OSError as err:
        fail(source, None, f"cannot read: {err.strerror or err}")
    if len(data) > MAX_FILE_BYTES:
        fail(source, None, f"file too large (more than {MAX_FILE_BYTES} bytes)")
    return parse_plan(_decode(data, source), fmt, source=source, xy=xy, which=which, cols=cols)


def _check_cells(plan: Plan, source: str) -> None:
    for i, path in enumerate(plan.paths):
        for t, cell in enumerate(path):
            if len(cell) != 2:
                fail(source, f"paths[{i}][{t}]", "a cell is (row, col)", cell)
            r, c = cell
            if not (isinstance(r, int) and isinstance(c, int)):
                try:
                    ok = int(r) == r and int(c) == c
                except (TypeError, ValueError, OverflowError):
                    ok = False
                if not ok:
                    fail(source, f"paths[{i}][{t}]", "cells must be integers", cell)
            if not (0 <= r <= MAX_COORD and 0 <= c <= MAX_COORD):
                fail(source, f"paths[{i}][{t}]", f"cells must be in 0..{MAX_COORD}", cell)


def format_plan(plan: Plan, fmt: str, *, xy: bool = True) -> str:
    """The text of ``plan`` in format ``fmt`` (see :func:`parse_plan` for ``xy``).

    Formats keep what they can carry: ``lns`` and ``timed`` only the cells, ``lacam`` also
    the map name and size and scalar ``meta`` entries, the JSON formats all JSON-safe
    ``meta``. A plan a format cannot express raises :class:`PlanFormatError`.
    """
    _check_fmt(fmt)
    source = "<plan>"
    _check_cells(plan, source)
    if fmt in ("lns", "timed") and not plan.num_agents:
        fail(source, "paths", f"{fmt} cannot hold a plan with no agents (its file would be "
             "empty)")
    if fmt == "lacam":
        return lacam.format_plan(plan, source)
    if fmt == "lns":
        return agentlines.format_lns(plan)
    if fmt == "timed":
        return agentlines.format_timed(plan, xy=xy)
    if fmt == "robotrunners":
        return robotrunners.format_plan(plan, source)
    return pathsjson.format_plan(plan, source)


def write_plan(plan: Plan, path: str | Path, fmt: str, *, xy: bool = True) -> None:
    """Write ``plan`` to ``path`` in format ``fmt``, atomically (a temporary file in the same
    folder, then :func:`os.replace`), so a failed write never leaves half a file."""
    text = format_plan(plan, fmt, xy=xy)
    p = Path(path)
    tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8", newline="\n") as f:
            f.write(text)
        os.replace(tmp, p)
    finally:
        if tmp.exists():
            tmp.unlink()
