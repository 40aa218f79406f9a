"""Each second of lost time is charged to the right cause, on hand-built cases whose causes
are known beforehand.

``test_gap_open.py`` checks that the parts add up; these check *which* part gets the time:
an AGV held up by another for exactly 3 s more (by a failure or by an injected delay of
the one ahead), a single turn in place whose duration is angle / turn rate, a one-cell
move from rest whose duration is ``2 sqrt(d / a)``. The expected figures come from the
case (the held seconds, the kinematics), not from the executor's records.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import pytest

from warerover_phys.config import AgvTypeSpec, ExecutorSpec
from warerover_phys.execute import load_floor
from warerover_phys.gap.ideal_plan import Failure, TimedPlan
from warerover_phys.gap.open_loop import PARTS, compare, execute_timed
from warerover_phys.planning.paths import TimedPath

DT = 0.02
"""The physics step (``executor.dt_s``): labels are whole steps, so a duration that
falls inside a step is matched to within one step."""
PHYSICS = ExecutorSpec(name="physics", dt_s=DT)
OPEN = ["......", "......", "......"]
AHEAD = [(0, 1), (0, 2), (0, 3), (0, 4), (0, 5)]
BEHIND = [(0, 0), (0, 1), (0, 2), (0, 3), (0, 4)]
"""Two AGVs in a row, the one behind entering each cell the tick the one ahead leaves it
(a plan without waits: any hold-up of the one ahead is the one behind's dependency)."""


def floor(rows: list[str]):
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "floor.map"
        p.write_text(f"type octile\nheight {len(rows)}\nwidth {len(rows[0])}\nmap\n"
                     + "\n".join(rows) + "\n")
        layout, _, _ = load_floor(p)
    return layout


def plan(cells_by_agv: list[list[tuple[int, int]]], spec: AgvTypeSpec | None = None,
         failures: tuple[Failure, ...] = ()) -> TimedPlan:
    """One cell per tick along each list (1 m cells, 1 s ticks), no dwells."""
    layout = floor(OPEN)
    spec = spec or AgvTypeSpec(body_m=(0.7, 0.7), max_speed_mps=1.5, max_accel_mps2=1.0)
    nodes = [[r * layout.cols + c for r, c in cells] for cells in cells_by_agv]
    paths = {i: TimedPath(i, 0, tuple((n, n) for n in ns)) for i, ns in enumerate(nodes)}
    return TimedPlan(layout=layout, types=[spec] * len(paths), tick_s=1.0, paths=paths,
                     dwells={}, source="test", failures=failures)


def parts(run) -> list[dict[str, float]]:
    agents, _, _ = compare(run)
    assert all(a["completed"] for a in agents)
    return [{p: a[f"lost_{p}_s"] for p in PARTS} | {"lost": a["lost_s"]} for a in agents]


def changed(a: dict, b: dict) -> dict[str, float]:
    """The parts that differ between two runs, and by how much (b - a)."""
    return {k: round(b[k] - a[k], 9) for k in a if not math.isclose(a[k], b[k], abs_tol=1e-9)}


@pytest.fixture(scope="module")
def in_a_row():
    """The pair in a row, executed as planned (the one behind already waits a little: the
    one ahead takes longer than a tick to get going)."""
    return parts(execute_timed(plan([AHEAD, BEHIND]), PHYSICS))


def test_a_failure_ahead_is_three_seconds_of_dependency_behind(in_a_row):
    """The one ahead is down for 3 ticks before its first move: it loses exactly 3 s to
    ``failures``, the one behind exactly 3 s more to ``dependency``, nothing else moves."""
    run = execute_timed(plan([AHEAD, BEHIND], failures=(Failure(0, 0, 3),)), PHYSICS)
    ahead, behind = parts(run)
    assert changed(in_a_row[0], ahead) == {"failures": 3.0, "lost": 3.0}
    assert changed(in_a_row[1], behind) == {"dependency": 3.0, "lost": 3.0}


def test_an_injected_delay_ahead_is_three_seconds_of_dependency_behind(in_a_row):
    """The same hold-up as an injected delay (``executor.delays``' mechanism, set by hand
    for 3 s at the start): ``injected`` ahead, ``dependency`` behind, 3 s each."""
    def delay_the_one_ahead(tick, ex):
        if tick == 0:
            ex.delayed_until[0] = ex.sim_s + 3.0

    run = execute_timed(plan([AHEAD, BEHIND]), PHYSICS, before_tick=delay_the_one_ahead)
    ahead, behind = parts(run)
    assert changed(in_a_row[0], ahead) == {"injected": 3.0, "lost": 3.0}
    assert changed(in_a_row[1], behind) == {"dependency": 3.0, "lost": 3.0}


def test_the_one_behind_waits_on_the_one_ahead_only(in_a_row):
    ahead, behind = in_a_row
    assert ahead["dependency"] == 0.0 and behind["dependency"] > 0.5
    for p in ("turning", "injected", "failures"):
        assert ahead[p] == behind[p] == 0.0


@pytest.mark.parametrize("rate", [2.5, 1.0])
@pytest.mark.parametrize("cells,angle", [
    ([(0, 0), (0, 1), (0, 2), (1, 2), (2, 2)], math.pi / 2),   # east, then south
    ([(1, 0), (1, 1), (1, 2), (1, 1), (1, 0)], math.pi),       # east, then back west
])
def test_a_single_turn_is_charged_its_duration_as_turning(cells, angle, rate):
    """One turn in place: ``turning`` is angle / turn rate (to a step); no dependency,
    injection or failure on a lone AGV."""
    spec = AgvTypeSpec(body_m=(0.7, 0.7), max_speed_mps=1.5, max_accel_mps2=1.0,
                       max_turn_rate_radps=rate)
    (a,) = parts(execute_timed(plan([cells], spec), PHYSICS))
    assert abs(a["turning"] - angle / rate) <= DT + 1e-9, (a["turning"], angle / rate)
    assert a["dependency"] == a["injected"] == a["failures"] == 0.0
    assert a["accel_decel"] > 0  # it stops for the turn and starts again


@pytest.mark.parametrize("accel", [1.0, 0.5])
def test_a_move_from_rest_is_charged_its_extra_time_as_accel_decel(accel):
    """One cell (1 m) from rest to rest under acceleration ``a`` (top speed not reached):
    ``2 sqrt(1 / a)`` seconds against the plan's one tick; the extra is ``accel_decel``,
    the only part."""
    spec = AgvTypeSpec(body_m=(0.7, 0.7), max_speed_mps=1.5, max_accel_mps2=accel)
    (a,) = parts(execute_timed(plan([[(0, 0), (0, 1)]], spec), PHYSICS))
    want = 2 * math.sqrt(1.0 / accel) - 1.0
    assert abs(a["accel_decel"] - want) <= DT + 1e-9, (a["accel_decel"], want)
    assert {p for p, v in a.items() if v and p != "lost"} == {"accel_decel"}


def test_a_three_cell_run_is_charged_the_trapezoid_it_drives():
    """Three cells (3 m) at 1.5 m/s and 1 m/s^2: 3 / 1.5 + 1.5 / 1 = 3.5 s against 3
    ticks: 0.5 s lost, all of it driving (``accel_decel`` + ``faster_than_plan``)."""
    (a,) = parts(execute_timed(plan([[(0, 0), (0, 1), (0, 2), (0, 3)]]), PHYSICS))
    assert abs(a["lost"] - 0.5) <= DT + 1e-9, a
    assert abs(a["accel_decel"] + a["faster_than_plan"] - a["lost"]) <= 1e-9, a
