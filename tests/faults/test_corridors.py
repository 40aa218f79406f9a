"""Safety corridors (routes, geometry, covered cells) and the fcl intrusion checker against
its shapely reference."""

from __future__ import annotations

import doctest

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString

from warerover_phys.config import LayoutSpec
from warerover_phys.errors import LayoutError, ScenarioError
from warerover_phys.faults import (
    Corridor,
    IntrusionChecker,
    agv_boxes,
    cover_mask,
    intrusions_shapely,
    plan_corridor,
)
from warerover_phys.faults import corridors as corridors_module
from warerover_phys.faults import intrusion as intrusion_module
from warerover_phys.layout import build_layout

# --------------------------------------------------------------------------- helpers


def make_layout(rows: list[str], cell_m: float = 1.0):
    # A layout needs a station ('R') and a shelf ('S'); 'A' marks a maintenance access point.
    return build_layout(LayoutSpec(grid=rows, cell_m=cell_m))


def flat(layout, cells) -> list[int]:
    return [r * layout.cols + c for r, c in cells]


def corridor(layout, cells, width_m=1.0, margin_m=0.0, cid=0, agv=0, walkable=None) -> Corridor:
    return plan_corridor(layout, cid, agv, flat(layout, cells), width_m, margin_m,
                         walkable=walkable)


OPEN = ["S......",
        ".......",
        ".......",
        ".......",
        "R......"]


def test_docstring_examples():
    for module in (corridors_module, intrusion_module):
        result = doctest.testmod(module)
        assert result.attempted > 0 and result.failed == 0, module.__name__


# --------------------------------------------------------------------------- routes


def test_nearest_border_cell_lowest_on_ties():
    lay = make_layout(OPEN)
    # (0,2), (2,0) and (4,2) are all two steps away: the lowest (row, col) wins.
    cor = corridor(lay, [(2, 2)])
    assert cor.access == (0, 2)
    assert cor.route == ((2, 2), (1, 2), (0, 2))
    assert cor.agv == 0 and cor.id == 0


def test_access_points_preferred_over_nearer_border():
    rows = [r for r in OPEN]
    rows[2] = "......A"
    cor = corridor(make_layout(rows), [(2, 2)])
    assert cor.access == (2, 6)
    assert cor.route == tuple((2, c) for c in range(2, 7))
    assert cor.rects[0] == (2.0, 2.0, 7.0, 3.0)  # one straight run, then the footprint box


def test_shelves_avoided_unless_walkable_says_so():
    lay = make_layout(["###A###",
                       "#.....#",
                       "#.SSS.#",
                       "#.....#",
                       "#R#####"])
    cor = corridor(lay, [(3, 3)])
    assert cor.access == (0, 3) and cor.route[0] == (3, 3)
    assert len(cor.route) == 8  # around the shelf row: 7 steps
    assert all(lay.grid[r, c] not in (1, 2) for r, c in cor.route)  # no obstacle, no shelf
    assert all(abs(a[0] - b[0]) + abs(a[1] - b[1]) == 1
               for a, b in zip(cor.route, cor.route[1:], strict=False))
    # Few turns: along, up the side aisle, across, up: 4 straight runs and the AGV's box.
    assert len(cor.rects) == 4 + 1
    walk = ~lay.obstacles
    walk[0, 3] = True
    straight = corridor(lay, [(3, 3)], walkable=walk)
    assert straight.route == ((3, 3), (2, 3), (1, 3), (0, 3))


def test_prefers_straight_runs_among_shortest_routes():
    lay = make_layout(["S..A.",
                       ".....",
                       ".#...",
                       "....R"])
    cor = corridor(lay, [(3, 1)])
    assert cor.route == ((3, 1), (3, 2), (3, 3), (2, 3), (1, 3), (0, 3))
    assert len(cor.rects) == 2 + 1


def test_agv_under_a_shelf_stands_on_walkable_ground():
    lay = make_layout(["###A###",
                       "#.....#",
                       "#.SSS.#",
                       "#.....#",
                       "#R#####"])
    assert corridor(lay, [(2, 3)]).route == ((2, 3), (1, 3), (0, 3))
    border = make_layout(OPEN)  # (0, 0) is a shelf on the border: the AGV is already out
    cor = corridor(border, [(0, 0)])
    assert cor.route == ((0, 0),) and cor.access == (0, 0)


def test_two_by_two_footprint():
    lay = make_layout(["S.....", "......", "......", "......", "......", "R....."])
    cor = corridor(lay, [(2, 2), (2, 3), (3, 2), (3, 3)], width_m=0.6)
    assert cor.access == (0, 2) and cor.route == ((2, 2), (1, 2), (0, 2))
    assert (2.0, 2.0, 4.0, 4.0) in cor.rects  # the AGV's bounding box
    assert cor.polygon.contains(shapely.box(2.0, 2.0, 4.0, 4.0))
    # On the border already: the route is the footprint, the corridor its box.
    edge = corridor(lay, [(0, 1), (0, 2), (1, 1), (1, 2)])
    assert edge.route == ((0, 1), (0, 2), (1, 1), (1, 2)) and edge.access == (0, 1)
    assert edge.rects == ((1.0, 0.0, 3.0, 2.0),)


def test_moving_footprint_routes_from_either_cell():
    lay = make_layout(["S.....", "......", ".....A", "......", "R....."])
    cor = corridor(lay, [(2, 2), (2, 3)])  # moving from (2,2) to (2,3)
    assert cor.route == ((2, 3), (2, 4), (2, 5))
    assert (2.0, 2.0, 4.0, 3.0) in cor.rects


def test_unreachable_raises_layout_error():
    lay = make_layout([".....", ".###.", ".#.#.", ".###.", "S...R"])
    with pytest.raises(LayoutError, match="border cell"):
        corridor(lay, [(2, 2)])
    walled_access = make_layout(["A.#..", "####.", "S...R"])
    with pytest.raises(LayoutError, match="access point"):  # border is near, access is not
        corridor(walled_access, [(2, 2)])


def test_width_larger_than_map_names_the_field():
    lay = make_layout(OPEN, cell_m=0.5)  # 5 x 7 cells: 2.5 m x 3.5 m
    assert corridor(lay, [(2, 2)], width_m=2.5).rects
    with pytest.raises(ScenarioError) as err:
        corridor(lay, [(2, 2)], width_m=2.6)
    assert err.value.field == "faults.corridor_width_m" and err.value.value == 2.6
    assert "faults.corridor_width_m" in str(err.value)


# --------------------------------------------------------------------------- geometry


L_SHAPED = ["A......",
            "#####..",
            "S......",
            "R......"]


def test_runs_join_without_notches_and_clip_to_the_map():
    lay = make_layout(L_SHAPED, cell_m=0.8)
    for width in (0.3, 0.8, 1.5):
        cor = corridor(lay, [(3, 1)], width_m=width, margin_m=0.25)
        centres = [((c + 0.5) * 0.8, (r + 0.5) * 0.8) for r, c in cor.route]
        walk = LineString(centres).buffer(width / 2, cap_style="square", join_style="mitre")
        foot = shapely.box(0.8, 2.4, 1.6, 3.2)
        world = shapely.box(0, 0, 7 * 0.8, 4 * 0.8)
        expected = shapely.union(walk, foot).intersection(world)
        assert cor.polygon.symmetric_difference(expected).area < 1e-9, width
        zone = cor.polygon.buffer(0.25, join_style="mitre").intersection(world)
        assert cor.zone.symmetric_difference(zone).area < 1e-9
        assert world.contains(cor.zone)
        assert all(0 <= x0 < x1 <= 5.6 and 0 <= y0 < y1 <= 3.2 for x0, y0, x1, y1 in cor.rects)


def test_cells_exact_route_with_zero_margin_and_neighbours_with_margin():
    lay = make_layout(L_SHAPED)
    cor = corridor(lay, [(3, 1)], width_m=1.0, margin_m=0.0)
    assert cor.route[0] == (3, 1) and cor.access == (0, 0)
    assert len(cor.rects) > 2  # it turns
    assert cor.cells == frozenset(flat(lay, cor.route))
    assert cor.polygon.area == pytest.approx(len(cor.route))
    wide = corridor(lay, [(3, 1)], width_m=1.0, margin_m=0.2)
    mask = np.zeros((lay.rows, lay.cols), dtype=bool)
    for r, c in wide.route:
        mask[max(r - 1, 0):r + 2, max(c - 1, 0):c + 2] = True  # 8 neighbours (mitre corners)
    assert wide.cells == frozenset(np.flatnonzero(mask).tolist())
    assert wide.cells > cor.cells


def test_cover_mask_is_the_union():
    lay = make_layout(L_SHAPED)
    a = corridor(lay, [(3, 1)], cid=0)
    b = corridor(lay, [(2, 6)], cid=1, agv=1, margin_m=0.3)
    mask = cover_mask([a, b], lay.rows, lay.cols)
    assert mask.shape == (lay.rows, lay.cols) and mask.dtype == bool
    assert set(np.flatnonzero(mask).tolist()) == a.cells | b.cells
    assert not cover_mask([], lay.rows, lay.cols).any()


def test_corridors_are_deterministic():
    lay = make_layout(L_SHAPED)
    assert corridor(lay, [(3, 1)], margin_m=0.2) == corridor(lay, [(3, 1)], margin_m=0.2)


# --------------------------------------------------------------------------- intrusions


LONG = ["S" + "." * 22 + "A",
        "R" + "." * 23,
        "." * 24,
        "." * 24]


def long_corridor(width_m=3.0, margin_m=0.2) -> Corridor:
    # A 3 m wide corridor along row 0 (y in [0, 2]: clipped at the map's top edge).
    return corridor(make_layout(LONG), [(0, 2)], width_m=width_m, margin_m=margin_m)


def test_body_fully_inside_a_long_rectangle_is_reported():
    cor = long_corridor()
    assert cor.rects[0] == (1.0, 0.0, 24.0, 2.0)
    chk = IntrusionChecker(np.array([[0.3, 0.2]]))
    chk.set_corridors([cor])
    (hit,) = chk.check(np.array([[12.0, 1.0, 0.0]]))
    assert (hit.agv, hit.corridor) == (0, 0)
    # Penetration is the shortest way out: 1.0 + 0.2 m across the run.
    assert hit.depth_m == pytest.approx(0.2 + 1.2, abs=1e-9)
    assert hit.depth_m > cor.margin_m
    # Deep inside a wide corridor: 4.1 m from the nearest way out, far more than the body.
    wide = corridor(make_layout(["S" + "." * 11] + ["." * 12] * 10 + ["R" + "." * 11]),
                    [(6, 6)], width_m=8.0, margin_m=0.1)
    assert wide.rects[0] == (2.5, 2.5, 12.0, 10.5)  # to (6, 11), clipped at the right edge
    chk = IntrusionChecker(np.array([[0.1, 0.1]]))
    chk.set_corridors([wide])
    (hit,) = chk.check(np.array([[7.0, 6.5, 0.0]]))
    assert hit.depth_m == pytest.approx(0.1 + 4.1, abs=1e-9)


def test_margin_only_touch_far_body_and_skip():
    cor = long_corridor()
    half = np.array([[0.3, 0.2]] * 4)
    chk = IntrusionChecker(half)
    chk.set_corridors([cor])
    poses = np.array([[12.0, 2.3, 0.0],            # 0.1 m below the walkway: in the margin
                      [12.0, 2.5, 0.0],            # 0.3 m: outside the 0.2 m margin
                      [12.0, 2.0 + 0.3 + 0.15, np.pi / 2],  # rotated, 0.15 m away
                      [5.0, 1.0, 0.3]])            # inside
    found = {(i.agv, i.corridor): i.depth_m for i in chk.check(poses)}
    assert set(found) == {(0, 0), (2, 0), (3, 0)}
    assert 0 < found[(0, 0)] <= cor.margin_m and found[(0, 0)] == pytest.approx(0.1)
    assert found[(2, 0)] == pytest.approx(0.05)
    assert found[(3, 0)] > cor.margin_m
    assert [i.agv for i in chk.check(poses, skip={0, 3})] == [2]
    # Moved bodies are re-posed; unchanged ones keep their place.
    poses2 = poses.copy()
    poses2[3] = [12.0, 5.0, 0.0]
    poses2[1] = [12.0, 2.35, 0.0]
    assert [(i.agv, round(i.depth_m, 9)) for i in chk.check(poses2)] == \
        [(0, 0.1), (1, 0.05), (2, 0.05)]
    # Just inside / just outside the margin (0.1 mm either side of it).
    near = np.array([[12.0, 2.2 + 0.2 - 1e-4, 0.0], [12.0, 2.2 + 0.2 + 1e-4, 0.0],
                     [12.0, 2.2 + 0.2 + 1e-4, 0.0], [12.0, 9.0, 0.0]])
    assert [(i.agv, round(i.depth_m, 9)) for i in chk.check(near)] == [(0, 1e-4)]
    chk.set_corridors([])
    assert chk.check(poses) == []


def test_checker_rejects_bad_shapes():
    for half in ([[0.3, -0.1]], [[0.3, np.nan]], [[0.3, np.inf]], [0.3, 0.2]):
        with pytest.raises(ValueError):
            IntrusionChecker(np.array(half))
    # A zero length or width is a segment (or a point), measured like any body.
    assert IntrusionChecker(np.array([[0.3, 0.0]])).n == 1
    chk = IntrusionChecker(np.array([[0.3, 0.2]]))
    chk.set_corridors([long_corridor()])
    with pytest.raises(ValueError):
        chk.check(np.zeros((2, 3)))


def test_max_depth_per_agv_and_corridor():
    lay = make_layout(LONG)
    a = corridor(lay, [(0, 2)], width_m=1.0, margin_m=0.2, cid=4)
    b = corridor(lay, [(3, 10)], width_m=1.0, margin_m=0.5, cid=9, agv=1)
    chk = IntrusionChecker(np.array([[12.0, 0.3]]))  # one long body across both
    chk.set_corridors([a, b])
    poses = np.array([[11.0, 2.0, np.pi / 2]])
    got = chk.check(poses)
    assert [(i.agv, i.corridor) for i in got] == [(0, 4), (0, 9)]
    ref = intrusions_shapely(poses, chk.half_sizes, [a, b])
    assert [i.depth_m for i in got] == pytest.approx([i.depth_m for i in ref], abs=1e-9)


# --------------------------------------------------------------------------- property


@st.composite
def scenes(draw):
    rows, cols = draw(st.integers(3, 8)), draw(st.integers(3, 8))
    cell_m = draw(st.sampled_from([0.5, 1.0, 1.3]))
    cells = draw(st.lists(st.sampled_from(".....#SA"), min_size=rows * cols,
                          max_size=rows * cols))
    cells[0], cells[-1] = "S", "R"
    grid = ["".join(cells[r * cols:(r + 1) * cols]) for r in range(rows)]
    lay = make_layout(grid, cell_m)
    free = np.flatnonzero(~(lay.obstacles | lay.shelf_mask).ravel()).tolist()
    assume(free)
    cors = []
    for k in range(draw(st.integers(1, 3))):
        start = draw(st.sampled_from(free))
        foot = [start]
        if draw(st.booleans()) and start + 1 in free and (start + 1) % cols:
            foot.append(start + 1)  # moving between two cells
        width = draw(st.floats(0.2, min(rows, cols) * cell_m))
        margin = draw(st.one_of(st.just(0.0), st.floats(0.0, 0.6)))
        try:
            cors.append(plan_corridor(lay, 10 + k, k, foot, width, margin))
        except LayoutError:
            pass
    assume(cors)
    n = draw(st.integers(1, 25))
    xy = draw(st.lists(st.tuples(st.floats(-1.0, cols * cell_m + 1.0),
                                 st.floats(-1.0, rows * cell_m + 1.0),
                                 st.floats(-np.pi, np.pi)), min_size=2 * n, max_size=2 * n))
    half = draw(st.lists(st.tuples(st.floats(0.05, 0.7), st.floats(0.05, 0.7)),
                         min_size=n, max_size=n))
    skip = draw(st.sets(st.integers(0, n - 1), max_size=2))
    return cors, np.array(xy[:n]), np.array(xy[n:]), np.array(half), skip


def near_margin_boundary(poses, half, cors, tol=1e-6) -> bool:
    """Some body is within ``tol`` of a corridor's margin boundary (its report is ambiguous)."""
    bodies = agv_boxes(poses, half)
    for cor in cors:
        dist = shapely.distance(bodies, cor.polygon)
        if cor.margin_m > 0 and (np.abs(dist - cor.margin_m) < tol).any():
            return True
        if cor.margin_m == 0:
            overlap = shapely.area(shapely.intersection(bodies, cor.polygon))
            if ((dist < tol) & (overlap < 10 * tol)).any():
                return True
    return False


# 150 examples: random scenes: the two checkers differ only in rare corner cases
@pytest.mark.slow  # fcl against shapely on many poses: make test-all
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                   HealthCheck.filter_too_much])
@given(scenes())
def test_fcl_checker_matches_shapely_reference(scene):
    cors, poses_a, poses_b, half, skip = scene
    poses_b[::2] = poses_a[::2]  # the second call moves only some of the bodies
    assume(not near_margin_boundary(poses_a, half, cors))
    assume(not near_margin_boundary(poses_b, half, cors))
    chk = IntrusionChecker(half)
    chk.set_corridors(cors)
    for poses in (poses_a, poses_b):
        got = chk.check(poses, skip=skip)
        ref = intrusions_shapely(poses, half, cors, skip=skip)
        assert [(i.agv, i.corridor) for i in got] == [(i.agv, i.corridor) for i in ref]
        assert [i.depth_m for i in got] == pytest.approx([i.depth_m for i in ref], abs=1e-6)
        # The definition, checked against the corridor polygon directly.
        bodies = agv_boxes(poses, half)
        by_pair = {(i.agv, i.corridor): i.depth_m for i in got}
        for cor in cors:
            dist = shapely.distance(bodies, cor.polygon)
            overlap = shapely.area(shapely.intersection(bodies, cor.polygon))
            for a in range(len(poses)):
                depth = by_pair.get((a, cor.id))
                if a in skip or dist[a] > cor.margin_m:
                    assert depth is None
                elif dist[a] > 0:
                    assert depth == pytest.approx(cor.margin_m - dist[a], abs=1e-6)
                elif overlap[a] > 1e-6:
                    assert depth is not None and depth > cor.margin_m
