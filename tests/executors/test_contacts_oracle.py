"""The physics executor's contact figures against contacts recomputed with shapely from
the recorded poses (``tests/contacts_oracle.py``: the poses of ``trajectories.npz`` and
the layout's obstacle, edge and shelf polygons, none of the executor's code).

Recorded at every physics step, the poses are those the engine checks, so the two must
agree exactly: every ``static_contact`` / ``contact`` event of the executor falls on an
overlap here, every overlap that begins here has its event, the counts are zero together,
and the smallest AGV-AGV clearance is the same number. Run on the shipped scenarios with
random delays and failures on (where the counts are zero: the check is that nothing is
hidden and nothing invented), and on hand-built cases where contacts do happen: a long
AGV turning in place between walls, two AGVs driven into each other without the
dependency graph.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from contacts_oracle import agv_overlaps, min_agv_clearance, run_starts, static_overlaps

from warerover_phys import load_scenario, run_episode
from warerover_phys.config import AgvTypeSpec, ExecutorSpec
from warerover_phys.execute import load_floor
from warerover_phys.executors.bodies import SHELF_SIDE
from warerover_phys.gap.ideal_plan import TimedPlan
from warerover_phys.gap.open_loop import execute_timed
from warerover_phys.planning.paths import TimedPath

LAYOUTS = Path(__file__).resolve().parents[2] / "layouts"
DT = 0.02
EVERY_STEP = [("executor.name", "physics"), ("executor.dt_s", DT),
              ("executor.trajectory_hz", 1 / DT)]
DELAYS = [("executor.delays.model", "bernoulli"), ("executor.delays.prob", 0.02),
          ("executor.delays.min_ticks", 1), ("executor.delays.max_ticks", 3)]
FAULTS = [("faults.random.prob_per_tick", 0.01), ("faults.random.repair_ticks", 20)]


def sample_of(t_s: float) -> int:
    """The sample holding the poses an event at ``t_s`` was found at: an event carries the
    time its step began, a sample the time its step ended (sample 0 ends at ``DT``)."""
    return int(round(t_s / DT))


def sample_times(traj: dict) -> np.ndarray:
    t = np.asarray(traj["t"], dtype=float)
    steps = np.rint(t / DT).astype(int)
    assert np.array_equal(steps, np.arange(1, len(t) + 1)), "a sample per physics step"
    return steps


def check_static(traj: dict, layout, events: list[dict], count: int) -> list:
    """The executor's wall and edge contacts (events ``static_contact``) and its static
    count against the recomputed overlaps; returns the overlaps."""
    sample_times(traj)
    found = static_overlaps(traj, layout)
    walls = [(t, i) for t, i, what in found if not what.startswith("shelf")]
    touching = set(walls)
    got = {(sample_of(e["t_s"]), e["agv"]) for e in events if e["event"] == "static_contact"}
    # every event is an overlap here
    assert touching >= got, sorted(got - touching)[:10]
    # every overlap that begins (the AGV touched nothing the step before) has its event
    begins = set(run_starts(walls))
    assert begins <= got, sorted(begins - got)[:10]
    assert (count > 0) == bool(found), (count, found[:10])
    return found


def check_agvs(traj: dict, events: list[dict], count: int) -> list:
    found = agv_overlaps(traj)
    touching = set(found)
    got = {(sample_of(e["t_s"]), *sorted(e["agvs"])) for e in events
           if e["event"] == "contact"}
    assert touching >= got, sorted(got - touching)[:10]
    begins = set(run_starts(found))
    assert begins <= got, sorted(begins - got)[:10]
    assert (count > 0) == bool(found), (count, found[:10])
    return found


def test_the_oracle_shelf_side_is_the_models():
    import contacts_oracle

    assert contacts_oracle.SHELF_SIDE == SHELF_SIDE


SHIPPED = [pytest.param("paper_heterogeneous", DELAYS + FAULTS, 150, id="paper_heterogeneous"),
           pytest.param("paper_fault", DELAYS, None, id="paper_fault",
                        marks=pytest.mark.slow)]  # a whole episode: make test-all
SHIPPED_SLOW = [pytest.param(name, DELAYS + FAULTS, None, marks=pytest.mark.slow, id=name)
                for name in ("paper_homogeneous", "paper_heterogeneous", "warerover_basic",
                             "warerover_hetero")]


@pytest.mark.parametrize("name,extra,max_ticks", SHIPPED + SHIPPED_SLOW)
def test_shipped_scenarios_contacts_match_the_recorded_poses(name, extra, max_ticks):
    over = EVERY_STEP + extra + ([("max_ticks", max_ticks)] if max_ticks else [])
    result = run_episode(load_scenario(LAYOUTS / f"{name}.yaml", over), seed=1)
    m, traj, events = result.metrics, result.trajectory, result.events
    # delays and failures did happen
    assert any(e["event"] == "delay" for e in events)
    assert m["failures"] > 0
    check_static(traj, result.world.layout, events, m["static_contacts"])
    check_agvs(traj, events, m["agv_contacts"])
    assert math.isclose(min_agv_clearance(traj, 1.0), m["min_clearance_m"], abs_tol=1e-9)


def floor(rows: list[str]):
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "floor.map"
        p.write_text(f"type octile\nheight {len(rows)}\nwidth {len(rows[0])}\nmap\n"
                     + "\n".join(rows) + "\n")
        layout, _, _ = load_floor(p)
    return layout


def run_plan(rows, cells_by_agv, body_m, adg: bool = True):
    layout = floor(rows)
    spec = AgvTypeSpec(body_m=body_m, max_speed_mps=1.5, max_accel_mps2=1.0)
    paths = {i: TimedPath(i, 0, tuple((r * layout.cols + c,) * 2 for r, c in cells))
             for i, cells in enumerate(cells_by_agv)}
    plan = TimedPlan(layout=layout, types=[spec] * len(paths), tick_s=1.0, paths=paths,
                     dwells={}, source="test")
    run = execute_timed(plan, ExecutorSpec(name="physics", dt_s=DT, adg=adg,
                                           trajectory_hz=1 / DT))
    return layout, run


JUNCTION = ["....",
            "@.@@",
            "@.@@"]
"""A T-junction: in along the top row, a turn south at column 1 between walls."""


@pytest.mark.parametrize("body_m,touches", [((0.9, 0.6), True), ((0.95, 0.95), True),
                                            ((0.7, 0.7), False)])
def test_a_long_agv_turning_between_walls_touches_them(body_m, touches):
    """A body whose half diagonal is over half a cell sweeps its corners into the walls
    while it turns in place; a 0.7 m square does not (0.49 m < 0.5 m)."""
    layout, run = run_plan(JUNCTION, [[(0, 0), (0, 1), (1, 1), (2, 1)]], body_m)
    found = check_static(run.trajectory, layout, run.events, run.summary["static_contacts"])
    assert bool(found) == touches
    assert (run.summary["static_contacts"] >= 1) == touches


def test_two_agvs_driven_into_each_other_touch():
    """Head on in a corridor on time-indexed following (no dependency graph): they meet;
    the executor's contact events are the overlaps recomputed here."""
    corridor = ["......"]
    plan = [[(0, 0), (0, 1), (0, 2), (0, 3)], [(0, 5), (0, 4), (0, 3), (0, 2)]]
    _, run = run_plan(corridor, plan, (0.7, 0.7), adg=False)
    found = check_agvs(run.trajectory, run.events, run.summary["agv_contacts"])
    assert found and run.summary["agv_contacts"] >= 1
    assert min_agv_clearance(run.trajectory) == 0.0
