"""Issue 13, fault 5 and the corridor records: every AGV-second inside a corridor counts;
an AGV caught inside gets a bounded exit time; ``trajectories.npz`` lets an outside checker
recompute the figures with shapely."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from warerover_phys import load_scenario, scenario_from_dict
from warerover_phys.sim import Simulation

SMALL = ["..........", "..SS.SS...", ".........R", "..SS.SS...", "P...P...P."]


def caught_sim(executor: str, **faults) -> Simulation:
    """AGV 1 stands idle at (2, 4), one cell from AGV 0 at (2, 3): AGV 0's corridor (to
    the access cell (0, 4)) covers it."""
    return Simulation(scenario_from_dict({
        "layout": {"grid": SMALL},
        "fleet": {"agvs": [{"count": 3, "starts": [[2, 3], [2, 4], [0, 0]]}]},
        "orders": {"pattern": "oneshot", "oneshot": {"count": 1}},
        "executor": executor, "faults": faults}), seed=0)


@pytest.mark.parametrize("executor", ["grid", "physics"])
def test_agv_caught_in_a_corridor_is_sent_out_within_its_bound(executor):
    """Fails on main before the exit requests: the idle AGV caught inside waited for the
    repair and overran its bound. Now the loop plans it to the nearest free spot outside
    and it leaves within the bound."""
    sim = caught_sim(executor)
    w = sim.world
    sim.fail(0, repair_ticks=30)
    (grant,) = w.corridor_book.grants.values()
    m = sim.run().metrics
    assert m["corridor_caught_inside"] == 1 == m["corridor_exits_within_bound"]
    assert m["corridor_exits_overrun"] == 0 and m["corridor_intrusions"] == 0
    assert m["corridor_intrusion_agv_s"] == 0.0
    assert 0 < m["corridor_exit_max_s"] <= grant.bound_s
    sent = [e for e in w.events if e["event"] == "corridor_exit_sent"]
    assert sent and sent[0]["agv"] == 1 and sent[0]["corridor"] == grant.corridor
    spot = tuple(sent[0]["spot"])
    assert w.node(spot) not in w.corridor_log[0]["cells"]
    (done,) = [e for e in w.events if e["event"] == "corridor_exit"]
    assert done["within"] and not done["closed"]


@pytest.mark.parametrize("executor", ["grid", "physics"])
def test_agv_left_standing_in_a_corridor_is_an_intrusion_after_its_bound(executor,
                                                                          monkeypatch):
    """Before the fix: 0 intrusions (an AGV inside at the opening was exempt as long as it
    stayed). Now its 30 s inside count, less its exit bound. (The loop's exit request is
    switched off here, so that the AGV stays.)"""
    monkeypatch.setattr(Simulation, "_send_out", lambda self: None)
    sim = caught_sim(executor)
    w = sim.world
    sim.fail(0, repair_ticks=30)
    (grant,) = w.corridor_book.grants.values()
    assert (grant.agv, grant.reason) == (1, "inside")
    agv = w.agvs[1]
    spec, sc = agv.spec, w.scenario
    # (cells to drive out + 1) moves at the plan's move time, a half turn, v / a, margin.
    extras = (np.pi / spec.max_turn_rate_radps + spec.max_speed_mps / spec.max_accel_mps2
              + sc.faults.exit_margin_s)
    moves = (grant.bound_s - extras) / (agv.ticks_per_move * sc.tick_s)
    assert moves == pytest.approx(round(moves)) and round(moves) >= 2
    m = sim.run().metrics
    assert m["corridor_caught_inside"] == 1
    assert m["corridor_exits_overrun"] == 1 and m["corridor_exits_within_bound"] == 0
    assert m["corridor_inside_agv_s"] == pytest.approx(30.0)
    # Everything past the deadline counts (to a physics step, or a tick on the grid).
    step = 1.0 if executor == "grid" else sc.executor.dt_s
    assert m["corridor_intrusion_agv_s"] == pytest.approx(30.0 - grant.bound_s, abs=step)
    assert m["corridor_intrusions"] == 1
    names = [e["event"] for e in w.events if e["event"].startswith("corridor")]
    assert names[:4] == ["corridor_opened", "corridor_caught", "corridor_exit_overrun",
                         "corridor_intrusion"]


@pytest.mark.parametrize("executor", ["grid", "physics"])
def test_exit_time_is_configurable(executor, monkeypatch):
    monkeypatch.setattr(Simulation, "_send_out", lambda self: None)  # it stays
    sim = caught_sim(executor, exit_time_s=40.0)
    sim.fail(0, repair_ticks=30)
    m = sim.run().metrics
    assert m["corridor_inside_agv_s"] == pytest.approx(30.0)
    assert m["corridor_intrusion_agv_s"] == 0.0 and m["corridor_intrusions"] == 0
    assert m["corridor_exits_within_bound"] == 1 and m["corridor_exits_overrun"] == 0


def test_exit_options_are_validated():
    from warerover_phys.errors import ScenarioError

    for bad in ({"exit_time_s": 0}, {"exit_time_s": -1.0}, {"exit_margin_s": -0.5},
                {"exit_bound": 3}):
        with pytest.raises(ScenarioError, match="faults"):
            caught_sim("grid", **bad)


def test_grid_executor_checks_corridors_every_tick(monkeypatch):
    """Before the fix the grid executor's reports said metres, so the loop never ran its
    cell check: an AGV standing in a corridor went unseen on the grid."""
    monkeypatch.setattr(Simulation, "_send_out", lambda self: None)  # it stays
    sim = caught_sim("grid")
    sim.fail(0, repair_ticks=5)
    for _ in range(3):
        sim.step()
    assert sim.world.corridor_book.inside_s == pytest.approx(3.0)


# ------------------------------------------------------------------ outside recomputation


def recompute_from_npz(traj: dict) -> tuple[float, float, int]:
    """(inside AGV-s, intrusion AGV-s, samples that changed inside/outside) from the
    exported arrays alone, with shapely: bodies from x, y, heading, body_m."""
    t = np.asarray(traj["t"])
    x, y, h, state = (np.asarray(traj[k]) for k in ("x", "y", "heading", "state"))
    body = np.asarray(traj["body_m"], dtype=float)
    period = float(np.median(np.diff(t)))
    n = x.shape[1]
    sign = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]], dtype=float)
    inside_s = intrusion_s = 0.0
    flips = 0
    grants = {(int(a), int(c)): (float(s), float(b))
              for a, c, s, b in zip(traj["corridor_caught_agv"], traj["corridor_caught_corridor"],
                                    traj["corridor_caught_s"], traj["corridor_caught_bound_s"],
                                    strict=True)}
    for row, cid in enumerate(traj["corridor_id"].tolist()):
        rects = traj["corridor_rects"][traj["corridor_rect_of"] == row]
        person = shapely.union_all(shapely.box(*rects.T))
        margin = float(traj["corridor_margin_m"][row])
        t0 = float(traj["corridor_open_s"][row])
        t1 = float(traj["corridor_close_s"][row])
        t1 = np.inf if np.isnan(t1) else t1
        m = np.flatnonzero((t >= t0 - 1e-9) & (t < t1 - 1e-9))
        for a in range(n):
            if a == int(traj["corridor_agv"][row]) or not len(m):
                continue
            half = (body[m, a] if body.ndim == 3 else np.broadcast_to(body[a], (len(m), 2))) / 2
            c, s = np.cos(h[m, a]), np.sin(h[m, a])
            lx, ly = sign[None, :, 0] * half[:, None, 0], sign[None, :, 1] * half[:, None, 1]
            px = x[m, a][:, None] + c[:, None] * lx - s[:, None] * ly
            py = y[m, a][:, None] + s[:, None] * lx + c[:, None] * ly
            bodies = shapely.polygons(np.stack([px, py], axis=-1))
            inside = (shapely.distance(bodies, person) < margin) & (state[m, a] != 7)
            flips += int(np.count_nonzero(np.diff(inside.astype(int)))) + int(inside[0])
            inside_s += inside.sum() * period
            counted = inside.copy()
            if (a, cid) in grants:  # caught when it opened, or when repaired inside
                caught, bound = grants[(a, cid)]
                after = t[m] >= caught - 1e-9
                left = np.flatnonzero(~inside & after & (state[m, a] != 7))  # up and out
                first_out = t[m][left[0]] if len(left) else np.inf
                exempt_until = min(first_out, caught + bound)
                counted &= ~after | (t[m] >= exempt_until - 1e-9)
            intrusion_s += counted.sum() * period
    return inside_s, intrusion_s, flips


def test_npz_corridor_records_recompute_the_intrusion_figures():
    """Physics, paper_fault with frequent failures and delays: shapely over the exported
    poses and corridor arrays agrees with the executor's per-step figures to within a
    sample period per entry or exit."""
    sc = load_scenario("layouts/paper_fault.yaml", [
        ("executor.name", "physics"), ("planner.name", "astar"),
        ("faults.random.prob_per_tick", 0.03), ("executor.delays.model", "bernoulli"),
        ("executor.delays.prob", 0.05), ("max_ticks", 150), ("orders.oneshot.count", 8)])
    res = Simulation(sc, seed=4).run()
    m, traj = res.metrics, res.trajectory
    for key in ("corridor_id", "corridor_agv", "corridor_open_s", "corridor_close_s",
                "corridor_margin_m", "corridor_rects", "corridor_rect_of",
                "corridor_caught_agv", "corridor_caught_corridor", "corridor_caught_s",
                "corridor_caught_bound_s",
                "corridor_caught_exit_s", "corridor_caught_overran"):
        assert key in traj, key
    assert len(traj["corridor_id"]) == m["failures"] > 0
    assert m["corridor_inside_agv_s"] > 0, "the episode must put AGVs in corridors"
    inside, intrusion, flips = recompute_from_npz(traj)
    print(f"npz: inside {inside:.2f} / intrusion {intrusion:.2f} AGV-s, metrics: "
          f"{m['corridor_inside_agv_s']:.2f} / {m['corridor_intrusion_agv_s']:.2f}, "
          f"{flips} entries/exits")
    period = 1.0 / sc.executor.trajectory_hz
    tol = (flips + 2 * len(traj["corridor_caught_agv"]) + 1) * period
    assert inside == pytest.approx(m["corridor_inside_agv_s"], abs=tol)
    assert intrusion == pytest.approx(m["corridor_intrusion_agv_s"], abs=tol)
    assert int(traj["corridor_caught_overran"].sum()) == m["corridor_exits_overrun"]


def test_accounting_identities_hold_on_a_busy_episode():
    sc = load_scenario("layouts/paper_fault.yaml", [
        ("executor.name", "grid"), ("faults.random.prob_per_tick", 0.05), ("max_ticks", 200)])
    m = Simulation(sc, seed=1).run().metrics
    assert m["corridor_caught_inside"] == (m["corridor_exits_within_bound"]
                                           + m["corridor_exits_overrun"])
    assert 0 <= m["corridor_intrusion_agv_s"] <= m["corridor_inside_agv_s"]
    assert (m["corridor_intrusions"] == 0) == (m["corridor_intrusion_agv_s"] == 0)
