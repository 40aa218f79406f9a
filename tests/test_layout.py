"""Layout bases (ASCII grid, structured, MovingAI map, generator) and their checks."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from warerover_phys.config import GeneratorSpec, LayoutSpec, scenario_from_dict
from warerover_phys.errors import LayoutError, ScenarioError
from warerover_phys.layout import CellType, build_layout, generate_base
from warerover_phys.sim import run_episode
from warerover_phys.world import World

DATA = Path(__file__).parent / "data"


def test_ascii_grid_cells_and_orientation():
    layout = build_layout(LayoutSpec(grid=["P.S.",
                                           "#..R"]))
    assert (layout.rows, layout.cols) == (2, 4)
    assert layout.grid[0, 2] == CellType.SHELF
    assert layout.grid[1, 0] == CellType.OBSTACLE
    assert layout.stations == ((1, 3),)
    assert layout.parking == ((0, 0),)
    assert layout.to_ascii() == ["P.S.", "#..R"]


def test_structured_layout_places_blocks_and_inventory():
    spec = LayoutSpec(size=(10, 12), shelf_blocks=[{"origin": (2, 2), "rows": 2, "cols": 3},
                                                   {"origin": (6, 2), "rows": 1, "cols": 2,
                                                    "size": 2}],
                      stations=[(0, 0), (9, 0)], parking=[{"origin": (9, 5), "cols": 4}],
                      inventory={"num_skus": 10, "skus_per_shelf": 3})
    layout = build_layout(spec)
    sizes = sorted(s.size for s in layout.shelves)
    assert sizes == [1] * 6 + [2] * 2
    assert int((layout.grid == CellType.SHELF).sum()) == 6 + 2 * 4
    # Every SKU is on some shelf, and shelves of one size class hold SKUs of that class.
    assert set(layout.sku_shelves) == set(range(layout.num_skus))
    for shelf in layout.shelves:
        assert all(layout.sku_sizes[sku] == shelf.size for sku in shelf.skus)
        assert 1 <= len(shelf.skus) <= 3
    # Same inventory seed, same contents.
    assert build_layout(spec).shelves == layout.shelves


def test_movingai_map_as_base():
    spec = LayoutSpec(map=str(DATA / "warehouse-10-20-10-2-1.map"),
                      stations=[(1, 1), (61, 1)], parking=[{"origin": (1, 5), "cols": 4}],
                      shelf_blocks=[{"origin": (30, 3), "rows": 2, "cols": 2}])
    layout = build_layout(spec)
    assert (layout.rows, layout.cols) == (63, 161)
    text = (DATA / "warehouse-10-20-10-2-1.map").read_text().splitlines()[4:]
    expected = sum(ch in "@OTW" for line in text for ch in line)
    assert int(layout.obstacles.sum()) == expected
    with pytest.raises(ScenarioError) as err:
        build_layout(LayoutSpec(map=str(DATA / "warehouse-10-20-10-2-1.map"),
                                stations=[(2, 26)]))
    assert err.value.field == "layout.stations[0]"  # (2, 26) is a shelf of the map


@pytest.mark.no_cover  # a CPU-time bound: measured without coverage's tracer
@pytest.mark.parametrize("blocks,shape", [((2, 2), (2, 3)), ((45, 56), (2, 8))])
def test_generator_scales(blocks, shape):
    gen = GeneratorSpec(block_rows=blocks[0], block_cols=blocks[1], block_shape=shape,
                        stations=12, parking=40)
    t = time.process_time()  # CPU time: a loaded machine does not stretch it
    grid = generate_base(gen, fleet_size=40)
    elapsed = time.process_time() - t
    shelves = int((grid == CellType.SHELF).sum())
    assert shelves == blocks[0] * blocks[1] * shape[0] * shape[1]
    assert int((grid == CellType.STATION).sum()) == 12
    assert int((grid == CellType.PARKING).sum()) == 40
    if blocks == (45, 56):
        assert grid.shape[0] >= 140 and grid.shape[1] >= 500, grid.shape
        assert elapsed < 2.0


@pytest.mark.no_cover  # a CPU-time bound: measured without coverage's tracer
def test_generated_industrial_size_layout_passes_checks():
    sc = scenario_from_dict({
        "layout": {"generator": {"block_rows": 20, "block_cols": 44, "block_shape": [2, 10],
                                 "aisle_width": 1, "stations": 30}},
        "fleet": {"agvs": [{"count": 400}]}})
    t = time.process_time()  # CPU time: a loaded machine does not stretch it
    world = World.build(sc)
    assert world.layout.rows >= 60 and world.layout.cols >= 480
    assert len(world.agvs) == 400
    assert time.process_time() - t < 30


def test_reachability_is_checked_for_the_largest_footprint():
    grid = ["PP.........R",
            "PP.SSS......",
            "............"]
    ok = {"layout": {"grid": grid},
          "fleet": {"types": {"big": {"footprint": 2, "body_m": [1.5, 1.5]}},
                    "agvs": [{"type": "big", "count": 1}]}}
    # The only shelves are 1x1: nobody can carry them.
    with pytest.raises(LayoutError) as err:
        World.build(scenario_from_dict(ok))
    assert err.value.field == "fleet.types"
    # A 2x2 station corner in a 1-wide dead end cannot be reached by a 2x2 AGV.
    narrow = ["PP......#R",
              "PP......#.",
              "P.SS......"]
    mixed = {"layout": {"grid": narrow},
             "fleet": {"types": {"small": {}, "big": {"footprint": 2, "body_m": [1.5, 1.5]}},
                       "agvs": [{"type": "small", "count": 1}, {"type": "big", "count": 1}]}}
    with pytest.raises(LayoutError) as err:
        World.build(scenario_from_dict(mixed))
    assert err.value.field == "fleet.types.big.footprint"
    # Without the big AGV it is fine and runs.
    mixed["fleet"]["agvs"] = [{"type": "small", "count": 1}]
    assert run_episode(scenario_from_dict(mixed), seed=0).metrics["success_rate"] == 1.0


def test_walled_in_station_is_reported():
    grid = ["P.....#R",
            "..SS..##",
            "........"]
    with pytest.raises(LayoutError) as err:
        World.build(scenario_from_dict({"layout": {"grid": grid},
                                        "fleet": {"agvs": [{"count": 1}]}}))
    assert err.value.field == "layout.stations[0]"
    assert err.value.value == [0, 7]


def test_inventory_is_fixed_by_its_own_seed():
    spec = {"size": (6, 8), "shelf_blocks": [{"origin": (2, 2), "rows": 2, "cols": 4}],
            "stations": [(0, 0)]}
    a = build_layout(LayoutSpec(**spec, inventory={"seed": 1}))
    b = build_layout(LayoutSpec(**spec, inventory={"seed": 2}))
    assert [s.skus for s in a.shelves] != [s.skus for s in b.shelves]
    assert np.array_equal(a.grid, b.grid)
