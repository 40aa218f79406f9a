"""A pytest plugin that records each test's CPU time (setup + call + teardown: the process's
own user + sys time and that of the subprocesses it waited for), a figure the machine's
load does not change much, unlike the wall clock of ``--durations``.

    PYTHONPATH=tools PYTEST_CPU_OUT=build/cpu pytest -p pytest_cpu ...

writes one ``<worker>.jsonl`` per xdist worker (``main.jsonl`` without xdist) in
``PYTEST_CPU_OUT``: ``{"test": nodeid, "cpu_s": ..., "wall_s": ...}`` per line.
``tools/test_time.py`` reads them.
"""

from __future__ import annotations

import json
import os
import resource
import time
from pathlib import Path

import pytest


def _cpu() -> float:
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    out = os.environ.get("PYTEST_CPU_OUT")
    c0, t0 = _cpu(), time.monotonic()
    yield
    if not out:
        return
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    path = Path(out) / f"{worker}.jsonl"
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a") as f:
        f.write(json.dumps({"test": item.nodeid, "cpu_s": round(_cpu() - c0, 3),
                            "wall_s": round(time.monotonic() - t0, 3)}) + "\n")
