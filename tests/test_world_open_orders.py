"""World.all_done keeps a count of orders not completed instead of scanning every order each
tick (the loop asks once a tick); it must say what the scan said, every tick."""

from __future__ import annotations

from pathlib import Path

import pytest

from warerover_phys import load_scenario
from warerover_phys.sim import Simulation
from warerover_phys.world import OrderStatus

LAYOUTS = Path(__file__).resolve().parents[1] / "layouts"


@pytest.mark.parametrize("layout", ["paper_fault", "warerover_basic"])
def test_all_done_agrees_with_a_scan_every_tick(layout):
    """With failures (orders back to pending) and WareRover's re-queueing (assigned or
    in-progress orders back to pending, possibly completed twice)."""
    sim = Simulation(load_scenario(LAYOUTS / f"{layout}.yaml"), seed=1)
    w = sim.world
    seen_open = False
    while True:
        scan = w.tick > 0 and w.stream.exhausted(w.tick - 1) and all(
            s == OrderStatus.COMPLETED for s in w.status.values())
        assert w.all_done() == scan, f"tick {w.tick}"
        assert w._open == sum(s != OrderStatus.COMPLETED for s in w.status.values())
        seen_open |= w._open > 0
        if sim.done:
            break
        sim.step()
    assert seen_open and w.all_done()
