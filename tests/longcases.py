"""Which cases of a long matrix run in ``make test`` and which only in ``make test-all``.

``make test`` is the first signal (a few minutes on two cores, see ``docs/testing.md``);
``make test-all`` (what CI runs) adds every test marked ``slow``. A parametrized test over
many seeds, scenarios or patterns keeps its first cases in the default set and moves the
rest to the slow set: no case is dropped, each still runs in CI.

Single cases picked by their measured time are listed in ``slow_cases.txt`` beside this
file (``tools/test_time.py`` measures them): ``tests/conftest.py`` marks each listed case
``slow`` at collection, so a test file need not change to move one of its cases.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import pytest

SLOW_CASES = Path(__file__).with_name("slow_cases.txt")


def slow_after(n: int, values: Iterable) -> list:
    """``values`` for ``pytest.mark.parametrize``: the first ``n`` plain (the default set),
    the others marked ``slow`` (``make test-all``). A tuple value is a case of several
    arguments, as ``parametrize`` takes it."""
    out = []
    for i, v in enumerate(values):
        if i < n:
            out.append(v)
        else:
            args = v if isinstance(v, tuple) else (v,)
            out.append(pytest.param(*args, marks=pytest.mark.slow))
    return out


def slow_cases(path: Path = SLOW_CASES) -> dict[str, str]:
    """``{node id: reason}`` from ``slow_cases.txt``: one case a line, ``NODE_ID  # reason``
    (the node id as ``pytest --collect-only -q`` prints it); blank lines and lines starting
    with ``#`` are left out. A line without a reason is an error."""
    cases: dict[str, str] = {}
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip() or line.startswith("#"):
            continue
        node, sep, reason = line.partition("  # ")
        if not sep or not reason.strip() or not node.strip():
            raise ValueError(f"{path.name}:{n}: expected 'NODE_ID  # reason', got {line!r}")
        if node.strip() in cases:
            raise ValueError(f"{path.name}:{n}: {node.strip()} listed twice")
        cases[node.strip()] = reason.strip()
    return cases


def mark_slow_cases(items: list, cases: dict[str, str]) -> int:
    """Mark every collected item whose node id is listed ``slow``; how many were marked."""
    marked = 0
    for item in items:
        if item.nodeid in cases:
            item.add_marker(pytest.mark.slow)
            marked += 1
    return marked
