"""The session adapter: stepping, snapshots, on-demand faults, orders, restart."""

from __future__ import annotations

import numpy as np
import pytest

from warerover_phys.serve.protocol import FRAME_MAGIC, encode_frame
from warerover_phys.serve.session import NO_NODE, LiveSession

from .conftest import REPO


@pytest.fixture
def session(tmp_path):
    return LiveSession.from_default(tmp_path)


def test_step_and_snapshot(session):
    assert session.step(5) == 5
    snap = session.snapshot()
    n = len(session.sim.world.agvs)
    assert snap.tick == 5 and snap.x.shape == (n,) and snap.paths.shape == (n, 8)
    lay = session.sim.world.layout
    assert (snap.x > 0).all() and (snap.x < lay.cols * lay.cell_m).all()
    planned = snap.paths[snap.paths != NO_NODE]
    assert len(planned) and planned.max() < lay.rows * lay.cols


def test_frame_layout(session):
    session.step(3)
    snap = session.snapshot()
    frame = encode_frame(snap, 1.0, 10.0)
    n, h = len(snap.x), snap.paths.shape[1]
    assert int.from_bytes(frame[:4], "little") == FRAME_MAGIC
    pad = (-2 * n) % 4
    assert len(frame) == 36 + 12 * n + 2 * n + pad + 4 * n * h
    x = np.frombuffer(frame, "<f4", n, 36)
    assert np.allclose(x, snap.x, atol=1e-5)


def test_fail_opens_corridor_and_repair_closes_it(session):
    session.step(3)
    session.fail(4)
    st = session.status()
    assert st["failed"] == [4]
    assert [c["agv"] for c in st["corridors"]] == [4]
    assert st["corridors"][0]["zone"], "corridor polygon missing"
    with pytest.raises(ValueError, match="already failed"):
        session.fail(4)
    session.step(2)
    session.repair(4)
    st = session.status()
    assert st["failed"] == [] and st["corridors"] == []
    with pytest.raises(ValueError, match="does not exist"):
        session.fail(99)


def test_add_orders_are_served(session):
    ids = session.add_orders(3, station=0)
    assert ids == [1_000_000, 1_000_001, 1_000_002]
    session.step(150)
    done = session.sim.world.completed_tick
    assert all(i in done for i in ids)
    with pytest.raises(ValueError):
        session.add_orders(1, station=999)


def test_restart_switches_executor(session):
    session.step(2)
    v = session.scene_version
    session.restart(executor="physics", seed=3)
    assert session.executor_name == "physics" and session.scene_version == v + 1
    assert session.sim.world.tick == 0
    session.step(3)
    snap = session.snapshot()
    assert np.isfinite(snap.x).all()
    info = session.agv_info(0)
    assert info["id"] == 0 and "waiting_for" in info and info["speed_mps"] >= 0


def test_restart_with_a_bad_planner_keeps_the_episode(session):
    from warerover_phys.errors import WareroverError

    session.step(4)
    with pytest.raises((WareroverError, ValueError)):
        session.restart(planner="nosuchplanner")
    assert session.sim.world.tick == 4
    session.restart()
    assert session.scenario.planner.name == "astar"


def test_scenario_file(tmp_path):
    s = LiveSession(REPO / "layouts" / "paper_heterogeneous.yaml", tmp_path)
    scene = s.scene()
    assert {a["k"] for a in scene["agvs"]} == {1, 2}
    assert any(sh[2] == 2 for sh in scene["shelves"])
    s.step(4)
    assert s.recording().x.shape[1] == len(scene["agvs"])
