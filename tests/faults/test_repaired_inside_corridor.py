"""An AGV repaired inside another AGV's open corridor (issue 31): it was down when that
corridor opened, so it was not caught then; when it is repaired it is caught, with the
bounded exit time any AGV caught by an opening corridor gets, not counted as an intruder.

``paper_fault.yaml`` on physics, seed 11: AGV 8 fails at tick 115 (repair at 155); AGV 7
fails at tick 122 and its corridor (id 8) covers AGV 8; AGV 8 is repaired at 155 inside it.
Before: 1 intrusion, 7 AGV-seconds. Now: caught at 155 (``repaired_inside``), out within
its bound, no intrusion.
"""

from __future__ import annotations

from pathlib import Path

from warerover_phys import load_scenario, run_episode

LAYOUTS = Path(__file__).resolve().parents[2] / "layouts"


def test_an_agv_repaired_inside_a_corridor_is_caught_not_an_intruder():
    sc = load_scenario(LAYOUTS / "paper_fault.yaml",
                       [("executor.name", "physics"), ("max_ticks", 170)])
    result = run_episode(sc, seed=11)
    events = result.events
    opened = [e for e in events if e["event"] == "corridor_opened" and e["agv"] == 7
              and e["tick"] == 122]
    assert opened, "the set-up moved: AGV 7 no longer fails at tick 122"
    cid = opened[0]["corridor"]
    caught = [e for e in events if e["event"] == "corridor_caught" and e["agv"] == 8
              and e["corridor"] == cid]
    assert [(e["tick"], e["reason"]) for e in caught] == [(155, "repaired_inside")]
    exits = [e for e in events if e["event"] == "corridor_exit" and e["agv"] == 8
             and e["corridor"] == cid]
    assert exits and exits[0]["within"] and exits[0]["exit_s"] <= caught[0]["bound_s"]
    assert not [e for e in events if e["event"] == "corridor_intrusion" and e["agv"] == 8]
    m = result.metrics
    assert m["corridor_intrusions"] == 0 and m["corridor_intrusion_agv_s"] == 0
    assert m["corridor_caught_inside"] == m["corridor_exits_within_bound"] + \
        m["corridor_exits_overrun"]
