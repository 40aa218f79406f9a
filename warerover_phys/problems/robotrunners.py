"""League of Robot Runners problems: read one, run it in the one loop, write its output JSON.

**Problems** (:func:`read_problem`): the start-kit's problem JSON names a map (MovingAI grid,
``E`` emitters and ``S`` service points free), an agent file (count, then one linearised
start ``row * width + col`` per line; the first ``teamSize`` are used) and a task file
(count, then one task per line: its errands' linearised cells, visited in order by one
robot; one errand in 2023, two or three later). ``numTasksReveal`` is, in 2023 files (with a
``taskAssignmentStrategy``), the tasks each robot knows ahead; in 2024 and later files
(``version``), a multiplier: ``numTasksReveal * teamSize`` open tasks are kept in a pool and
refilled as tasks finish. ``agentCounter`` and ``delayConfig`` (2026) are read and reported,
not modelled (one action per timestep; delays come from ``executor.delays`` if set).

**Runs** (:func:`problem_scenario`): the problem becomes a :class:`~warerover_phys.config.
Scenario` of the one loop (:class:`~warerover_phys.sim.Simulation`): its map the layout
(1 m cells), its agents the fleet (1x1 robots facing east, 1.5 m/s, quarter turn within a
tick), its tasks errand tasks (:mod:`warerover_phys.problems.errands`) assigned by the problem's rule
(2023 ``roundrobin`` / ``roundrobin-fixed`` with wrap-around, ``greedy``; 2024+ ``pool``:
nearest first errand), planned by lifelong PIBT (the league's rotation model ``MAPF_T`` by
default: forward, turn clockwise ``R`` / counter-clockwise ``C``, wait ``W``, one per
timestep; rules ``actions`` and ``turn-first``) and executed by any executor: ``grid``
(ideal moves) or ``physics`` (pymunk bodies through the action dependency graph). Faults,
corridors, delays, video and sweeps come with the loop.

**Output** (:func:`output_json`, the start kit's fields): ``actionModel`` (``MAPF_T``;
without rotations ``MAPF``, ours: ``U`` / ``D`` / ``L`` / ``R`` move one cell up (-row),
down, left (-col) or right, ``W`` waits), ``version``, ``teamSize``, ``start``
(``[row, col, heading]``), ``numTaskFinished``, ``sumOfCost``, ``makespan``,
``actualPaths``, ``plannerPaths``, ``plannerTimes``, ``errors`` (empty), ``events``
(``[timestep, robot, task, errands done]``: one with 0 when a task is assigned, one per
errand done), ``tasks`` (``[id, release timestep, [row1, col1, ...]]``) and
``actualSchedule`` (per robot ``"t:task,"`` when it takes a task). Which start-kit version
each field follows is in ``docs``' Robot Runners page. On the grid ``actualPaths`` are
the executed moves tick by tick. On physics robots run late and may finish two moves
within one timestep, which one action per timestep cannot say: ``actualPaths`` then list
the moves the bodies made, in the order they made them, each at the first timestep that is
no earlier than the timestep it finished in, after the robot's previous action, and no
earlier than the move out of the cell of the robot that was there before (the order of
visits the bodies kept) — a collision-free replay of what the bodies did
(:func:`serialise_moves`), turns put where the moves need them.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ScenarioError
from .errands import check_cell, read_numbers, read_task_file, read_text
from .movingai import MovingAIMap, read_map

if TYPE_CHECKING:
    from ..config import Scenario
    from ..sim import EpisodeResult

__all__ = ["LorrProblem", "read_problem", "problem_scenario", "output_json",
           "write_output_json", "serialise_moves", "HEADINGS", "RULES", "MAX_AGENTS"]

HEADINGS = "ESWN"
"""Heading codes 0-3: east (+col), south (+row), west (-col), north (-row)."""
_STEP = ((0, 1), (1, 0), (0, -1), (-1, 0))
_MOVE_LETTER = {(0, 1): "R", (1, 0): "D", (0, -1): "L", (-1, 0): "U"}
RULES = ("actions", "turn-first")
"""How PIBT meets the rotation model (``planner.rotation_rule``)."""
MAX_AGENTS = 100_000
MAX_OPEN = 1_000_000
"""Most open tasks of a 2024+ pool (``numTasksReveal`` x ``teamSize``)."""


@dataclass(frozen=True)
class LorrProblem:
    """One Robot Runners problem (see the module docstring)."""

    source: str
    grid: MovingAIMap
    map_file: Path
    task_file: Path
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

    @property
    def assign(self) -> str:
        """The errand rule (``orders.errands.assign``) of the strategy."""
        return {"roundrobin-fixed": "roundrobin"}.get(self.strategy, self.strategy)


def _fail(message: str, file: str, fld: str | None = None, value: Any = None) -> ScenarioError:
    return ScenarioError(message, file=file, field=fld, value=value)


def read_problem(path: str | Path) -> LorrProblem:
    """Read a Robot Runners problem JSON and the files it names; every error names the file,
    the field and the value."""
    path = Path(path)
    source = str(path)
    try:
        data = json.loads(read_text(path, "problem", source, limit=16 * 2**20))
    except json.JSONDecodeError as e:
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
    if type(reveal) not in (int, float) or not math.isfinite(reveal) or not \
            0 < reveal <= MAX_AGENTS:
        raise _fail(f"expected a positive number up to {MAX_AGENTS}", source, "numTasksReveal",
                    reveal)
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
    map_file = base / data["mapFile"]
    grid = read_map(map_file)
    free = ~grid.obstacles.ravel()
    agent_file = base / data["agentFile"]
    _, agent_lines = read_numbers(agent_file, "agentFile", source)
    if len(agent_lines) < team:
        raise _fail(f"teamSize {team} but the agent file has {len(agent_lines)} agents",
                    source, "teamSize", team)
    starts = tuple(check_cell(ln.split(",")[0].strip(), free, agent_file, f"agent {i}")
                   for i, ln in enumerate(agent_lines[:team]))
    if len(set(starts)) != len(starts):
        seen: dict[int, int] = {}
        for i, s in enumerate(starts):
            if s in seen:
                raise _fail(f"agents {seen[s]} and {i} start on the same cell", str(agent_file),
                            f"agent {i}", s)
            seen[s] = i
    task_file = base / data["taskFile"]
    _, tasks = read_task_file(task_file, free, source)
    return LorrProblem(source=source, grid=grid, map_file=map_file, task_file=task_file,
                       starts=starts, tasks=tuple(tasks), reveal=float(reveal),
                       strategy=strategy, version=version, agent_counter=counter,
                       delay_config=delay)


def problem_scenario(problem: LorrProblem, *, ticks: int, rotations: bool = True,
                     rule: str = "actions", seed: int = 0, planner: str = "pibt",
                     executor: str = "grid", overrides: list[tuple[str, Any]] | None = None
                     ) -> Scenario:
    """The problem as a scenario of the one loop (see the module docstring), run for
    ``ticks`` timesteps; ``overrides`` (``field.path``, value) pairs as ``--set`` gives
    them."""
    from ..config import scenario_from_dict

    if rule not in RULES:
        raise ScenarioError(f"expected one of {', '.join(RULES)}", file=problem.source,
                            field="rotation_rule", value=rule)
    cols = problem.grid.cols
    name = "".join(c if c.isalnum() or c in "._-" else "_" for c in Path(problem.source).stem)
    data = {
        "name": (name or "robotrunners")[:128].lstrip(".") or "robotrunners",
        "seed": seed,
        "max_ticks": ticks,
        "tick_s": 1.0,
        "layout": {"map": str(problem.map_file.resolve()), "cell_m": 1.0},
        "fleet": {"types": {"robot": {"footprint": 1}},
                  "agvs": [{"type": "robot", "count": problem.team_size,
                            "starts": [[s // cols, s % cols] for s in problem.starts]}]},
        "orders": {"pattern": "errands", "errands": {
            "file": str(problem.task_file.resolve()), "assign": problem.assign,
            "reveal": problem.reveal, "idle": "stay"}},
        "scheduler": {"name": "errands"},
        "planner": {"name": planner, "rotations": rotations, "rotation_rule": rule,
                    "ties": "high_id"},
        "executor": {"name": executor},
    }
    return scenario_from_dict(data, source=problem.source, overrides=overrides)


# ----------------------------------------------------------------------------- output


def _task_events(result: EpisodeResult, n: int
                 ) -> tuple[list[tuple[int, int, int, int]], list[list[tuple[int, int]]], list[int]]:
    """From the world's log: ``(timestep, robot, task, errands done)`` per assignment (0) and
    per errand done, each robot's ``(timestep, task)`` assignments, and each robot's
    timesteps with a task (the start kit's per-robot cost)."""
    events: list[tuple[int, int, int, int]] = []
    schedule: list[list[tuple[int, int]]] = [[] for _ in range(n)]
    busy = [0] * n
    since: dict[int, int] = {}
    horizon = result.world.tick
    for e in result.world.events:
        kind = e["event"]
        if kind == "order_assigned":
            events.append((e["tick"], e["agv"], e["order"], 0))
            schedule[e["agv"]].append((e["tick"], e["order"]))
            since[e["agv"]] = e["tick"]
        elif kind == "errand_done":
            events.append((e["tick"], e["agv"], e["order"], e["errands"]))
        elif kind == "order_completed" and e["agv"] in since:
            busy[e["agv"]] += min(e["tick"], horizon) - since.pop(e["agv"])
    for i, t in since.items():
        busy[i] += horizon - t
    return events, schedule, busy


def _grid_rows(result: EpisodeResult, cols: int, rotations: bool) -> list[str]:
    """Each robot's actions tick by tick from its executed states (one move at most per
    tick, as on the grid) and, with rotations, its headings."""
    out = []
    heads = result.headings or {}
    for i, states in sorted(result.actual.items()):
        cells = [s[1] for s in states]
        hs = heads.get(i)
        acts = []
        for t in range(len(cells) - 1):
            a, b = cells[t], cells[t + 1]
            if a != b:
                if rotations:
                    acts.append("F")
                else:
                    acts.append(_MOVE_LETTER[(b // cols - a // cols, b % cols - a % cols)])
            elif rotations and hs is not None and hs[t + 1] != hs[t]:
                acts.append("R" if (hs[t + 1] - hs[t]) % 4 == 1 else "C")
            else:
                acts.append("W")
        out.append("".join(acts))
    return out


def serialise_moves(starts: list[int], moves: list[list[tuple[int, int, int]]], cols: int,
                    rotations: bool, horizon: int) -> list[str]:
    """Per robot an action string (one action per timestep) replaying its moves without a
    collision. ``moves[i]`` = ``[(cell entered, timestep it finished in, finish time), ...]``
    in order (finish times order the visits of a cell: any increasing clock). Each move goes
    at the earliest timestep that is no earlier than the one it finished in, after the
    robot's previous action, and no earlier than the move out of that cell of the robot
    that entered it before. With ``rotations`` a robot faces east at the start and turns
    (``R``, ``C``, a quarter per timestep) just after its previous action to face each
    move; moves are ``F``. Padded with ``W`` to ``horizon`` timesteps, or longer if the
    replay needs it."""
    n = len(starts)
    # every robot's actions: (letter, lower bound, is a move)
    acts: list[list[tuple[str, int, bool]]] = []
    visits: dict[int, list[tuple[float, int, int]]] = defaultdict(list)  # cell -> (when, i, k)
    for i in range(n):
        here, h, seq = starts[i], 0, []
        visits[here].append((-math.inf, i, -1))
        for cell, t, when in moves[i]:
            d = (cell // cols - here // cols, cell % cols - here % cols)
            if rotations:
                want = _STEP.index(d)
                for letter in ("", "R", "RR", "C")[(want - h) % 4]:
                    seq.append((letter, 0, False))
                h = want
                letter = "F"
            else:
                letter = _MOVE_LETTER[d]
            visits[cell].append((when, i, len(seq)))
            seq.append((letter, t, True))
            here = cell
        acts.append(seq)
    leave: dict[tuple[int, int], int] = {}  # (robot, move in) -> its move out
    for i, seq in enumerate(acts):
        last = -1
        for k, (_, _, move) in enumerate(seq):
            if move:
                leave[(i, last)] = k
                last = k
    after: dict[tuple[int, int], tuple[int, int]] = {}  # (i, move) waits for (j, move out)
    for vs in visits.values():
        vs.sort()
        for (_, j, kj), (_, i, ki) in zip(vs, vs[1:], strict=False):
            out = leave.get((j, kj))
            if out is not None:
                after[(i, ki)] = (j, out)
    when_t = [[-1] * len(seq) for seq in acts]
    nxt = [0] * n
    waiting: dict[tuple[int, int], list[int]] = defaultdict(list)
    stack = list(range(n))
    while stack:
        i = stack.pop()
        seq = acts[i]
        while nxt[i] < len(seq):
            k = nxt[i]
            t0 = when_t[i][k - 1] + 1 if k else 0
            dep = after.get((i, k))
            if dep is not None:
                tj = when_t[dep[0]][dep[1]]
                if tj < 0:
                    waiting[dep].append(i)
                    break
                t0 = max(t0, tj)
            when_t[i][k] = max(t0, seq[k][1])
            nxt[i] += 1
            stack.extend(waiting.pop((i, k), ()))
    if any(nxt[i] < len(acts[i]) for i in range(n)):  # pragma: no cover - a cycle
        raise ValueError("the moves' order of visits has a cycle: not a run of bodies")
    length = max([horizon] + [w[-1] + 1 for w in when_t if w])
    rows = []
    for i in range(n):
        row = ["W"] * length
        for (letter, _, _), t in zip(acts[i], when_t[i], strict=True):
            row[t] = letter
        rows.append("".join(row))
    return rows


def _physics_rows(result: EpisodeResult, log, cols: int, rotations: bool) -> list[str]:
    """Each robot's moves from the executor's finished actions (:class:`~warerover_phys.
    executors.causes.CauseLog`), serialised (:func:`serialise_moves`)."""
    n = len(result.actual)
    moves: list[list[tuple[int, int, int]]] = [[] for _ in range(n)]
    order = np.lexsort((log.seq, log.agv))
    for j in order.tolist():
        if log.src[j] != log.dst[j]:
            fin = int(log.finish_step[j])
            moves[int(log.agv[j])].append((int(log.dst[j]),
                                           max(0, (fin - 1) // log.steps_per_tick), fin))
    starts = [result.actual[i][0][1] for i in range(n)]
    return serialise_moves(starts, moves, cols, rotations, result.world.tick)


def _planned_rows(result: EpisodeResult, cols: int, rotations: bool, horizon: int) -> list[str]:
    """Each robot's planned action per timestep: the first action of the path committed
    at that timestep (``W`` where none)."""
    n = len(result.actual)
    rows = [["W"] * horizon for _ in range(n)]
    for p in result.planned:
        t, states, hs = p["tick"], p["states"], p.get("headings")
        if not 0 <= t < horizon or len(states) < 2:
            continue
        a, b = states[0][1], states[1][1]
        if a != b:
            rows[p["agv"]][t] = "F" if rotations else \
                _MOVE_LETTER[(b // cols - a // cols, b % cols - a % cols)]
        elif rotations and hs is not None and hs[1] != hs[0]:
            rows[p["agv"]][t] = "R" if (hs[1] - hs[0]) % 4 == 1 else "C"
    return ["".join(r) for r in rows]


def output_json(result: EpisodeResult, problem: LorrProblem, *, rotations: bool,
                executor=None) -> dict[str, Any]:
    """The start kit's output JSON of a finished run (see the module docstring).
    ``executor``: the run's executor, whose finished actions give a physics run's
    ``actualPaths`` (None or a grid executor: the executed states). Which start-kit version
    each field follows: :mod:`warerover_phys.lorr_fields`."""
    from .. import lorr_fields as lf

    cols = problem.grid.cols
    n = problem.team_size
    horizon = result.world.tick
    log = executor.cause_log() if executor is not None and \
        hasattr(executor, "cause_log") else None
    actual = _grid_rows(result, cols, rotations) if log is None else \
        _physics_rows(result, log, cols, rotations)
    events, schedule, busy = _task_events(result, n)
    orders = result.world.orders
    cells = {k: order.errands for k, order in orders.items()}
    errands = {k: len(c) for k, c in cells.items()}
    v2023 = problem.version is None
    return {
        "actionModel": "MAPF_T" if rotations else "MAPF",
        "version": problem.version or "2023 LoRR",
        "teamSize": n,
        "start": [[s // cols, s % cols, HEADINGS[0]] for s in problem.starts],
        "numTaskFinished": len(result.world.completed_tick),
        **lf.cost_fields(busy),
        "actualPaths": [",".join(r) for r in actual],
        "plannerPaths": [",".join(r) for r in _planned_rows(result, cols, rotations, horizon)],
        "plannerTimes": [round(s, 6) for s in result.plan_s],
        "errors": [],
        "events": lf.events_2023(events, errands, n) if v2023 else lf.events_2024(events),
        "tasks": lf.tasks_field({k: o.tick for k, o in orders.items()}, cells, cols,
                                version_2023=v2023),
        "actualSchedule": lf.schedule_strings(schedule),
    }


def write_output_json(doc: dict[str, Any], path: str | Path) -> None:
    """Write ``doc`` (:func:`output_json`) to ``path``: ``json.dumps`` of it and a newline."""
    Path(path).write_text(json.dumps(doc) + "\n", encoding="utf-8")
