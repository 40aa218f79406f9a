"""Python's garbage collector during the long simulation loops.

A run at 1,000 AGVs keeps a large, long-lived object graph (the action dependency graph's
actions, visits and queues, trajectories, event lists) while it allocates many short-lived
containers per physics step. At the interpreter's default thresholds (700, 10, 10) the
collector runs thousands of times per run and every few hundred of those traverses the
whole long-lived graph. Measured on the 1,000-agent lacam3 plan of ``tools/bench_execute.py``
(dt 0.02 s, 1,572 ticks, the same box and commit): 2,052 young, 187 middle and 10 full
collections, 64.7 and 67.8 s of execution; with :data:`LOOP_THRESHOLDS`, 146 young, 7 middle
and no full collection, 57.5 s. Nothing is kept longer than at the defaults except garbage
in reference cycles, which waits for the later thresholds (or for the defaults again after
the loop).

:func:`long_loop` raises the thresholds for the duration of a loop (``execute_plan``,
``Simulation.run``) and restores what they were; it changes no result.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["LOOP_THRESHOLDS", "long_loop"]

LOOP_THRESHOLDS = (10_000, 20, 100)
"""Collector thresholds (:func:`gc.set_threshold`) inside :func:`long_loop`: a young
collection every 10,000 net allocations of containers instead of 700, older generations
less often."""


@contextmanager
def long_loop() -> Iterator[None]:
    """Run the body with :data:`LOOP_THRESHOLDS` (never lower than the thresholds in
    force), then restore the thresholds in force before."""
    old = gc.get_threshold()
    gc.set_threshold(*(max(a, b) for a, b in zip(old, LOOP_THRESHOLDS, strict=False)))
    try:
        yield
    finally:
        gc.set_threshold(*old)
