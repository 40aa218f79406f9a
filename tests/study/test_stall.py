"""A plan whose open-loop execution stalled without a contact or a deadlock (issue 33's
trade-offs study: ``lacam-lns`` on random-32-32-10-random-3 with 200 agents, the
``slow-turner`` robots turning and accelerating 20% slower than planned).

What happened: the plan follower decides for standing *and turning* AGVs every decision
step. AGV 102 was decided in the last step of its turn, found its next cell still held and
was put to sleep (``_asleep``, registered on that cell's queue); in the same physics step
its turn ended, the cell had been left meanwhile, and the end-of-turn decision started the
move. The sleep flag stayed set while it drove. At its next stop the follower took it for
a sleeper whose wake-up was already spent, never decided for it again, and the 29 AGVs
queued behind it (directly or through others) waited for ever: no cycle in the wait-for
graph, so no deadlock report, and no contact. The fix clears the flag when an action starts
(``PlanFollower._start``)."""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from warerover_phys.study import load_study, run_study

DATA = Path(__file__).resolve().parents[1] / "data"
STALL = DATA / "study_stall"


def test_a_move_started_at_the_end_of_a_turn_does_not_leave_the_agv_asleep(tmp_path):
    spec = {"name": "stall",
            "instances": [{"map": str(DATA / "random-32-32-10.map"),
                           "scens": [str(STALL / "random-32-32-10-random-3.scen")],
                           "agents": [200]}],
            "planners": {"lacam-lns": {"plans": str(STALL), "pattern": "{scen}-{n}.txt"}},
            "robots": {"slow-turner": {"max_speed_mps": 1.0, "max_accel_mps2": 1.0,
                                       "max_turn_rate_radps": 0.8, "body_m": [0.7, 0.7]}},
            "mismatch": {"slower": {"turn_rate": 0.8, "accel": 0.8}},
            "execution": {"tick_s": 1.0, "dt_s": 0.1, "trajectory_hz": 1.0}}
    path = tmp_path / "stall.yaml"
    path.write_text(yaml.safe_dump(spec), encoding="utf-8")
    run_study(load_study(path), tmp_path / "out", workers=1)
    rows = [json.loads(x) for x in (tmp_path / "out" / "results.jsonl").read_text().splitlines()]
    assert len(rows) == 1
    row = rows[0]
    assert row["status"] == "ok", row["error"]
    assert row["completed"] and row["deadlocks"] == 0 and row["agv_contacts"] == 0
    # every agent finished: the executed makespan is the last finish, above the planned one
    assert row["executed_makespan_s"] >= row["planned_makespan_s"] > 0
