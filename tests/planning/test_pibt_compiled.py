"""The loop's compiled lifelong PIBT for 1x1 fleets (:mod:`warerover_phys.planning.
pibt_compiled`) against the Python reference step of :class:`PIBTPlanner`: whole warehouse
episodes (loaded AGVs on the loaded graph, held AGVs working in place, corridors that change
the graphs) plan the same paths tick by tick; every executed state is checked by the
independent validator."""

from __future__ import annotations

import pytest

from warerover_phys import load_scenario
from warerover_phys.config import parse_override
from warerover_phys.planning.pibt import compiled as pibt_compiled
from warerover_phys.planning.pibt.planner import PIBTPlanner
from warerover_phys.sim import Simulation
from warerover_phys.validate import validate_states


def _episode(path: str, engine: str, *sets: str):
    sc = load_scenario(path, [parse_override(s) for s in ("planner=pibt", *sets)])
    sim = Simulation(sc, planner=PIBTPlanner(engine=engine))
    return sim.run()


@pytest.mark.parametrize("path,sets", [
    ("layouts/paper_homogeneous.yaml", ()),
    ("layouts/warerover_basic.yaml", ("max_ticks=150",)),
    ("layouts/paper_fault.yaml", ()),
    ("layouts/industrial.yaml", ("max_ticks=40",)),
])
def test_compiled_step_plans_what_the_reference_plans(path, sets, monkeypatch):
    calls = []
    plan = pibt_compiled.CompiledStep.plan
    monkeypatch.setattr(pibt_compiled.CompiledStep, "plan",
                        lambda self, *a: calls.append(1) or plan(self, *a))
    fast = _episode(path, "numba", *sets)
    assert len(calls) == fast.metrics["ticks"]  # the compiled step planned every tick
    ref = _episode(path, "python", *sets)
    assert fast.planned == ref.planned
    assert fast.actual == ref.actual
    assert fast.metrics["orders_completed"] == ref.metrics["orders_completed"] > 0
    w = fast.world
    assert any(a.loaded for a in w.agvs) or fast.metrics["orders_completed"] > 0
    assert validate_states(fast.actual, w.layout.grid == 1) == []
