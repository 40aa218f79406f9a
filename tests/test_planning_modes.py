"""tools/planning_modes.py (issue 15): a unit-timing mode is read off its motion twin's run
(the same plan), and reads the same as a run of its own."""

from __future__ import annotations

import math

import pytest
from tool_helpers import load_tool

from warerover_phys import load_scenario
from warerover_phys.gap.open_loop import MOTION_UNIT_KEYS
from warerover_phys.gap.stats import seed_gap


def _tool():
    return load_tool("planning_modes")


pm = _tool()


def test_each_plan_runs_once_unless_asked():
    every = list(pm.MODES)
    assert pm.plan_runs(every) == {"plain": "motion", "rotations": "rotations+motion",
                                   "motion": "motion",
                                   "rotations+motion": "rotations+motion"}
    assert pm.plan_runs(every, run_all=True) == {m: m for m in every}
    # without its twin a unit-timing mode runs on its own
    assert pm.plan_runs(["plain", "rotations+motion"]) == {
        "plain": "plain", "rotations+motion": "rotations+motion"}


def test_unit_report_puts_the_unit_figures_back():
    rep = {"timing": "motion", "executed_makespan_s": 12.0, "orders": 3,
           "executed_orders_makespan_s": 10.0}
    for i, k in enumerate(MOTION_UNIT_KEYS):
        rep[k], rep[f"{k}_unit"] = 100.0 + i, 200.0 + i
    unit = pm.unit_report(rep)
    assert unit["timing"] == "unit"
    assert all(unit[k] == 200.0 + i for i, k in enumerate(MOTION_UNIT_KEYS))
    assert not any(k.endswith("_unit") for k in unit)
    assert unit["executed_makespan_s"] == 12.0
    assert pm.unit_report({"timing": "unit", "makespan_ratio": 1.5}) == {
        "timing": "unit", "makespan_ratio": 1.5}


@pytest.mark.slow
@pytest.mark.parametrize("twin", ["plain", "rotations"])
def test_twin_reads_as_its_own_run(twin):
    """The figures of ``plain`` (``rotations``) read off a ``motion``
    (``rotations+motion``) run equal those of a run of its own, same seed."""
    path, extra = "layouts/paper_homogeneous.yaml", [("max_ticks", 40)]
    own = seed_gap((load_scenario(path, extra + pm.MODES[twin]), 1, "open"))["report"]
    src = pm.UNIT_TWIN[twin]
    via = seed_gap((load_scenario(path, extra + pm.MODES[src]), 1, "open"))["report"]
    a, b = pm._figures(own), pm._figures(pm.unit_report(via))
    assert via["timing"] == "motion" and own["timing"] == "unit"
    assert a.keys() == b.keys()
    for k in a:
        if a[k] is None or (isinstance(a[k], float) and math.isnan(a[k])):
            assert b[k] is None or math.isnan(b[k]), k
        else:
            assert b[k] == pytest.approx(a[k], rel=1e-12, abs=1e-12), k
