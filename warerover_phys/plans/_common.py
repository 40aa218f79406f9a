"""Shared helpers of the plan readers: errors, limits, excerpts of bad input."""

from __future__ import annotations

import math
import re
from typing import Any, NoReturn

from ..errors import PlanFormatError

MAX_FILE_BYTES = 512 * 1024 * 1024
"""Files larger than this are refused before reading."""
MAX_COORD = 9_999_999
"""Largest row / column / flat node accepted (numbers have at most 7 digits)."""
MAX_TIMESTEP = 1_000_000
"""Largest timestep a file may name (timed points, paths.json ticks)."""
MAX_CELLS = 20_000_000
"""Largest number of (agent, timestep) entries a file may expand to."""
MAX_AGENTS = 100_000
"""Most agents a plan may have (counted before their cells are parsed)."""
EXCERPT = 80

_NUM = r"\d{1,7}"


def excerpt(text: Any) -> str:
    """At most :data:`EXCERPT` characters of ``text`` (for error messages)."""
    text = str(text)
    return text if len(text) <= EXCERPT else text[: EXCERPT - 3] + "..."


def fail(source: str, where: str | None, message: str, bad: Any = None) -> NoReturn:
    """Raise the one-line :class:`PlanFormatError` every reader raises."""
    if bad is None:
        raise PlanFormatError(message, file=source, field=where)
    raise PlanFormatError(message, file=source, field=where, value=excerpt(bad))


def tuple_pattern(n: int) -> str:
    """Regex of one ``(a,b)`` / ``(a,b,c)`` tuple of small non-negative integers."""
    inner = r"\s*,\s*".join([_NUM] * n)
    return r"\(\s*" + inner + r"\s*\)"


_ANY_TUPLE = re.compile(r"\(([^()]*)\)?")
_INT_TOKEN = re.compile(r"\s*([+-]?\d+)\s*")


def diagnose(body: str, n: int, sep: str) -> tuple[str, str]:
    """Why ``body`` (a list of ``n``-tuples separated by ``sep``) did not match: the message
    and the text from the first bad spot on. Slow; only used to explain an error."""
    pos = 0
    while True:
        while pos < len(body) and body[pos].isspace():
            pos += 1
        if pos >= len(body):
            return "malformed list", body
        rest = body[pos:]
        if body[pos] != "(":
            return f"expected '(' of a {n}-number tuple", rest
        m = _ANY_TUPLE.match(body, pos)
        if m is None or m.group(0)[-1] != ")":
            return "unclosed tuple (truncated line?)", rest
        parts = m.group(1).split(",")
        if len(parts) != n:
            return f"expected {n} numbers in a tuple, found {len(parts)}", rest
        for part in parts:
            t = _INT_TOKEN.fullmatch(part)
            if t is None:
                return "not an integer", rest
            if t.group(1).startswith("-"):
                return "negative coordinate", rest
            if len(t.group(1).lstrip("+")) > 7:
                return f"number too large (max {MAX_COORD})", rest
            if t.group(1).startswith("+"):
                return "unexpected '+' sign", rest
        pos = m.end()
        while pos < len(body) and body[pos].isspace():
            pos += 1
        if pos >= len(body):
            return "malformed list", rest
        if body.startswith(sep, pos):
            pos += len(sep)
            continue
        return f"expected '{sep}' between tuples", body[pos:]


_UNWRAP = str.maketrans("()", "  ")


def ints_of(body: str, sep: str) -> list[int]:
    """The integers of a list of tuples that already matched its pattern (fast)."""
    if sep != ",":
        body = body.replace(sep, ",")  # the pattern allows no other use of sep
    parts = body.translate(_UNWRAP).split(",")
    if not parts[-1].strip():
        parts.pop()
    return list(map(int, parts))


_INT_TEXT = re.compile(r"[+-]?\d{1,18}")
_FLOAT_TEXT = re.compile(r"[+-]?(\d+\.\d*|\.\d+|\d+)([eE][+-]?\d{1,3})?")


def scalar(text: str) -> int | float | str:
    """A header value as int, finite float or the string itself (JSON-safe)."""
    if _INT_TEXT.fullmatch(text):
        return int(text)
    if _FLOAT_TEXT.fullmatch(text):
        value = float(text)
        if math.isfinite(value):
            return value
    return text


def check_int(value: Any, source: str, where: str, *, low: int = 0,
              high: int = MAX_COORD, what: str = "integer") -> int:
    """``value`` if it is a JSON integer in ``[low, high]``, else a PlanFormatError."""
    if type(value) is not int:
        fail(source, where, f"expected {what}, an integer", value)
    if value < low:
        fail(source, where, f"{what} must be at least {low}", value)
    if value > high:
        fail(source, where, f"{what} too large (max {high})", value)
    return value
