"""Errand tasks: lists of cells that one AGV visits in order (``orders.pattern: errands``).

This is the work of a League of Robot Runners problem (:mod:`warerover_phys.problems.
robotrunners`) and of a MovingAI map with a task stream. A task becomes an
:class:`~warerover_phys.orders.Order` with ``errands`` set; the world runs it as a trip
whose stops are the errand cells (AGV state ``ERRAND``), and the ``errands`` scheduler
assigns the tasks by the rule in :class:`~warerover_phys.config.ErrandsSpec`.

Tasks are released by the rule, not by the clock (:meth:`ErrandStream.arrivals`):

- ``roundrobin``: one task for every free AGV, AGV ``i`` getting task ids ``i``, ``i + n``,
  ``i + 2n``, ... (the order names the AGV: ``for_agv``);
- ``greedy``: one task for every free AGV, the next ids of the list;
- ``pool``: ``max(1, int(reveal x n))`` at the first tick, then as many as were finished, so
  that as many tasks are open or under way as at the start.

Task ``k`` has the errands of the list's ``k mod len(list)``-th task (the list wraps
around). Random tasks (no list) are drawn when released, with the orders generator: the
number of errands uniformly in ``errands_per_task``, each cell uniformly over the cells an
AGV of the fleet can stand on.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..config import ErrandsSpec
from ..errors import ScenarioError
from ..orders import Order

__all__ = ["ErrandStream", "read_task_file", "read_numbers", "read_text", "check_cell", "MAX_TASKS"]

MAX_TASKS = 10_000_000
"""Most tasks a task file may list."""


MAX_FILE_BYTES = 512 * 2**20
"""Largest agent or task file read (bytes)."""


def read_text(path: Path, what: str, source: str, limit: int = MAX_FILE_BYTES) -> str:
    """The UTF-8 text of a regular file of at most ``limit`` bytes (a device, a FIFO or a
    folder is refused before it is opened), else a :class:`ScenarioError` naming it."""
    import stat

    try:
        st = path.stat()
    except FileNotFoundError:
        raise ScenarioError(f"{what} file not found", file=source, field=what,
                            value=str(path)) from None
    except OSError as e:
        raise ScenarioError(f"cannot read the {what} file: {e.strerror}", file=source,
                            field=what, value=str(path)) from None
    if not stat.S_ISREG(st.st_mode):
        from ..inputs import describe

        raise ScenarioError(f"the {what} is {describe(path)}, not a regular file", file=source,
                            field=what, value=str(path))
    try:
        with open(path, "rb") as f:
            data = f.read(limit + 1)
    except OSError as e:
        raise ScenarioError(f"cannot read the {what} file: {e.strerror}", file=source,
                            field=what, value=str(path)) from None
    if len(data) > limit:
        raise ScenarioError(f"the {what} file is larger than {limit // 2**20} MiB",
                            file=source, field=what, value=str(path))
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise ScenarioError(f"the {what} file is not UTF-8 text", file=source, field=what,
                            value=str(path)) from None


def read_numbers(path: Path, what: str, source: str) -> tuple[str | None, list[str]]:
    """(``# version`` comment, the entry lines after the count) of a Robot Runners agent or
    task file; every failure a :class:`ScenarioError` naming the file and the field."""
    text = read_text(path, what, source)
    version = None
    body = []
    for ln in text.splitlines():
        ln = ln.strip()
        if ln.startswith("#"):
            version = version or ln.lstrip("# ").strip()
        elif ln:
            body.append(ln)
    if not body:
        raise ScenarioError(f"{what} file is empty", file=str(path), field="count")
    try:
        count = int(body[0])
    except ValueError:
        raise ScenarioError(f"the first line of the {what} file must be a count",
                            file=str(path), field="count", value=body[0]) from None
    if count < 0 or len(body) - 1 < count:
        raise ScenarioError(f"{what} file says {count} entries but has {len(body) - 1}",
                            file=str(path), field="count", value=count)
    return version, body[1:count + 1]


def read_task_file(path: Path, free: np.ndarray, source: str
                   ) -> tuple[str | None, list[tuple[int, ...]]]:
    """The tasks of a Robot Runners task file: each its errands' linearised cells (checked
    against ``free``, the flat mask of cells an AGV may stand on)."""
    version, lines = read_numbers(path, "taskFile", source)
    if len(lines) > MAX_TASKS:
        raise ScenarioError(f"more than {MAX_TASKS} tasks", file=str(path), field="count",
                            value=len(lines))
    tasks = []
    for k, ln in enumerate(lines):
        errands = tuple(check_cell(x.strip(), free, path, f"task {k}")
                        for x in ln.split(",") if x.strip())
        if not errands:
            raise ScenarioError("a task needs at least one errand", file=str(path),
                                field=f"task {k}", value=ln)
        tasks.append(errands)
    if not tasks:
        raise ScenarioError("no tasks", file=str(path), field="count", value=0)
    return version, tasks


def check_cell(text: str, free: np.ndarray, file: Path, fld: str, cols: int | None = None
               ) -> int:
    """A linearised cell ``row * width + col`` read from ``text``: on the map and free."""
    try:
        v = int(text)
    except ValueError:
        raise ScenarioError("expected a linearised cell (row * width + column)", file=str(file),
                            field=fld, value=text) from None
    if not 0 <= v < len(free):
        raise ScenarioError(f"cell off the map ({len(free)} cells)", file=str(file), field=fld,
                            value=v)
    if not free[v]:
        raise ScenarioError("the cell is an obstacle", file=str(file), field=fld, value=v)
    return v


class ErrandStream:
    """The errand tasks of one episode, released by the rule (see the module docstring).

    ``free``: flat mask of the cells an AGV may stand on (errand cells are checked against
    it and random ones drawn from it); ``agvs``: the fleet size; ``rng``: the orders
    generator (random tasks only)."""

    def __init__(self, spec: ErrandsSpec, cols: int, free: np.ndarray, agvs: int,
                 rng: np.random.Generator, base: Path, source: str | None) -> None:
        self.spec = spec
        self.cols = cols
        self.n = agvs
        self.rng = rng
        self.version: str | None = None
        self.tasks: list[tuple[int, ...]] | None = None
        if spec.file is not None:
            path = Path(spec.file)
            path = path if path.is_absolute() else base / path
            self.version, self.tasks = read_task_file(path, free, source or str(path))
        elif spec.tasks is not None:
            rows = len(free) // cols
            self.tasks = []
            for k, task in enumerate(spec.tasks):
                nodes = []
                for j, (r, c) in enumerate(task):
                    if not (0 <= r < rows and 0 <= c < cols and free[r * cols + c]):
                        raise ScenarioError("errand cell off the floor or blocked",
                                            file=source, field=f"orders.errands.tasks[{k}][{j}]",
                                            value=[r, c])
                    nodes.append(r * cols + c)
                self.tasks.append(tuple(nodes))
        else:
            self._cells = np.flatnonzero(free)
            if len(self._cells) == 0:
                raise ScenarioError("no free cell to draw errands on", file=source,
                                    field="orders.errands")
        self.next_task = 0
        """``greedy`` and ``pool``: the next task id to release."""
        self.rr_next = list(range(agvs))
        """``roundrobin``: each AGV's next task id."""
        self.released = 0

    def task(self, k: int) -> tuple[int, ...]:
        """Errands of task ``k`` (listed tasks wrap around; random ones are drawn when
        released, see :meth:`_order`)."""
        assert self.tasks is not None
        return self.tasks[k % len(self.tasks)]

    def _order(self, k: int, tick: int, agv: int | None = None) -> Order:
        if self.tasks is not None:
            errands = self.task(k)
        else:
            lo, hi = self.spec.errands_per_task
            m = int(self.rng.integers(lo, hi + 1))
            errands = tuple(int(x) for x in self.rng.choice(self._cells, size=m))
        self.released += 1
        return Order(id=k, tick=tick, sku=-1, station=-1, size=1, errands=errands,
                     for_agv=agv)

    def arrivals(self, tick: int, idle: Sequence[int], unfinished: int) -> list[Order]:
        """Tasks released at ``tick``: ``idle`` lists the free AGVs (id order), ``unfinished``
        counts the tasks released and not yet finished."""
        rule = self.spec.assign
        if rule == "roundrobin":
            out = []
            for i in idle:
                out.append(self._order(self.rr_next[i], tick, i))
                self.rr_next[i] += self.n
            return out
        if rule == "greedy":
            count = len(idle)
        else:
            target = max(1, int(self.spec.reveal * self.n))
            count = max(0, target - unfinished)
        out = [self._order(self.next_task + j, tick) for j in range(count)]
        self.next_task += count
        return out

    def exhausted(self, tick: int) -> bool:
        """Never: tasks come for as long as the episode runs (``max_ticks``)."""
        return False
