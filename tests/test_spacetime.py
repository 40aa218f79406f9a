"""The space-time validator (warerover_phys.spacetime): swept volumes in (x, y, t) and fcl.

What it must show: it finds conflicts that a per-tick / per-sample check misses (bodies that
cross between samples), it agrees with the discrete validator on unit-time plans where the
bodies are small enough for the grid to be exact, it passes a real physics run, and bad input
is one clean error."""

from __future__ import annotations

import io
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import shapely
from hardening_helpers import LAYOUTS, assert_clean_error, run_cli
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from longcases import slow_after

from warerover_phys.plans.model import Plan
from warerover_phys.spacetime import (
    AgentMotion,
    SpacetimeInputError,
    TimedPlan,
    build_volumes,
    from_plan,
    from_schedule,
    from_trajectory,
    load_trajectory_file,
    validate_spacetime,
)
from warerover_phys.spacetime.check import candidate_pairs
from warerover_phys.validate import validate_states

SMALL = (0.45, 0.45)
"""A body under half a cell: on 4-neighbour unit moves the grid check is then exact."""


def states(plan: Plan, cols: int) -> dict[int, list[tuple[int, int]]]:
    return {i: [(r * cols + c, r * cols + c) for r, c in p] for i, p in enumerate(plan.paths)}


def discrete_pairs(plan: Plan, rows: int, cols: int) -> set[tuple[int, int]]:
    found = validate_states(states(plan, cols), np.zeros((rows, cols), dtype=bool),
                            max_conflicts=10 ** 6)
    return {tuple(sorted(c.agvs)) for c in found if c.kind in ("vertex", "swap")}


def spacetime_pairs(plan: Plan, body=SMALL) -> set[tuple[int, int]]:
    res = validate_spacetime(from_plan(plan, body_m=body), max_conflicts=10 ** 6)
    return {c.agvs for c in res.conflicts}


# --- the volumes ---------------------------------------------------------------------------

@pytest.mark.parametrize("module", ["motion", "check"])
def test_docstring_examples(module):
    import doctest
    import importlib

    result = doctest.testmod(importlib.import_module(f"warerover_phys.spacetime.{module}"))
    assert result.attempted > 0 and result.failed == 0


def random_plan(seed: int, agents: int = 12, samples: int = 6) -> TimedPlan:
    rng = np.random.default_rng(seed)
    return TimedPlan({a: AgentMotion(np.cumsum(rng.uniform(0.1, 1.0, samples)),
                                     rng.uniform(0, 5, samples), rng.uniform(0, 5, samples),
                                     rng.uniform(-4, 4, samples),
                                     (float(rng.uniform(0.2, 1.0)), float(rng.uniform(0.2, 1.0))))
                      for a in range(agents)})


def test_volumes_are_the_convex_hulls_of_their_vertices():
    import trimesh

    vol = build_volumes(random_plan(0))
    for i in range(0, len(vol), 7):
        mesh = vol.mesh(i)
        hull = trimesh.convex.convex_hull(mesh.vertices)
        assert mesh.is_watertight and mesh.is_winding_consistent
        assert mesh.volume > 0  # outward faces
        assert mesh.volume == pytest.approx(hull.volume, rel=1e-9)


def inside(vol, idx: np.ndarray, pts: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    """Is each point (x, y, t) inside some volume of ``idx``? (half-space tests)"""
    verts = vol.vertices(idx)
    tris = vol.faces(idx, verts)
    p = verts[np.arange(len(idx))[:, None, None], tris]
    normal = np.cross(p[:, :, 1] - p[:, :, 0], p[:, :, 2] - p[:, :, 0])
    normal /= np.linalg.norm(normal, axis=2, keepdims=True)
    side = np.einsum("vfk,vfpk->vfp", normal, pts[None, None, :, :] - p[:, :, 0, None, :])
    return (side <= eps).all(axis=1).any(axis=0)


@settings(max_examples=40, deadline=None)
@given(dx=st.floats(-3, 3), dy=st.floats(-3, 3), h0=st.floats(-4, 4),
       dh=st.floats(-math.pi + 1e-6, math.pi), length=st.floats(0.2, 1.5),
       width=st.floats(0.2, 1.5))
def test_the_volumes_contain_the_interpolated_body(dx, dy, h0, dh, length, width):
    """Exact for moves, conservative for turns: every point of the body at every time of
    the straight-line, constant-turn-rate motion lies inside the agent's volumes."""
    m = AgentMotion(np.array([0.0, 1.0]), np.array([0.0, dx]), np.array([0.0, dy]),
                    np.array([h0, h0 + dh]), (length, width))
    vol = build_volumes(TimedPlan({0: m}), tolerance_m=0.0)
    s = np.linspace(0, 1, 41)
    h = h0 + dh * s
    u = np.array([(a, b) for a in (-1, -0.3, 1) for b in (-1, 0.5, 1)]) * (length / 2, width / 2)
    c, sn = np.cos(h)[:, None], np.sin(h)[:, None]
    px = dx * s[:, None] + c * u[:, 0] - sn * u[:, 1]
    py = dy * s[:, None] + sn * u[:, 0] + c * u[:, 1]
    pts = np.stack([px.ravel(), py.ravel(), np.repeat(s, len(u))], axis=1)
    assert inside(vol, np.arange(len(vol)), pts, eps=1e-7).all()
    if dh == 0:  # a pure move: one volume, the sheared prism itself
        assert len(vol) == 1
        assert vol.mesh(0).volume == pytest.approx(length * width, rel=1e-6)


def outlines_over(m: AgentMotion, times: np.ndarray, grow: float = 0.0) -> np.ndarray:
    """The body at each of ``times`` (interpolated as the model says: straight line, the
    shorter turn), grown by ``grow`` per side, as shapely polygons (None before the first
    sample)."""
    x, y = np.interp(times, m.t_s, m.x_m), np.interp(times, m.t_s, m.y_m)
    k = np.clip(np.searchsorted(m.t_s, times, side="right") - 1, 0, len(m.t_s) - 1)
    k1 = np.minimum(k + 1, len(m.t_s) - 1)
    dh = (m.heading_rad[k1] - m.heading_rad[k] + np.pi) % (2 * np.pi) - np.pi
    dh[dh == -np.pi] = np.pi
    span = np.where(k1 > k, m.t_s[k1] - m.t_s[k], 1.0)
    s = np.clip(np.where(k1 > k, (times - m.t_s[k]) / span, 0.0), 0, 1)
    h = m.heading_rad[k] + dh * s
    hl, hw = m.body_m[0] / 2 + grow, m.body_m[1] / 2 + grow
    c, sn = np.cos(h)[:, None], np.sin(h)[:, None]
    u = np.array([(1, 1), (-1, 1), (-1, -1), (1, -1)]) * (hl, hw)
    rings = np.stack([x[:, None] + c * u[:, 0] - sn * u[:, 1],
                      y[:, None] + sn * u[:, 0] + c * u[:, 1]], axis=2)
    out = shapely.polygons(rings)
    out[times < m.t_s[0]] = None
    return out


@pytest.mark.parametrize("seed", slow_after(2, range(6)))
def test_agrees_with_dense_sampling(seed):
    """An independent check of the whole pipeline: bodies compared with shapely at 4,000
    instants. Every pair seen overlapping by more than the tolerance (bodies shrunk by a
    bit more than half of it per side) is a conflict; every conflict is a pair seen within
    reach (bodies grown by the turn bound and the motion between two instants)."""
    rng = np.random.default_rng(seed)
    agents = {}
    for a in range(8):
        k = 5
        heads = rng.uniform(-4, 4, k) if seed % 2 else np.full(k, rng.uniform(-4, 4))
        agents[a] = AgentMotion(np.sort(rng.uniform(0, 10, k)) + np.arange(k) * 1e-3,
                                rng.uniform(0, 6, k), rng.uniform(0, 6, k), heads,
                                (float(rng.uniform(0.3, 1.2)), float(rng.uniform(0.3, 1.2))))
    plan = TimedPlan(agents)
    res = validate_spacetime(plan, max_conflicts=10 ** 6)
    found = {c.agvs for c in res.conflicts}
    times = np.linspace(0, plan.end_s, 4000)
    step = times[1] - times[0]
    speed = max(float(np.max(np.hypot(np.diff(m.x_m), np.diff(m.y_m)) / np.diff(m.t_s)) +
                      np.max(np.abs(np.diff(m.heading_rad)) / np.diff(m.t_s)) *
                      np.hypot(*m.body_m) / 2) for m in agents.values())
    slack = res.max_rotation_bound_m + speed * step
    small = {a: outlines_over(m, times, grow=-0.001) for a, m in agents.items()}
    big = {a: outlines_over(m, times, grow=slack) for a, m in agents.items()}
    sure, near = set(), set()
    for p in agents:
        for q in agents:
            if p < q:
                if shapely.intersects(small[p], small[q]).any():
                    sure.add((p, q))
                if shapely.intersects(big[p], big[q]).any():
                    near.add((p, q))
    assert sure <= found <= near, (sure - found, found - near)
    assert found  # the random plans do collide


def test_grid_broad_phase_finds_every_overlapping_box_pair():
    vol = build_volumes(random_plan(1, agents=25, samples=8))
    a, b = candidate_pairs(vol)
    xmin, xmax, ymin, ymax = vol.extents()
    i, j = np.triu_indices(len(vol), 1)
    meet = ((vol.agent[i] != vol.agent[j]) & (xmin[i] <= xmax[j]) & (xmin[j] <= xmax[i]) &
            (ymin[i] <= ymax[j]) & (ymin[j] <= ymax[i]) & (vol.t0[i] < vol.t1[j]) &
            (vol.t0[j] < vol.t1[i]))
    assert set(zip(a.tolist(), b.tolist(), strict=True)) == \
        set(zip(i[meet].tolist(), j[meet].tolist(), strict=True))


@pytest.mark.parametrize("seed", [2, 3])
def test_grid_and_fcl_broad_phases_find_the_same_conflicts(seed):
    plan = random_plan(seed, agents=10, samples=5)
    grid = validate_spacetime(plan, max_conflicts=10 ** 6)
    tree = validate_spacetime(plan, broad_phase="fcl", max_conflicts=10 ** 6)
    assert grid.conflicts  # random motion on a 5 m square: there are some
    assert [(c.agvs, c.t_start_s, c.t_end_s) for c in grid.conflicts] == \
        [(c.agvs, c.t_start_s, c.t_end_s) for c in tree.conflicts]


def test_trimesh_hulls_are_watertight_convex_and_give_the_same_conflicts():
    """The narrow phase's hulls: built with numpy or with trimesh's convex_hull (qhull), the
    same solids (trimesh checks both watertight, outward and convex), the same conflicts."""
    plan = random_plan(4, agents=8, samples=4)
    vol = build_volumes(plan)
    idx = np.arange(len(vol))
    fast, slow = vol.hulls(idx), vol.hulls(idx, method="trimesh")
    assert fast.is_watertight and slow.is_watertight
    vf = fast.vertices.reshape(-1, 8, 3)
    assert np.allclose(np.sort(vf, axis=1), np.sort(slow.vertices.reshape(-1, 8, 3), axis=1))
    for k in range(0, len(vol), 5):
        a = fast.submesh([np.arange(12 * k, 12 * k + 12)], append=True)
        b = slow.submesh([np.arange(12 * k, 12 * k + 12)], append=True)
        assert a.is_convex and b.is_convex
        assert a.volume == pytest.approx(b.volume, rel=1e-9) and a.volume > 0
    numpy_res = validate_spacetime(plan, max_conflicts=10 ** 6)
    trimesh_res = validate_spacetime(plan, max_conflicts=10 ** 6, hulls="trimesh")
    assert numpy_res.conflicts and numpy_res.conflicts == trimesh_res.conflicts


def test_narrow_phase_finds_a_volume_wholly_inside_another():
    """fcl's BVH models are surfaces: a hull inside another is found by the containment
    test, both ways round, and a hull beside another is not."""
    from warerover_phys.spacetime.check import _narrow
    from warerover_phys.spacetime.volumes import Volumes

    def vol(x, t0, t1, half):
        n = len(x)
        z = np.zeros(n)
        return Volumes(np.arange(n), np.zeros(n, np.int8), np.array(t0, float),
                       np.array(t1, float), np.array(x, float), z, z, np.array(x, float), z,
                       z, np.array(half, float), np.array(half, float), inner=z)

    v = vol([0.0, 0.2, 3.0], [0.0, 2.0, 2.0], [10.0, 3.0, 3.0], [1.0, 0.1, 0.1])
    assert _narrow(v, np.array([0, 1, 0]), np.array([1, 0, 2])).tolist() == \
        [True, True, False]


# --- what a per-tick check misses ----------------------------------------------------------

def test_bodies_that_cut_a_corner_conflict_though_every_tick_is_valid():
    """A moves east into the cell B leaves southwards, in the same tick: the per-tick
    validator allows it (no vertex, no swap), but 0.7 m bodies moving in straight lines
    overlap mid-tick (their corners meet at the shared cell's corner); 0.45 m bodies pass."""
    plan = Plan(paths=(((0, 0), (0, 1)), ((0, 1), (1, 1))))
    assert validate_states(states(plan, 2), np.zeros((2, 2), dtype=bool)) == []
    res = validate_spacetime(from_plan(plan))
    assert not res.ok and len(res.conflicts) == 1
    c = res.conflicts[0]
    assert c.agvs == (0, 1) and c.parts == "body-body"
    assert 0 < c.t_s < 1 and c.t_start_s == 0 and c.t_end_s == 1
    assert c.x_m == pytest.approx(1.25) and c.y_m == pytest.approx(0.75)
    assert 0.301 <= c.t_contact_s <= 0.302  # |dx| = 1 - t < 0.699 once t > 0.301 (|dy| = t)
    assert validate_spacetime(from_plan(plan, body_m=SMALL)).ok


def overlaps_at_samples(plan: TimedPlan) -> int:
    """The per-sample check: outlines compared at every sample time only."""
    hits = 0
    times = np.unique(np.concatenate([m.t_s for m in plan.agents.values()]))
    for t in times:
        polys = []
        for m in plan.agents.values():
            x, y, h = (np.interp(t, m.t_s, v) for v in (m.x_m, m.y_m, m.heading_rad))
            ring = shapely.affinity.rotate(shapely.box(-m.body_m[0] / 2, -m.body_m[1] / 2,
                                                       m.body_m[0] / 2, m.body_m[1] / 2),
                                           h, use_radians=True, origin=(0, 0))
            polys.append(shapely.affinity.translate(ring, x, y))
        for i in range(len(polys)):
            for j in range(i + 1, len(polys)):
                hits += polys[i].intersection(polys[j]).area > 1e-9
    return hits


def test_bodies_that_cross_between_samples_are_found():
    """Two AGVs cross the square diagonally in one sample interval: at both samples they are
    2.8 m apart, in between they pass through each other. The per-sample check sees
    nothing; the per-tick validator sees only two illegal (diagonal) moves, no vertex or
    swap; the swept volumes meet at t = 0.5 s in the middle."""
    plan = from_schedule({0: [((0, 0), 0.0), ((2, 2), 1.0)], 1: [((0, 2), 0.0), ((2, 0), 1.0)]})
    assert overlaps_at_samples(plan) == 0
    per_tick = validate_states({0: [(0, 0), (8, 8)], 1: [(2, 2), (6, 6)]},
                               np.zeros((3, 3), dtype=bool))
    assert {c.kind for c in per_tick} == {"move"}
    res = validate_spacetime(plan)
    assert [c.agvs for c in res.conflicts] == [(0, 1)]
    c = res.conflicts[0]
    assert (c.t_s, c.x_m, c.y_m, c.cell) == (pytest.approx(0.5), pytest.approx(1.5),
                                             pytest.approx(1.5), (1, 1))


@settings(max_examples=30, deadline=None)
@given(gap=st.floats(0.8, 20), v=st.floats(0.1, 30), w=st.floats(0.0, 30),
       turn=st.floats(0, 3))
def test_first_contact_time_is_found_never_early(gap, v, w, turn):
    """Head-on along x: A's and B's 0.7 m squares first overlap by more than the 1 mm
    tolerance at t* = (gap - 0.699) / (v + w); the bisection reports it within 1 ms, never
    before. If B turns as it comes it reaches at least as far ahead (a square's extent is
    at least its half side), so contact comes no later."""
    a = AgentMotion.from_samples([(0, 0, 0, 0), (v, 0, 0, 1)])
    b = AgentMotion.from_samples([(gap, 0, 0, 0), (gap - w, 0, turn, 1)])
    res = validate_spacetime(TimedPlan({0: a, 1: b}))
    t_star = (gap - 0.699) / (v + w)
    if t_star > 1:  # straight, they never get that close within the plan (turned, B's
        if turn == 0:  # corners reach further ahead, and may still meet A)
            assert res.ok
        return
    c = res.conflicts[0]
    assert c.t_contact_s <= t_star + 1e-3 + 1e-9  # a turned square reaches at least as far
    if turn == 0:
        assert t_star - 1e-9 <= c.t_contact_s


def test_fast_bodies_passing_through_each_other_between_samples():
    """Head-on at 20 m/s, sampled at 1 Hz: 10 m apart at both samples."""
    plan = TimedPlan({0: AgentMotion.from_samples([(0, 0, 0, 0), (10, 0, 0, 1)]),
                      1: AgentMotion.from_samples([(10, 0, math.pi, 0), (0, 0, math.pi, 1)])})
    assert overlaps_at_samples(plan) == 0
    res = validate_spacetime(plan)
    assert len(res.conflicts) == 1 and res.conflicts[0].t_s == pytest.approx(0.5)


def test_turning_bodies_sweep_their_ends():
    """Two long AGVs (1.2 x 0.4 m) side by side, 0.7 m between centres: both clear at both
    samples, while one half-turns in place its ends swing through the other."""
    still = AgentMotion.from_samples([(0, 0, 0, 0), (0, 0, 0, 1)], body_m=(1.2, 0.4))
    turner = AgentMotion.from_samples([(0, 0.7, 0, 0), (0, 0.7, math.pi, 1)],
                                      body_m=(1.2, 0.4))
    parked = AgentMotion.from_samples([(0, 0.7, 0, 0), (0, 0.7, 0, 1)], body_m=(1.2, 0.4))
    plan = TimedPlan({0: still, 1: turner})
    assert overlaps_at_samples(plan) == 0
    res = validate_spacetime(plan)
    assert [c.agvs for c in res.conflicts] == [(0, 1)]
    assert 0 < res.conflicts[0].t_s < 1
    assert res.max_rotation_bound_m == pytest.approx(math.hypot(0.6, 0.2) * (math.pi / 16) ** 2
                                                     / 8, rel=1e-6)
    assert 0.1 <= res.conflicts[0].t_start_s and res.conflicts[0].t_end_s <= 0.9
    assert validate_spacetime(TimedPlan({0: still, 1: parked})).ok


def test_neighbours_turning_in_place_together_are_clear():
    """Two 0.7 m squares on neighbouring 1 m cells, both turning a quarter in place in the
    same tick: their corners sweep circles 0.495 m round, 10 mm apart at closest. The turn's
    bound must stay inside that (a looser bound, or pieces of pi / 8, made this a false
    conflict)."""
    for turn in (math.pi / 2, -math.pi / 2, math.pi):
        a = AgentMotion.from_samples([(0.5, 0.5, 0, 0), (0.5, 0.5, turn, 1)])
        b = AgentMotion.from_samples([(1.5, 0.5, math.pi / 2, 0), (1.5, 0.5, math.pi, 1)])
        c = AgentMotion.from_samples([(0.5, 1.5, 0, 0), (0.5, 1.5, -turn, 1)])
        res = validate_spacetime(TimedPlan({0: a, 1: b, 2: c}))
        assert res.ok, (turn, res.conflicts)
    # 0.72 m squares (corner circles 0.509 m) do meet
    a = AgentMotion.from_samples([(0.5, 0.5, 0, 0), (0.5, 0.5, math.pi / 2, 1)],
                                 body_m=(0.72, 0.72))
    b = AgentMotion.from_samples([(1.5, 0.5, 0, 0), (1.5, 0.5, math.pi / 2, 1)],
                                 body_m=(0.72, 0.72))
    assert not validate_spacetime(TimedPlan({0: a, 1: b})).ok


def test_touching_within_the_tolerance_is_not_a_conflict():
    a = AgentMotion.from_samples([(0, 0, 0, 0), (0, 0, 0, 2)])
    for gap, ok in ((0.7, True), (0.7 - 5e-4, True), (0.69, False)):
        b = AgentMotion.from_samples([(gap, 0, 0, 0), (gap, 0, 0, 2)])
        assert validate_spacetime(TimedPlan({0: a, 1: b})).ok is ok, gap
    b = AgentMotion.from_samples([(0.699, 0, 0, 0), (0.699, 0, 0, 2)])
    assert not validate_spacetime(TimedPlan({0: a, 1: b}), tolerance_m=0.0).ok


def test_carried_shelves_count():
    """Bodies 1 m apart are clear; the 0.9 m shelves they carry are not (1.8 m apart)."""
    shelf = np.array([[1.0, 1.0], [1.0, 1.0]])
    a = AgentMotion.from_samples([(0, 0, 0, 0), (0, 0, 0, 1)], shelf_m=shelf)
    b = AgentMotion.from_samples([(0.95, 0, 0, 0), (0.95, 0, 0, 1)], shelf_m=shelf)
    res = validate_spacetime(TimedPlan({0: a, 1: b}))
    assert [c.parts for c in res.conflicts] == ["shelf-shelf"]
    assert validate_spacetime(TimedPlan({0: a, 1: b}), shelves=False).ok


def test_an_agent_stays_on_its_last_pose_until_the_plan_ends():
    """Agent 0's plan ends at t = 1 on cell (0, 1); agent 1 drives into it at t = 3."""
    plan = from_schedule({0: [((0, 0), 0.0), ((0, 1), 1.0)],
                          1: [((0, 4), 0.0), ((0, 2), 2.0), ((0, 1), 3.0)]})
    res = validate_spacetime(plan)
    assert [c.agvs for c in res.conflicts] == [(0, 1)]
    assert res.conflicts[0].t_start_s >= 2.0


def test_plan_headings_turn_the_body():
    plan = Plan(paths=(((0, 0), (0, 0)),), headings=((0, 1),))
    tp = from_plan(plan)
    assert tp.agents[0].heading_rad.tolist() == [0.0, math.pi / 2]
    two = from_plan(Plan(paths=(((0, 0),), ((0, 0),)), rows=1, cols=1), footprints=[2, 1])
    assert (two.agents[0].x_m[0], two.agents[1].x_m[0]) == (1.0, 0.5)


# --- agreement with the discrete validator on unit-time plans ------------------------------

MOVES = ((0, 0), (0, 1), (1, 0), (0, -1), (-1, 0))


@st.composite
def walks(draw):
    rows, cols = draw(st.integers(2, 5)), draw(st.integers(2, 5))
    n = draw(st.integers(2, 6))
    ticks = draw(st.integers(1, 8))
    paths = []
    for _ in range(n):
        r, c = draw(st.integers(0, rows - 1)), draw(st.integers(0, cols - 1))
        path = [(r, c)]
        for _ in range(ticks):
            dr, dc = draw(st.sampled_from(MOVES))
            if 0 <= r + dr < rows and 0 <= c + dc < cols:
                r, c = r + dr, c + dc
            path.append((r, c))
        paths.append(tuple(path))
    return Plan(paths=tuple(paths), rows=rows, cols=cols), rows, cols


# 150 examples: random walks, cheap: conflicts are rare among them
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(walks())
def test_agrees_with_the_discrete_validator_on_random_walks(case):
    """Random 4-neighbour walks (conflicts and all): with bodies under half a cell, two
    agents' volumes meet exactly when the per-tick validator reports a vertex or swap
    conflict between them (or both on one cell at one tick), and the conflict's time span
    holds the tick."""
    plan, rows, cols = case
    found = validate_states(states(plan, cols), np.zeros((rows, cols), dtype=bool),
                            max_conflicts=10 ** 6)
    found = [c for c in found if c.kind in ("vertex", "swap")]
    res = validate_spacetime(from_plan(plan, body_m=SMALL), max_conflicts=10 ** 6)
    direct = {tuple(sorted(c.agvs)) for c in found}
    # validate_states names the first AGV on a cell against each other one there: three on
    # one cell are two conflicts, (a, b) and (a, c); b and c meet as well
    groups: dict[tuple, set[int]] = {}
    for c in found:
        if c.kind == "vertex":
            groups.setdefault((c.tick, c.cell), set()).update(c.agvs)
    shared = {(p, q) for g in groups.values() for p in g for q in g if p < q}
    assert direct <= {c.agvs for c in res.conflicts} <= direct | shared
    for c in found:
        pair = tuple(sorted(c.agvs))
        lo = c.tick - 1 if c.kind == "swap" else c.tick
        assert any(s.agvs == pair and s.t_start_s <= lo + 1e-9 and c.tick <= s.t_end_s + 1e-9
                   for s in res.conflicts), (c, res.conflicts)


@st.composite
def instances(draw):
    rows, cols = draw(st.integers(4, 8)), draw(st.integers(4, 8))
    rng = np.random.default_rng(draw(st.integers(0, 2 ** 16)))
    obstacles = rng.random((rows, cols)) < 0.15
    free = [tuple(map(int, c)) for c in np.argwhere(~obstacles)]
    n = draw(st.integers(2, min(8, len(free) // 2)))
    pick = rng.permutation(len(free))
    return obstacles, [free[i] for i in pick[:n]], [free[i] for i in pick[n:2 * n]], \
        draw(st.sampled_from(["lacam", "pibt"]))


# 25 examples: each example solves a floor with a one-shot planner
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances())
def test_agrees_with_the_discrete_validator_on_planner_plans(case):
    """The project's own one-shot planners on small random grids: a valid plan has no
    space-time conflict; an agent added that runs agent 0's path backwards meets agent 0
    (a vertex or swap) and both validators find exactly the same pairs."""
    from warerover_phys.errors import PlanningError
    from warerover_phys.planning.oneshot.core import solve

    obstacles, starts, goals, planner = case
    try:
        result = solve(obstacles, starts, goals, planner=planner, time_limit_s=5.0)
    except PlanningError:  # a goal walled off
        return
    if not result.success:
        return
    rows, cols = obstacles.shape
    plan = Plan(paths=tuple(tuple(map(tuple, p)) for p in result.paths), rows=rows, cols=cols)
    assert discrete_pairs(plan, rows, cols) == set()
    assert spacetime_pairs(plan) == set()
    assert spacetime_pairs(plan, body=(0.45, 0.3)) == set()
    horizon = max(len(p) for p in result.paths)
    path0 = list(result.paths[0]) + [result.paths[0][-1]] * (horizon - len(result.paths[0]))
    bad = Plan(paths=plan.paths + (tuple(map(tuple, path0[::-1])),), rows=rows, cols=cols)
    both = discrete_pairs(bad, rows, cols)
    assert (0, len(starts)) in both
    found = spacetime_pairs(bad)
    assert both <= found and (0, len(starts)) in found
    # anything more is a third AGV on a cell the discrete check names once
    assert all(len(p & q) for p in map(set, found - both) for q in map(set, [(0, len(starts))]))


# --- a real physics run --------------------------------------------------------------------

@pytest.fixture(scope="module")
def physics_run(tmp_path_factory) -> Path:
    from warerover_phys import load_scenario, run_episode
    from warerover_phys.outputs import write_outputs

    sc = load_scenario(LAYOUTS / "paper_homogeneous.yaml",
                       [("executor.name", "physics"), ("max_ticks", 60)])
    out = tmp_path_factory.mktemp("run") / "r"
    write_outputs(run_episode(sc, seed=1), out)
    return out


def test_a_physics_run_has_no_conflict(physics_run):
    plan = load_trajectory_file(physics_run)
    assert len(plan.agents) == 9 and plan.cell_m == 1.0
    res = validate_spacetime(plan)
    assert res.ok, res.conflicts[:3]
    assert res.volumes > 1000
    # the recorded shelves are in: someone carried one
    assert any(m.shelf_m is not None and (m.shelf_m > 0).any() for m in plan.agents.values())
    proc = run_cli("check-trajectory", physics_run, cwd=physics_run.parent)
    assert proc.returncode == 0, proc.stderr
    assert "ok: no two bodies met" in proc.stdout


def test_a_heterogeneous_physics_run_has_no_conflict(tmp_path):
    """2x2 AGVs (1.6 m bodies) beside 1x1 ones, carrying shelves, on physics."""
    from warerover_phys import load_scenario, run_episode
    from warerover_phys.outputs import write_outputs

    sc = load_scenario(LAYOUTS / "paper_heterogeneous.yaml",
                       [("executor.name", "physics"), ("max_ticks", 40)])
    write_outputs(run_episode(sc, seed=2), tmp_path / "r")
    plan = load_trajectory_file(tmp_path / "r")
    assert {m.body_m for m in plan.agents.values()} == {(0.7, 0.7), (1.6, 1.6)}
    res = validate_spacetime(plan)
    assert res.ok, res.conflicts[:3]


def test_a_doctored_physics_run_is_caught(physics_run, tmp_path):
    """Teleport AGV 1 onto AGV 0 for one sample: the CLI lists the conflict, exit 1."""
    with np.load(physics_run / "trajectories.npz") as data:
        traj = {k: data[k] for k in data.files}
    k = len(traj["t"]) // 2
    for key in ("x", "y", "heading"):
        traj[key] = traj[key].copy()
        traj[key][k, 1] = traj[key][k, 0]
    assert not validate_spacetime(from_trajectory(traj)).ok
    f = tmp_path / "trajectories.npz"
    np.savez(f, **traj)
    proc = run_cli("check-trajectory", f, "--json", cwd=tmp_path)
    assert proc.returncode == 1, proc.stderr
    import json
    report = json.loads(proc.stdout)
    assert not report["ok"] and report["conflicts"][0]["agvs"][0] in (0, 1)


# --- bad input -----------------------------------------------------------------------------

def save(path: Path, traj: dict) -> None:
    buf = io.BytesIO()
    np.savez(buf, **traj)
    path.write_bytes(buf.getvalue())


@pytest.mark.parametrize("kind, needles", [
    ("missing", ["heading", "missing field"]),
    ("nan", ["x", "not finite", "nan"]),
    ("backwards", ["t:", "increase"]),
    ("body", ["body_m", "shape"]),
    ("shelf", ["shelf_m", "negative"]),
    ("truncated", ["not an .npz archive"]),
    ("absent", ["trajectory file not found"]),
])
def test_bad_trajectories_are_one_clean_error(physics_run, tmp_path, kind, needles):
    with np.load(physics_run / "trajectories.npz") as data:
        traj = {k: data[k] for k in data.files}
    f = tmp_path / "trajectories.npz"
    if kind == "missing":
        del traj["heading"]
    elif kind == "nan":
        traj["x"] = traj["x"].copy()
        traj["x"][3, 2] = np.nan
    elif kind == "backwards":
        traj["t"] = traj["t"].copy()
        traj["t"][5] = traj["t"][4]
    elif kind == "body":
        traj["body_m"] = traj["body_m"][:, :1]
    elif kind == "shelf":
        traj["shelf_m"] = traj["shelf_m"].copy()
        traj["shelf_m"][1, 1, 0] = -1
    if kind == "truncated":
        raw = (physics_run / "trajectories.npz").read_bytes()
        f.write_bytes(raw[: len(raw) // 2])
    elif kind != "absent":
        save(f, traj)
    proc = run_cli("check-trajectory", tmp_path, cwd=tmp_path)
    assert_clean_error(proc, str(f), *needles)
    if kind not in ("truncated", "absent"):
        with pytest.raises(SpacetimeInputError):
            load_trajectory_file(f)


def test_bad_options_are_one_clean_error(physics_run, tmp_path):
    assert_clean_error(run_cli("check-trajectory", physics_run, "--tolerance-m", "nan",
                               cwd=tmp_path), "--tolerance-m")
    assert_clean_error(run_cli("check-trajectory", physics_run, "--max-turn-rad", "4",
                               cwd=tmp_path), "--max-turn-rad")


def test_bad_timed_plans_name_the_agent_and_field():
    with pytest.raises(SpacetimeInputError, match=r"agents\[3\]\.t_s.*increase"):
        TimedPlan({3: AgentMotion.from_samples([(0, 0, 0, 1.0), (1, 0, 0, 1.0)])})
    with pytest.raises(SpacetimeInputError, match=r"agents\[0\]\.body_m"):
        TimedPlan({0: AgentMotion.from_samples([(0, 0, 0, 0)], body_m=(0.0, 1.0))})
    with pytest.raises(SpacetimeInputError, match=r"schedules\[2\]\[1\]"):
        from_schedule({2: [((0, 0), 0.0), ((0, 1),)]}, source="plan.txt")
    with pytest.raises(ValueError, match="tolerance"):
        validate_spacetime(TimedPlan({}), tolerance_m=-1)


def test_a_run_folder_with_a_mixed_file_set_is_refused(physics_run, tmp_path):
    dst = tmp_path / "copy"
    shutil.copytree(physics_run, dst)
    with np.load(dst / "trajectories.npz") as data:
        traj = {k: data[k] for k in data.files}
    save(dst / "trajectories.npz", {**traj, "x": traj["x"] + 0.1})
    proc = run_cli("check-trajectory", dst, cwd=tmp_path)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr


def test_the_command_line_starts_without_the_validator():
    """Registering check-trajectory loads neither the validator nor fcl (nor numpy through
    them): ``warerover --help`` stays fast."""
    import subprocess
    import sys

    from hardening_helpers import REPO, cli_env

    code = ("import sys, warerover_phys.cli.commands; "
            "print(sorted(m for m in ('fcl', 'trimesh', 'warerover_phys.spacetime.check', "
            "'warerover_phys.spacetime.motion') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, env=cli_env(),
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
