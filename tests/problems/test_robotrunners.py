"""Robot Runners problems in the one loop (:mod:`warerover_phys.problems.robotrunners`).

- Parity: on the grid, the loop gives the retired runner's actions, tick by tick, on seven
  problems x rules x seeds (``tests/data/lorr_golden``, made by ``tools/lorr_golden.py``).
  The named differences: ``sumOfCost`` follows the start kit (robot-timesteps with a task),
  and errands reached at the last timestep count (the old runner stopped before its check).
- A physics run writes an output whose actual paths replay without collision (an
  independent replay below), whose moves are the bodies' moves, and whose tasks recount.
"""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import pytest

from warerover_phys.problems.robotrunners import (
    output_json,
    problem_scenario,
    read_problem,
    serialise_moves,
)
from warerover_phys.sim import Simulation

DATA = Path(__file__).parent.parent / "data"
GOLDEN = DATA / "lorr_golden"
STEP = ((0, 1), (1, 0), (0, -1), (-1, 0))
MOVE = {"R": (0, 1), "D": (1, 0), "L": (0, -1), "U": (-1, 0)}


def _run(case: dict, executor: str = "grid", ticks: int | None = None, **kw):
    prob = read_problem(DATA / case["problem"])
    sc = problem_scenario(prob, ticks=ticks or case["ticks"], rotations=case["rotations"],
                          rule=case["rule"], seed=case["seed"], executor=executor, **kw)
    sim = Simulation(sc)
    result = sim.run()
    return prob, result, output_json(result, prob, rotations=case["rotations"],
                                     executor=sim.executor)


def replay(doc: dict, obstacles) -> list[list[tuple[int, int]]]:
    """Every robot's cell at every timestep of ``actualPaths`` (independent of the package):
    checks the moves stay on free cells, and that no two robots share a cell or swap
    cells at any timestep."""
    rows, cols = obstacles.shape
    rot = doc["actionModel"] == "MAPF_T"
    pos = [(r, c) for r, c, _ in doc["start"]]
    head = [0] * len(pos)
    paths = [p.split(",") if p else [] for p in doc["actualPaths"]]
    horizon = max(len(p) for p in paths)
    out = [[p] for p in pos]
    for t in range(horizon):
        nxt = list(pos)
        for i, p in enumerate(paths):
            a = p[t] if t < len(p) else "W"
            if rot and a in "RC":
                head[i] = (head[i] + (1 if a == "R" else 3)) % 4
            elif a != "W":
                dr, dc = STEP[head[i]] if rot else MOVE[a]
                nxt[i] = (pos[i][0] + dr, pos[i][1] + dc)
                r, c = nxt[i]
                assert 0 <= r < rows and 0 <= c < cols and not obstacles[r, c], \
                    f"robot {i} leaves the free cells at timestep {t}"
        assert len(set(nxt)) == len(nxt), f"two robots share a cell after timestep {t}"
        where = {c: i for i, c in enumerate(pos)}
        for i in range(len(pos)):
            j = where.get(nxt[i])
            assert not (j is not None and j != i and nxt[j] == pos[i]), \
                f"robots {i} and {j} swap cells at timestep {t}"
        pos = nxt
        for i in range(len(pos)):
            out[i].append(pos[i])
    return out


def recount(doc: dict, cells: list[list[tuple[int, int]]]) -> int:
    """Tasks finished, from the replayed cells, tasks and schedule alone: after taking a
    task at timestep t, a robot does each errand at the first later timestep it stands on
    the errand's cell, in order (one per timestep)."""
    errands = {k: [tuple(flat[j:j + 2]) for j in range(0, len(flat), 2)]
               for k, _, flat in doc["tasks"]}
    finished = 0
    for i, schedule in enumerate(doc["actualSchedule"]):
        for item in filter(None, schedule.split(",")):
            t, k = map(int, item.split(":"))
            todo = list(errands[k])
            for s in range(t + 1, len(cells[i])):
                if cells[i][s] == todo[0]:
                    todo.pop(0)
                    if not todo:
                        finished += 1
                        break
    return finished


@pytest.mark.parametrize("name", sorted(p.name.split(".")[0] for p in GOLDEN.glob("*.json.gz")))
def test_the_loop_gives_the_retired_runners_actions(name):
    gold = json.load(gzip.open(GOLDEN / f"{name}.json.gz", "rt"))
    case = gold["case"]
    prob, result, doc = _run(case)
    for key in ("actualPaths", "plannerPaths", "tasks", "actualSchedule", "start", "version",
                "actionModel", "teamSize", "makespan"):
        assert doc[key] == gold[key], f"{key} differs from the retired runner's"
    # events: the same up to the last timestep; the loop also counts errands reached by the
    # last move (the start kit checks tasks after every move)
    ticks = case["ticks"]
    assert [e for e in doc["events"] if e[0] < ticks] == gold["events"]
    late = [e for e in doc["events"] if e[0] >= ticks]
    assert all(e[0] == ticks and e[3] > 0 for e in late)
    done_late = sum(1 for e in late if e[3] == len(prob.tasks[e[2] % len(prob.tasks)]))
    assert doc["numTaskFinished"] == gold["numTaskFinished"] + done_late
    # the kit's sum of cost: a robot-timestep counts while the robot has a task
    if prob.strategy in ("roundrobin", "greedy"):
        assert doc["sumOfCost"] == prob.team_size * ticks


def test_physics_output_replays_without_collision_and_recounts():
    case = {"problem": "lorr2023_warehouse_small/warehouse_small_50.json", "ticks": 120,
            "seed": 1, "rotations": True, "rule": "actions"}
    prob, result, doc = _run(case, executor="physics")
    assert doc["teamSize"] == 50 and doc["actionModel"] == "MAPF_T"
    assert result.metrics["agv_contacts"] == 0
    cells = replay(doc, prob.grid.obstacles)
    cols = prob.grid.cols
    for i in range(50):
        # the replay ends where the body ends up (its last cell entered)
        executed = [s for s in result.actual[i]]
        last = executed[-1][0] if executed[-1][0] != executed[-1][1] else executed[-1][1]
        assert cells[i][-1] == divmod(last, cols)
        # and visits the cells the body visited, in order
        seen = [divmod(s[1], cols) for s in executed if s[0] == s[1]]
        dedup = [c for k, c in enumerate(cells[i]) if k == 0 or c != cells[i][k - 1]]
        seen = [c for k, c in enumerate(seen) if k == 0 or c != seen[k - 1]]
        it = iter(dedup)
        assert all(c in it for c in seen), f"robot {i} replays other cells"
    assert doc["numTaskFinished"] == len(result.world.completed_tick) > 0
    assert recount(doc, cells) >= doc["numTaskFinished"] - 50  # tasks under way at the end


def test_grid_output_replays_and_recounts_exactly():
    case = {"problem": "lorr2023_warehouse_small/warehouse_small_50.json", "ticks": 80,
            "seed": 2, "rotations": True, "rule": "turn-first"}
    prob, result, doc = _run(case)
    cells = replay(doc, prob.grid.obstacles)
    cols = prob.grid.cols
    assert [[divmod(s[1], cols) for s in result.actual[i]] for i in range(50)] == cells
    assert recount(doc, cells) == doc["numTaskFinished"] > 0


def test_serialised_moves_keep_the_order_of_visits():
    """Two robots in a 1 x 4 corridor (cells 0-3): B (at 2) leaves for 3, A (at 1) follows
    into 2, both finishing in timestep 0 (A's finish later): A cannot go before B."""
    rows = serialise_moves([1, 2], [[(2, 0, 9)], [(3, 0, 5)]], 4, False, 2)
    assert rows == ["RW", "RW"]
    # A finishes two moves in timestep 0: the second goes to timestep 1
    rows = serialise_moves([0], [[(1, 0, 3), (2, 0, 7)]], 4, True, 1)
    assert rows == ["FF"]
    # with rotations, a robot turns (just after its previous action) to face its move
    rows = serialise_moves([1], [[(0, 3, 90)]], 4, True, 1)
    assert rows == ["RRWF"]


def test_same_seed_same_run():
    case = {"problem": "lorr2026_warehouse_fulfill/fulfill_200.json", "ticks": 40, "seed": 5,
            "rotations": True, "rule": "actions"}
    a = _run(case)[2]
    b = _run(case)[2]
    for key in ("actualPaths", "events", "tasks", "numTaskFinished", "sumOfCost"):
        assert a[key] == b[key]
