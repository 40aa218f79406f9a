"""League of Robot Runners problems: read them, run them lifelong, write the output JSON.

**Problems** (:func:`read_problem`): the start-kit's problem JSON names a map (MovingAI grid,
``E`` emitters and ``S`` service points free), an agent file (count, then one linearised
start ``row * width + col`` per line; the first ``teamSize`` are used) and a task file (count,
then one task per line: its errands' linearised cells, visited in order by one robot; one
errand in 2023, two or three later). ``numTasksReveal`` is, in 2023 files (with a
``taskAssignmentStrategy``), the tasks each robot knows ahead; in 2024 and later files
(``version``), a multiplier: ``numTasksReveal * teamSize`` open tasks are kept in a pool and
refilled as tasks finish. ``agentCounter`` and ``delayConfig`` (2026) are read and reported;
this runner does not model them (one action per timestep, no injected delays).

**Runs** (:func:`run_lifelong`): every timestep, free robots take tasks (2023 ``greedy``: the
next task of the file; ``roundrobin``: task ``k`` goes to robot ``k mod teamSize``; 2024 and
later: each free robot takes the open task whose first errand is nearest, robots in id
order), then one PIBT step (with swaps) moves every robot one cell towards its current
errand. With rotations (the league's ``MAPF_T`` model, the default) a robot faces one of
four headings and each timestep either moves one cell forward, turns a quarter (``R``
clockwise, ``C`` counter-clockwise) or waits. Two rules meet that model (``rule``):
``actions`` (default) runs PIBT over those actions, ranked by the cost-to-go of the cell and
heading each leads to, so a robot can only be pushed forward and one that is pushed but
cannot move turns towards a way out (:mod:`.planning.pibt_heading`); ``turn-first`` runs
PIBT on cells, ranking a robot's neighbouring cells by distance to its errand plus the
quarter turns needed to face them, a robot whose PIBT cell lies in another direction turns
towards it instead, and robots that were to move into the cell of a robot that does not
leave it wait too. On ``warehouse_small`` (2023) over 300 timesteps ``actions`` finishes
more tasks up to 200 robots and ``turn-first`` more at 400 (``tools/README.md``); both jam
at high density. Robots start facing east. A robot that stands on its
current errand's cell has done it (any heading); the task is finished with its last errand.
The steps run compiled with numba (:mod:`.planning.pibt_numba`, ``engine``), with the same
plans as the Python steps of :mod:`.planning.pibt` and :mod:`.planning.pibt_heading`, which
stay the reference (``engine="python"``). Robots' distance tables come from one store per
run, one table per goal cell, least recently used evicted under a MiB budget
(:mod:`.planning.dist_store`); with ``trace_dir``
the actions go to disk in chunks instead of lists, and :func:`write_output_json` streams
them into the output, so memory does not grow with the timesteps.

**Output** (:func:`output_json`), the start-kit's 2024 fields: ``actionModel`` (``MAPF_T``;
without rotations ``MAPF``, a model of ours: ``U`` / ``D`` / ``L`` / ``R`` move one cell up
(-row), down, left (-col) or right and ``W`` waits), ``version``, ``teamSize``, ``start`` (``[row, col, heading]``), ``numTaskFinished``, ``sumOfCost``
and ``makespan`` (the sum and the largest of the timesteps each robot held a task),
``actualPaths`` and ``plannerPaths`` (the same here: every planned action is executed),
``plannerTimes`` (seconds per timestep), ``errors`` (always empty: plans are valid by
construction and checked), ``events`` and ``tasks`` (in the 2023 kit's form for 2023
problems, the 2024 kit's otherwise) and ``actualSchedule``: :mod:`.lorr_fields` computes
them and says which kit version each follows. :func:`warerover_phys.plans.read_plan` reads both back (format
``robotrunners``).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ScenarioError
from .movingai import MovingAIMap, read_map

__all__ = ["LorrProblem", "LorrResult", "read_problem", "run_lifelong", "output_json",
           "write_output_json", "ActionChunks", "HEADINGS", "RULES", "ENGINES"]

HEADINGS = "ESWN"
"""Heading codes 0-3: east (+col), south (+row), west (-col), north (-row)."""
_STEP = ((0, 1), (1, 0), (0, -1), (-1, 0))
_MOVE_LETTER = {(0, 1): "R", (1, 0): "D", (0, -1): "L", (-1, 0): "U"}
RULES = ("actions", "turn-first")
"""How PIBT meets the rotation model (see the module docstring)."""
MAX_AGENTS = 100_000
MAX_TASKS = 10_000_000
MAX_FILE_BYTES = 256 * 2**20
"""Largest problem, agent or task file read (256 MiB)."""
MAX_REVEAL = 1_000
"""Largest ``numTasksReveal`` (2024 and later: times ``teamSize`` open tasks)."""
MAX_OPEN = 1_000_000
"""Most open tasks of the 2024 pool (``numTasksReveal`` x ``teamSize``)."""


@dataclass(frozen=True)
class LorrProblem:
    """One Robot Runners problem (see the module docstring)."""

    source: str
    grid: MovingAIMap
    starts: tuple[int, ...]
    """Linearised start cells of the team."""
    tasks: tuple[tuple[int, ...], ...]
    """Each task's errands, linearised, in order."""
    reveal: float
    strategy: str
    """``greedy``, ``roundrobin`` or ``roundrobin-fixed`` (2023 files) or ``pool`` (later)."""
    version: str | None = None
    agent_counter: int = 1
    delay_config: dict | None = None

    @property
    def team_size(self) -> int:
        return len(self.starts)


def _fail(message: str, file: str, fld: str | None = None, value: Any = None) -> ScenarioError:
    return ScenarioError(message, file=file, field=fld, value=value)


def _read_numbers(path: Path, what: str, source: str) -> tuple[str | None, list[str]]:
    """(version comment, lines after the count) of an agent or task file."""
    from .inputs import read_text

    try:
        text = read_text(path, what, MAX_FILE_BYTES)  # a regular file, size-limited
    except ScenarioError as e:
        raise _fail(e.message, source, what, str(path)) from None
    lines = [ln.strip() for ln in text.splitlines()]
    version = None
    body = []
    for ln in lines:
        if ln.startswith("#"):
            version = version or ln.lstrip("# ").strip()
        elif ln:
            body.append(ln)
    if not body:
        raise _fail(f"{what} file is empty", str(path), "count")
    try:
        count = int(body[0])
    except ValueError:
        raise _fail(f"the first line of the {what} file must be a count", str(path), "count",
                    body[0]) from None
    if count < 0 or len(body) - 1 < count:
        raise _fail(f"{what} file says {count} entries but has {len(body) - 1}", str(path),
                    "count", count)
    return version, body[1:count + 1]


def read_problem(path: str | Path) -> LorrProblem:
    """Read a Robot Runners problem JSON and the files it names; every error names the file,
    the field and the value."""
    path = Path(path)
    source = str(path)
    from .inputs import read_text

    text = read_text(path, "problem", MAX_FILE_BYTES)  # a regular file, size-limited
    try:
        data = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as e:
        raise _fail(f"not a JSON problem file: {e}", source) from None
    if not isinstance(data, dict):
        raise _fail("a problem file is a JSON object", source, None, type(data).__name__)
    for key in ("mapFile", "agentFile", "taskFile", "teamSize", "numTasksReveal"):
        if key not in data:
            raise _fail("missing key", source, key)
    for key in ("mapFile", "agentFile", "taskFile"):
        if not isinstance(data[key], str) or not data[key]:
            raise _fail("expected a relative file path", source, key, data[key])
    team = data["teamSize"]
    if type(team) is not int or not 1 <= team <= MAX_AGENTS:
        raise _fail(f"expected a whole number from 1 to {MAX_AGENTS}", source, "teamSize", team)
    reveal = data["numTasksReveal"]
    if type(reveal) not in (int, float) or not math.isfinite(reveal) or \
            not 0 < reveal <= MAX_REVEAL:
        raise _fail(f"expected a positive number up to {MAX_REVEAL}", source,
                    "numTasksReveal", reveal)
    version = data.get("version")
    strategy = data.get("taskAssignmentStrategy")
    if version is None and strategy is None:
        strategy = "greedy"
    if version is not None and strategy is None:
        strategy = "pool"
    if strategy not in ("greedy", "roundrobin", "roundrobin-fixed", "pool"):
        raise _fail("expected greedy, roundrobin or roundrobin-fixed", source,
                    "taskAssignmentStrategy", strategy)
    if strategy == "pool" and reveal * team > MAX_OPEN:
        raise _fail(f"numTasksReveal x teamSize open tasks: at most {MAX_OPEN:,} (got "
                    f"{reveal * team:,.0f})", source, "numTasksReveal", reveal)
    counter = data.get("agentCounter", 1)
    if type(counter) is not int or counter < 1:
        raise _fail("expected a whole number >= 1", source, "agentCounter", counter)
    delay = data.get("delayConfig")
    if delay is not None and not isinstance(delay, dict):
        raise _fail("expected an object", source, "delayConfig", delay)
    base = path.parent
    grid = read_map(base / data["mapFile"])
    cells = grid.rows * grid.cols
    free = ~grid.obstacles.ravel()

    def location(text: str, file: Path, fld: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise _fail("expected a linearised cell (row * width + column)", str(file), fld,
                        text) from None
        if not 0 <= v < cells:
            raise _fail(f"cell off the {grid.rows} x {grid.cols} map", str(file), fld, v)
        if not free[v]:
            raise _fail(f"cell ({v // grid.cols}, {v % grid.cols}) is an obstacle", str(file),
                        fld, v)
        return v

    agent_file = base / data["agentFile"]
    _, agent_lines = _read_numbers(agent_file, "agentFile", source)
    if len(agent_lines) < team:
        raise _fail(f"teamSize {team} but the agent file has {len(agent_lines)} agents",
                    source, "teamSize", team)
    starts = tuple(location(ln.split(",")[0], agent_file, f"agent {i}")
                   for i, ln in enumerate(agent_lines[:team]))
    if len(set(starts)) != len(starts):
        seen: dict[int, int] = {}
        for i, s in enumerate(starts):
            if s in seen:
                raise _fail(f"agents {seen[s]} and {i} start on the same cell", str(agent_file),
                            f"agent {i}", s)
            seen[s] = i
    task_file = base / data["taskFile"]
    _, task_lines = _read_numbers(task_file, "taskFile", source)
    if len(task_lines) > MAX_TASKS:
        raise _fail(f"more than {MAX_TASKS} tasks", str(task_file), "count", len(task_lines))
    tasks = []
    for k, ln in enumerate(task_lines):
        errands = tuple(location(x.strip(), task_file, f"task {k}")
                        for x in ln.split(",") if x.strip())
        if not errands:
            raise _fail("a task needs at least one errand", str(task_file), f"task {k}", ln)
        tasks.append(errands)
    if not tasks:
        raise _fail("no tasks", str(task_file), "count", 0)
    return LorrProblem(source=source, grid=grid, starts=starts, tasks=tuple(tasks),
                       reveal=float(reveal), strategy=strategy, version=version,
                       agent_counter=counter, delay_config=delay)


@dataclass
class LorrResult:
    """What a lifelong run did (see :func:`output_json`)."""

    problem: LorrProblem
    rotations: bool
    rule: str
    """How PIBT met the rotation model (:data:`RULES`; ``"none"`` without rotations)."""
    actions: list[list[str]]
    """Per robot, one action per timestep (empty when ``chunks`` holds them)."""
    positions: list[list[int]]
    """Per robot, its linearised cell at every timestep (0 .. ticks; empty when the run
    streamed its actions to ``chunks``)."""
    headings: list[list[int]]
    events: list[tuple[int, int, int, int]] = field(default_factory=list)
    """(timestep, robot, task, errands done)."""
    releases: dict[int, int] = field(default_factory=dict)
    """Task id -> timestep it was revealed."""
    schedule: list[list[tuple[int, int]]] = field(default_factory=list)
    """Per robot, (timestep, task) when it took a task."""
    tick_s: list[float] = field(default_factory=list)
    """Wall seconds of every timestep (assignment, planning and moving)."""
    finished: int = 0
    setup_s: float = 0.0
    chunks: ActionChunks | None = None
    """Where a streamed run's actions are (``run_lifelong(trace_dir=...)``)."""
    dist: dict[str, Any] = field(default_factory=dict)
    """The distance-table store's counters at the end (:meth:`DistStore.counters`)."""
    tick_misses: list[int] = field(default_factory=list)
    """Distance tables computed in every timestep."""
    tick_bfs_s: list[float] = field(default_factory=list)
    """Seconds of breadth-first search in every timestep (part of ``tick_s``)."""
    tick_plan_s: list[float] = field(default_factory=list)
    """Seconds of the PIBT step in every timestep (part of ``tick_s``)."""
    tick_cpu_s: list[float] = field(default_factory=list)
    """CPU seconds of this process in every timestep (wall time less waiting for a core on
    a loaded machine)."""
    tick_plan_cpu_s: list[float] = field(default_factory=list)
    """CPU seconds of the PIBT step in every timestep."""
    engine: str = "python"
    """The PIBT step that ran (``numba`` or ``python``, :data:`ENGINES`)."""
    compile_s: float = 0.0
    """Seconds of ``setup_s`` spent importing numba and compiling the numba steps or
    loading them from numba's cache (the first run of a process; 0 with ``engine="python"``)."""

    @property
    def ticks(self) -> int:
        return len(self.tick_s)

    def action_rows(self, block: int = 512):
        """Every robot's actions as one string (one character per timestep), in robot
        order, read block by block from ``chunks`` when the run streamed them."""
        if self.chunks is None:
            for acts in self.actions:
                yield "".join(acts)
        else:
            yield from self.chunks.rows(block)

    def summary(self) -> dict[str, Any]:
        ms = np.asarray(self.tick_s) * 1e3 if self.tick_s else np.zeros(1)
        return {"problem": self.problem.source, "agents": self.problem.team_size,
                "ticks": self.ticks, "rotations": self.rotations, "rotation_rule": self.rule,
                "tasks_finished": self.finished,
                "ms_per_tick_mean": float(ms.mean()), "ms_per_tick_p99":
                float(np.percentile(ms, 99)), "ms_per_tick_max": float(ms.max()),
                "engine": self.engine, "compile_s": self.compile_s,
                "setup_s": self.setup_s, "wall_s": self.setup_s + float(ms.sum()) / 1e3,
                "first_tick_s": float(ms[0]) / 1e3,
                "pibt_ms_per_tick_mean": float(np.mean(self.tick_plan_s)) * 1e3
                if self.tick_plan_s else 0.0,
                "pibt_ms_per_tick_p99": float(np.percentile(self.tick_plan_s, 99)) * 1e3
                if self.tick_plan_s else 0.0,
                **_ms("cpu_ms_per_tick", self.tick_cpu_s),
                **_ms("pibt_cpu_ms_per_tick", self.tick_plan_cpu_s),
                "dist_tables": {**self.dist, "misses_per_tick_mean": float(np.mean(
                    self.tick_misses)) if self.tick_misses else 0.0,
                    "misses_per_tick_max": max(self.tick_misses, default=0),
                    "bfs_ms_per_tick_mean": float(np.mean(self.tick_bfs_s)) * 1e3
                    if self.tick_bfs_s else 0.0,
                    "bfs_ms_per_tick_p99": float(np.percentile(self.tick_bfs_s, 99)) * 1e3
                    if self.tick_bfs_s else 0.0},
                "agent_counter_modelled": False if self.problem.agent_counter != 1 else None,
                "delays_modelled": False if self.problem.delay_config else None}


def _ms(name: str, seconds: list[float]) -> dict[str, float]:
    """``{name_mean, name_p99}`` in ms of ``seconds`` (0 when empty)."""
    ms = np.asarray(seconds) * 1e3 if seconds else np.zeros(1)
    return {f"{name}_mean": float(ms.mean()), f"{name}_p99": float(np.percentile(ms, 99))}


class _Tasks:
    """The task pool and who holds what."""

    def __init__(self, problem: LorrProblem, compiled: Callable | None = None) -> None:
        self.p = problem
        self.n = problem.team_size
        self.cols = problem.grid.cols
        self.next_task = 0
        # the open pool (2024 and later): task ids, in the order revealed, and the row and
        # column of each one's first errand
        self.open = np.zeros(0, dtype=np.int64)
        self.open_r = np.zeros(0, dtype=np.int64)
        self.open_c = np.zeros(0, dtype=np.int64)
        self.releases: dict[int, int] = {}
        self.rr_next = list(range(self.n))  # roundrobin: each robot's next task id
        self.compiled = compiled
        """:func:`~.planning.pibt_numba.nearest_open`, or None: the Python loop."""
        if problem.strategy == "pool":
            self._reveal(max(1, int(problem.reveal * self.n)), 0)

    def _task(self, k: int) -> tuple[int, ...]:
        return self.p.tasks[k % len(self.p.tasks)]

    def _reveal(self, count: int, tick: int) -> None:
        if count <= 0:
            return
        ids = np.arange(self.next_task, self.next_task + count, dtype=np.int64)
        for k in ids.tolist():
            self.releases[k] = tick
        first = np.asarray([self._task(k)[0] for k in ids.tolist()], dtype=np.int64)
        self.open = np.concatenate([self.open, ids])
        self.open_r = np.concatenate([self.open_r, first // self.cols])
        self.open_c = np.concatenate([self.open_c, first % self.cols])
        self.next_task += count

    def assign(self, free: list[int], where, tick: int) -> dict[int, int]:
        """Tasks for the free robots (robot -> task id)."""
        out: dict[int, int] = {}
        strategy = self.p.strategy
        if strategy == "greedy":
            for i in free:
                out[i] = self.next_task
                self.releases[self.next_task] = tick
                self.next_task += 1
        elif strategy in ("roundrobin", "roundrobin-fixed"):
            for i in free:
                k = self.rr_next[i]
                self.rr_next[i] += self.n
                self.releases[k] = tick
                out[i] = k
        else:
            if not len(self.open) or not free:
                return out
            fr, fc = self.open_r, self.open_c
            taken = np.zeros(len(self.open), dtype=bool)
            if self.compiled is not None:  # the same choices, compiled
                robots = np.asarray(free, dtype=np.int64)
                cells = np.asarray(where, dtype=np.int64)[robots]
                pick = self.compiled(fr, fc, cells // self.cols, cells % self.cols)
                for i, j in zip(free, pick.tolist(), strict=True):
                    if j < 0:
                        break
                    taken[j] = True
                    out[i] = int(self.open[j])
                free = []
            far = np.iinfo(np.int64).max
            for i in free:
                r, c = divmod(int(where[i]), self.cols)
                d = np.abs(fr - r) + np.abs(fc - c)
                d[taken] = far
                j = int(np.argmin(d))
                if taken[j]:
                    break
                taken[j] = True
                out[i] = int(self.open[j])
            keep = ~taken
            self.open, self.open_r, self.open_c = self.open[keep], fr[keep], fc[keep]
        return out

    def finished(self, count: int, tick: int) -> None:
        if self.p.strategy == "pool":
            self._reveal(count, tick)


def run_lifelong(problem: LorrProblem, ticks: int, *, rotations: bool = True, seed: int = 0,
                 rule: str = "actions",
                 progress: Callable[[int, int], None] | None = None,
                 dist_budget_mb: float | None = None, trace_dir: str | Path | None = None,
                 chunk_ticks: int = 100, prefetch: bool = False,
                 engine: str = "auto") -> LorrResult:
    """Run ``problem`` for ``ticks`` timesteps with lifelong PIBT (see the module
    docstring; ``rule``: one of :data:`RULES`, used with ``rotations``); every timestep's
    configuration is checked (no two robots on a cell, no swaps, no jumps).

    Distance tables come from one :class:`~.planning.dist_store.DistStore` (MiB budget
    ``dist_budget_mb``, default :data:`~.planning.dist_store.DEFAULT_BUDGET_MB`) shared by
    all robots and timesteps. ``trace_dir``: stream the actions to ``.npy`` files there,
    ``chunk_ticks`` timesteps each (:class:`ActionChunks`), instead of keeping actions,
    positions and headings in lists, so memory does not grow with ``ticks``. ``prefetch``:
    before the first timestep, compute the tables of the tasks' errand cells, in the order
    the tasks come, until the budget is full (set-up time instead of timestep time; the
    league gives entrants a preprocessing phase); plans do not change. ``engine``: the PIBT
    step, ``numba`` (compiled, :mod:`.planning.pibt_numba`), ``python`` (the reference
    steps) or ``auto`` (numba when it imports); both give the same plans."""
    if rule not in RULES:
        raise ValueError(f"rule: expected one of {RULES}, got {rule!r}")
    if engine not in ENGINES:
        raise ValueError(f"engine: expected one of {ENGINES}, got {engine!r}")
    t0 = time.perf_counter()
    from .planning import pibt_numba as pn  # imports numba: part of the compile time
    import_s = time.perf_counter() - t0
    from .planning.dist_store import DEFAULT_BUDGET_MB, DistStore
    from .planning.oneshot import grid_graph
    from .planning.pibt_heading import steps_of

    if engine == "auto":
        engine = "numba" if pn.AVAILABLE else "python"
    elif engine == "numba" and not pn.AVAILABLE:  # pragma: no cover - numba is a dependency
        raise ValueError("engine numba: numba is not installed (pip install numba)")
    fast = engine == "numba"
    grid = problem.grid
    cols = grid.cols
    graph = grid_graph(grid.obstacles)
    n = problem.team_size
    store = DistStore(graph, DEFAULT_BUDGET_MB if dist_budget_mb is None else dist_budget_mb,
                      reserve=n if fast else None)
    st = pn.step_tables(graph.neighbors, cols)
    steps = steps_of(graph.neighbors, cols) if rotations and rule == "actions" and not fast \
        else None
    if prefetch:
        store.prefetch(e for k in range(min(len(problem.tasks), 10 * store.capacity))
                       for e in problem.tasks[k])
    tasks = _Tasks(problem, pn.nearest_open if fast else None)
    rng = np.random.default_rng(seed)
    config = np.asarray(problem.starts, dtype=np.int64)
    heading = np.zeros(n, dtype=np.int64)
    task_of = np.full(n, -1, dtype=np.int64)
    errand = np.zeros(n, dtype=np.int64)  # errands of its task done
    goal = np.full(n, -1, dtype=np.int64)  # tables are made once robots have their first errands
    since = np.zeros(n, dtype=np.int64)
    frac = np.arange(n) / (n + 1)
    escaping = np.zeros(n, dtype=bool)
    if fast:
        c0 = time.perf_counter()
        pn.warm_up(store.dtype)
        result_compile_s = import_s + time.perf_counter() - c0
        # the robots' tables: rows of the store's slab (every robot gets one before the
        # first step); ``held`` keeps each robot's table alive, so its row stays its own
        rows = np.zeros(n, dtype=np.int64)
        tabs = (store.slab, rows)
        held: list = [None] * n
    else:
        result_compile_s = 0.0
        # a memoryview reads Python ints: PIBT's single reads run 3-10x faster than on numpy
        # scalars (uint16 against a float or a large int most)
        tabs = [None] * n
    chunks = None if trace_dir is None else ActionChunks(Path(trace_dir), n, chunk_ticks)
    result = LorrResult(problem, rotations, rule if rotations else "none",
                        actions=[], positions=[], headings=[],
                        schedule=[[] for _ in range(n)], chunks=chunks)
    result.engine = engine
    result.compile_s = result_compile_s
    kept_acts: list[np.ndarray] = []
    kept_cfg: list[np.ndarray] = [config]
    kept_head: list[np.ndarray] = [heading]
    arange = np.arange(n)
    pos = np.full(graph.num_nodes, -1, dtype=np.int64)
    letters = np.frombuffer(b"WRLDU", dtype=np.uint8)
    result.setup_s = time.perf_counter() - t0
    for tick in range(ticks):
        w0 = time.perf_counter()
        c0 = time.process_time()
        misses0, bfs0 = store.misses, store.bfs_s
        # Errands reached (any heading), then new tasks for free robots.
        advanced = _errands_reached(config, goal, task_of, errand, tasks, result, tick)
        free = np.flatnonzero(task_of < 0).tolist()
        for i, k in tasks.assign(free, config, tick).items():
            task_of[i], errand[i] = k, 0
            result.events.append((tick, i, k, 0))
            result.schedule[i].append((tick, k))
        # Goals change only for robots that did an errand, took a task or have none.
        for i in sorted(set(advanced).union(free)):
            k = int(task_of[i])
            g = int(config[i]) if k < 0 else tasks._task(k)[int(errand[i])]
            if g != goal[i]:
                goal[i] = g
                table = store.get(g)
                if fast:
                    held[i] = table
                    rows[i] = store.slot(table)
                else:
                    tabs[i] = memoryview(table)  # type: ignore[call-overload]
                since[i] = tick
        prio = (tick - since) + frac
        tie = rng.random(graph.num_nodes) * 0.5
        p0 = time.perf_counter()
        pc0 = time.process_time()
        if fast:
            order = pn.priority_order(prio)
            if rotations and rule == "actions":
                nxt, heading, acts, escaping = pn.heading_step_nb(
                    st, config, heading, tabs, order, tie, escaping)
            elif rotations:
                nxt = pn.pibt_step_nb(st, config, goal, tabs, order, tie, heading=heading)
                nxt, heading, acts = pn.turn_first_nb(config, nxt, heading, cols,
                                                      graph.num_nodes)
            else:
                nxt = pn.pibt_step_nb(st, config, goal, tabs, order, tie)
                acts = letters[_move_codes(nxt - config, cols)]
        else:
            nxt, heading, acts, escaping = _python_step(
                graph, st, steps, cols, config, heading, goal, tabs, prio.tolist(),
                tie.tolist(), escaping, rotations, rule, letters)
        result.tick_plan_s.append(time.perf_counter() - p0)
        result.tick_plan_cpu_s.append(time.process_time() - pc0)
        _check(config, nxt, st, pos, arange, tick)
        config = nxt
        if chunks is not None:
            chunks.append(acts)
        else:
            kept_acts.append(acts)
            kept_cfg.append(config)
            kept_head.append(heading)
        result.tick_misses.append(store.misses - misses0)
        result.tick_bfs_s.append(store.bfs_s - bfs0)
        result.tick_s.append(time.perf_counter() - w0)
        result.tick_cpu_s.append(time.process_time() - c0)
        if progress is not None:
            progress(tick + 1, ticks)
    # the last moves' errands count too (the start kit checks after every move)
    _errands_reached(config, goal, task_of, errand, tasks, result, ticks)
    if chunks is not None:
        chunks.flush()
    else:
        acts_2d = np.stack(kept_acts) if kept_acts else np.zeros((0, n), dtype=np.uint8)
        result.actions = [list(row.tobytes().decode("ascii"))
                          for row in np.ascontiguousarray(acts_2d.T)]
        result.positions = np.stack(kept_cfg).T.tolist()
        result.headings = np.stack(kept_head).T.tolist()
    result.releases = dict(tasks.releases)
    result.dist = store.counters()
    return result


ENGINES = ("auto", "numba", "python")
"""The PIBT step of :func:`run_lifelong`: compiled or the Python reference."""


def _errands_reached(config: np.ndarray, goal: np.ndarray, task_of: np.ndarray,
                     errand: np.ndarray, tasks: _Tasks, result: LorrResult,
                     tick: int) -> list[int]:
    """Robots standing on their current errand's cell at ``tick`` have done it: record the
    events, finish the tasks whose last errand it was (counted, and the pool refilled);
    the robots that advanced."""
    done_now = 0
    advanced = np.flatnonzero((config == goal) & (task_of >= 0)).tolist()
    for i in advanced:
        k = int(task_of[i])
        e = int(errand[i]) + 1
        errand[i] = e
        result.events.append((tick, i, k, e))
        if e == len(tasks._task(k)):
            task_of[i] = -1
            done_now += 1
    result.finished += done_now
    tasks.finished(done_now, tick)
    return advanced


def _move_codes(delta: np.ndarray, cols: int) -> np.ndarray:
    """Index into ``b"WRLDU"`` of each move ``nxt - config`` (linear cells)."""
    return np.where(delta == cols, 3, np.where(delta == -cols, 4, np.where(
        delta == 1, 1, np.where(delta == -1, 2, 0))))


def _python_step(graph, st, steps, cols, config, heading, goal, tabs, prio, tie, escaping,
                 rotations, rule, letters):
    """One timestep with the Python reference steps (lists in, arrays out)."""
    from .planning.pibt import pibt_step
    from .planning.pibt_heading import heading_pibt_step

    n = len(config)
    cfg = config.tolist()
    if rotations and rule == "actions":  # PIBT over the actions forward / turn / wait
        esc = frozenset(np.flatnonzero(escaping).tolist())
        nxt, nh, acts, esc = heading_pibt_step(graph.neighbors, cols, cfg, heading.tolist(),
                                               tabs, prio, tie, esc, steps)
        out_esc = np.zeros(n, dtype=bool)
        out_esc[list(esc)] = True
        return (np.asarray(nxt, dtype=np.int64), np.asarray(nh, dtype=np.int64),
                np.frombuffer("".join(acts).encode("ascii"), dtype=np.uint8).copy(), out_esc)
    if rotations:  # PIBT over cells, then turn first where a cell is not ahead
        hd = heading.tolist()
        costs = [_Facing(tabs[i], cfg[i], hd[i], cols) for i in range(n)]
        nxt = pibt_step(graph, cfg, costs, prio, tie, goals=goal.tolist())
        if nxt is None:  # pragma: no cover - no forced moves are given
            raise AssertionError("PIBT found no configuration")
        acts_l = ["W"] * n
        nxt = _turn_first(cfg, nxt, hd, acts_l, cols)
        return (np.asarray(nxt, dtype=np.int64), np.asarray(hd, dtype=np.int64),
                np.frombuffer("".join(acts_l).encode("ascii"), dtype=np.uint8).copy(), escaping)
    nxt = pibt_step(graph, cfg, tabs, prio, tie, goals=goal.tolist())
    if nxt is None:  # pragma: no cover - no forced moves are given
        raise AssertionError("PIBT found no configuration")
    acts_l = ["W"] * n
    for i in range(n):
        if nxt[i] != cfg[i]:
            dr, dc = nxt[i] // cols - cfg[i] // cols, nxt[i] % cols - cfg[i] % cols
            acts_l[i] = _MOVE_LETTER[(dr, dc)]
    return (np.asarray(nxt, dtype=np.int64), heading,
            np.frombuffer("".join(acts_l).encode("ascii"), dtype=np.uint8).copy(), escaping)


class ActionChunks:
    """A run's actions on disk: every ``chunk`` timesteps one ``.npy`` array (timesteps x
    robots, ``uint8`` ASCII codes of the action letters) in ``folder``; read back robot by
    robot (:meth:`rows`) a block of robots at a time, so neither writing nor reading holds
    the whole run."""

    def __init__(self, folder: Path, robots: int, chunk: int = 100) -> None:
        if chunk < 1:
            raise ValueError(f"chunk: expected a positive number of timesteps, got {chunk}")
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.robots = robots
        self.chunk = chunk
        self.files: list[Path] = []
        self._buf: list[bytes] = []
        self.ticks = 0

    def append(self, acts: list[str] | np.ndarray) -> None:
        """One timestep's actions (one letter per robot, or their ``uint8`` ASCII codes)."""
        self._buf.append(acts.tobytes() if isinstance(acts, np.ndarray)
                         else "".join(acts).encode("ascii"))
        self.ticks += 1
        if len(self._buf) >= self.chunk:
            self.flush()

    def flush(self) -> None:
        if not self._buf:
            return
        arr = np.frombuffer(b"".join(self._buf), dtype=np.uint8).reshape(len(self._buf),
                                                                         self.robots)
        path = self.folder / f"actions_{len(self.files):06d}.npy"
        np.save(path, arr)
        self.files.append(path)
        self._buf = []

    def rows(self, block: int = 512):
        """Every robot's actions as one string, in robot order."""
        self.flush()
        arrays = [np.load(f, mmap_mode="r") for f in self.files]
        for b0 in range(0, self.robots, block):
            b1 = min(self.robots, b0 + block)
            part = (np.concatenate([a[:, b0:b1] for a in arrays], axis=0) if arrays
                    else np.zeros((0, b1 - b0), dtype=np.uint8))
            for row in np.ascontiguousarray(part.T):
                yield row.tobytes().decode("ascii")


class _Facing:
    """A robot's distances to its goal, plus, for the cells next to it, the quarter turns it
    needs to face them (PIBT then prefers going on straight ahead)."""

    __slots__ = ("d", "here", "extra")

    def __init__(self, d: np.ndarray, here: int, heading: int, cols: int) -> None:
        self.d = d
        self.here = here
        r, c = divmod(here, cols)
        self.extra = {}
        for h, (dr, dc) in enumerate(_STEP):
            turns = (h - heading) % 4
            self.extra[(r + dr) * cols + c + dc] = min(turns, 4 - turns)

    def __getitem__(self, v: int) -> int:
        return int(self.d[v]) + self.extra.get(v, 0)


def _turn_first(config: list[int], nxt: list[int], heading: list[int], acts: list[str],
                cols: int) -> list[int]:
    """PIBT's cells under the rotation model: a robot moves only forward; one whose cell lies
    in another direction turns towards it and stays, and whoever was to enter the cell of a
    robot that stays, stays too. Updates ``heading`` and ``acts``; returns the cells."""
    n = len(config)
    out = list(nxt)
    for i in range(n):
        if out[i] == config[i]:
            continue
        dr = out[i] // cols - config[i] // cols
        dc = out[i] % cols - config[i] % cols
        want = _STEP.index((dr, dc))
        if want != heading[i]:
            diff = (want - heading[i]) % 4
            acts[i] = "R" if diff in (1, 2) else "C"
            heading[i] = (heading[i] + (1 if acts[i] == "R" else -1)) % 4
            out[i] = config[i]
    # Cascade: whoever enters a cell whose robot stays, stays.
    stack = [i for i in range(n) if out[i] == config[i]]
    entering: dict[int, int] = {out[i]: i for i in range(n) if out[i] != config[i]}
    while stack:
        i = stack.pop()
        j = entering.pop(config[i], None)
        if j is not None and out[j] != config[j]:
            out[j] = config[j]
            stack.append(j)
    for i in range(n):
        if out[i] != config[i] and acts[i] == "W":
            acts[i] = "F"
    return out


def _check(config: np.ndarray, nxt: np.ndarray, st: Any, pos: np.ndarray, arange: np.ndarray,
           tick: int) -> None:
    """No two robots on a cell, no two swapping cells, no jumps (over arrays: ``pos`` is a
    per-cell scratch array of -1, left as it was found; ``st``: the step tables)."""
    pos[nxt] = arange
    try:
        if (pos[nxt] != arange).any():
            raise AssertionError(f"vertex conflict at timestep {tick + 1}")  # pragma: no cover
        j = pos[config]  # who moves into my cell
        bad = (j >= 0) & (j != arange) & (config[np.maximum(j, 0)] == nxt)
        if bad.any():  # pragma: no cover
            i = int(np.flatnonzero(bad)[0])
            raise AssertionError(f"robots {i} and {int(j[i])} swap at timestep {tick + 1}")
        moved = np.flatnonzero(nxt != config)
        jumps = ~(st.nbr[config[moved]] == nxt[moved, None]).any(axis=1)
        if jumps.any():  # pragma: no cover
            raise AssertionError(f"robot {int(moved[jumps][0])} jumps at timestep {tick + 1}")
    finally:
        pos[nxt] = -1


def output_json(result: LorrResult, *, paths: bool = True) -> dict[str, Any]:
    """The start-kit's output JSON of a run (see the module docstring); without ``paths``,
    ``actualPaths`` and ``plannerPaths`` are None (:func:`write_output_json` streams
    them)."""
    from . import lorr_fields as lf

    p = result.problem
    cols = p.grid.cols
    n = p.team_size
    path_list: list[str] | None = None
    if paths:
        path_list = [",".join(row) for row in result.action_rows()]
    cells = {k: p.tasks[k % len(p.tasks)] for k in result.releases}
    errands = {k: len(c) for k, c in cells.items()}
    held = lf.goal_held_ticks(result.schedule, lf.finish_ticks(result.events, errands),
                              result.ticks)
    v2023 = p.version is None
    return {
        "actionModel": "MAPF_T" if result.rotations else "MAPF",
        "version": p.version or "2023 LoRR",
        "teamSize": n,
        "start": [[s // cols, s % cols, HEADINGS[0]] for s in p.starts],
        "numTaskFinished": result.finished,
        **lf.cost_fields(held),
        "actualPaths": path_list,
        "plannerPaths": path_list,
        "plannerTimes": [round(s, 6) for s in result.tick_s],
        "errors": [],
        "events": lf.events_2023(result.events, errands, n) if v2023
        else lf.events_2024(result.events),
        "tasks": lf.tasks_field(result.releases, cells, cols, version_2023=v2023),
        "actualSchedule": lf.schedule_strings(result.schedule),
    }


def write_output_json(result: LorrResult, path: str | Path) -> None:
    """Write :func:`output_json` to ``path`` (the same bytes as ``json.dumps`` of it and a
    newline) without building the paths in memory: they are streamed robot by robot."""
    doc = output_json(result, paths=False)
    with open(path, "w", encoding="utf-8") as f:
        f.write("{")
        for k, (key, value) in enumerate(doc.items()):
            f.write((", " if k else "") + json.dumps(key) + ": ")
            if key in ("actualPaths", "plannerPaths"):
                f.write("[")
                for i, row in enumerate(result.action_rows()):
                    f.write((", " if i else "") + json.dumps(",".join(row)))
                f.write("]")
            else:
                f.write(json.dumps(value))
        f.write("}\n")
