"""Wall-clock guards of a study's tasks: a plan that takes longer than its solver's limit
allows, or a cell whose execution runs on, becomes a row with status ``timeout`` instead of
holding a worker for as long as it likes.

A guard is a deadline on the wall clock. Inside it, :meth:`WallGuard.check` raises
:class:`CellTimeout` once the deadline has passed (the execution loop calls it every tick);
in a process's main thread (a pool or Ray worker) an interval timer (``SIGALRM``) also
raises it in whatever Python code runs then, and again every second until the guard ends
(an exception swallowed by a C callback is raised again), except while a module is
being imported or numba compiles or loads a kernel (cut short, they would leave the worker
with half-made process-wide state: the alarm waits for the next second). Compiled code that never returns
to Python is not interrupted: the solvers' own time limits bound it.

>>> with wall_guard(5.0, "solve") as g:
...     g.check()  # well within 5 s
"""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Iterator
from typing import Any

__all__ = ["CellTimeout", "WallGuard", "wall_guard"]


class CellTimeout(Exception):  # noqa: N818 - a row's status, not an error of the code
    """The wall-clock guard of a plan or a cell ran out."""

    def __init__(self, what: str, limit_s: float) -> None:
        super().__init__(f"{what} still running after {limit_s:g} s of wall clock "
                         "(the study's guard stopped it)")
        self.what = what
        self.limit_s = limit_s


class WallGuard:
    """A deadline: :meth:`check` raises :class:`CellTimeout` once it has passed."""

    def __init__(self, limit_s: float | None, what: str) -> None:
        self.limit_s = limit_s
        self.what = what
        self.deadline = None if limit_s is None else time.perf_counter() + limit_s

    def expired(self) -> bool:
        return self.deadline is not None and time.perf_counter() >= self.deadline

    def timeout(self) -> CellTimeout:
        return CellTimeout(self.what, self.limit_s or 0.0)

    @property
    def error(self) -> str:
        """The row's error text of a timeout."""
        return str(self.timeout())

    def check(self, *_: object) -> None:
        """Raise :class:`CellTimeout` if the deadline has passed (any arguments are
        ignored: it serves as a progress callback)."""
        if self.expired():
            raise self.timeout()

    def stopped(self, err: BaseException) -> bool:
        """Whether ``err`` is this guard's doing: a :class:`CellTimeout`, one wrapped in
        another error (a plugin constructor's, a reader's), or any error once the deadline
        has passed."""
        seen: BaseException | None = err
        while seen is not None:
            if isinstance(seen, CellTimeout):
                return True
            seen = seen.__cause__ or seen.__context__
        return self.expired() or "CellTimeout" in str(err)


_UNSAFE = ("<frozen importlib", "/numba/", "/llvmlite/")
"""Code an exception must not cut short (the import machinery, numba's compiler and cache):
it keeps process-wide state that a later task would find half-made."""


def _importing(frame: Any) -> bool:
    """Whether ``frame`` or a caller of it is code of :data:`_UNSAFE` (the alarm waits
    for the next second then)."""
    while frame is not None:
        name = frame.f_code.co_filename
        if any(u in name if u[0] == "/" else name.startswith(u) for u in _UNSAFE):
            return True
        frame = frame.f_back
    return False


@contextlib.contextmanager
def wall_guard(guard: WallGuard | float | None, what: str = "the task",
               ) -> Iterator[WallGuard]:
    """``guard`` (or a new :class:`WallGuard` of ``guard`` seconds, None: no limit, counted
    from now) for the ``with`` block; in the main thread the block is also interrupted by
    ``SIGALRM`` at the deadline."""
    if not isinstance(guard, WallGuard):
        guard = WallGuard(guard, what)
    limit_s = guard.limit_s if guard.deadline is None else guard.deadline - time.perf_counter()
    timer = (guard.deadline is not None and hasattr(signal, "setitimer")
             and threading.current_thread() is threading.main_thread())
    if not timer:
        yield guard
        return

    def alarm(signum: int, frame: Any) -> None:
        if not _importing(frame):  # an import cut short would poison the worker's modules
            guard.check()

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, max(limit_s, 1e-3), 1.0)
    try:
        yield guard
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
