"""Which cases of a long matrix run in ``make test`` and which only in ``make test-all``.

``make test`` is the first signal (a few minutes on two cores, see ``docs/testing.md``);
``make test-all`` (what CI runs) adds every test marked ``slow``. A parametrized test over
many seeds, scenarios or patterns keeps its first cases in the default set and moves the
rest to the slow set: no case is dropped, each still runs in CI.
"""

from __future__ import annotations

from collections.abc import Iterable

import pytest


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
