"""TA's matching is optimal against costs this test computes itself.

The oracle knows only the floor (which cells are walls, shelves, stations), where the AGVs
stand, which SKUs each shelf holds and the pending orders: it runs its own breadth-first
searches (an unloaded AGV drives under shelves, a loaded one only around them) and brute-
forces every matching of idle AGVs to SKU groups. It never calls a method of the scheduler
other than ``assign``, nor the world's distance tables: a wrong trip cost in TA (or in the
world's tables TA uses) makes TA's choice cost more than the optimum here.
"""

from __future__ import annotations

import itertools
import math
from collections import deque

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from warerover_phys import scenario_from_dict
from warerover_phys.orders import Order
from warerover_phys.schedulers import TaskAssignment
from warerover_phys.world import World

# Walls make the unloaded leg differ from the Manhattan distance, shelf rows make the loaded
# leg go round them. R: station, S: shelf, P: parking, #: wall.
GRID = ["R.....#.......R",
        ".SSS..#..SSS...",
        "......#........",
        ".##.......##.#.",
        ".SSS.#...SSS...",
        ".......#.......",
        "PPP....R......."]
FREE = [(r, c) for r, row in enumerate(GRID) for c, ch in enumerate(row) if ch in ".P"]
STEPS = ((0, 1), (1, 0), (0, -1), (-1, 0))


def bfs(source: tuple[int, int], passable) -> dict[tuple[int, int], int]:
    """Moves from ``source`` to every cell reachable through cells ``passable(cell)``."""
    dist = {source: 0}
    todo = deque([source])
    while todo:
        r, c = todo.popleft()
        for dr, dc in STEPS:
            nxt = (r + dr, c + dc)
            if 0 <= nxt[0] < len(GRID) and 0 <= nxt[1] < len(GRID[0]) \
                    and nxt not in dist and passable(nxt):
                dist[nxt] = dist[(r, c)] + 1
                todo.append(nxt)
    return dist


def unloaded(cell) -> bool:
    return GRID[cell[0]][cell[1]] != "#"


def loaded(cell) -> bool:
    return GRID[cell[0]][cell[1]] not in "#S"


def trip_cost(start, shelf_cell, station_cells) -> float:
    """Moves of a trip: to the shelf unloaded, then loaded to each station in turn
    (``math.inf`` where a leg is impossible)."""
    d = bfs(start, unloaded).get(shelf_cell, math.inf)
    here = shelf_cell
    for target in station_cells:
        d += bfs(here, loaded).get(target, math.inf)
        here = target
    return d


def world_for(starts, inventory_seed: int, cap: int, cost: str) -> World:
    return World.build(scenario_from_dict({
        "layout": {"grid": GRID,
                   "inventory": {"num_skus": 6, "skus_per_shelf": 1, "seed": inventory_seed}},
        "fleet": {"agvs": [{"count": len(starts), "starts": [list(s) for s in starts]}]},
        # candidate_shelves above the shelf count: TA weighs every shelf, as the oracle
        "scheduler": {"name": "ta", "max_orders_per_trip": cap, "ta_cost": cost,
                      "candidate_shelves": 20}}))


def oracle_cost(w: World, agv_cell, shelf: int, order_ids, cost: str) -> float:
    """What serving ``order_ids`` from ``shelf`` costs an AGV at ``agv_cell``: the trip's
    moves (stations visited in ascending index, as TA's trips go), per order served with
    ``ta_cost: per_order``."""
    stations = sorted({w.orders[o].station for o in order_ids})
    d = trip_cost(agv_cell, w.layout.shelves[shelf].anchor,
                  [tuple(w.layout.stations[s]) for s in stations])
    return d if cost == "trip" else d / len(order_ids)


@given(starts=st.lists(st.sampled_from(FREE), min_size=1, max_size=3, unique=True),
       orders=st.lists(st.tuples(st.integers(0, 5), st.integers(0, 2)), min_size=1,
                       max_size=7),
       inventory_seed=st.integers(0, 1000),
       variant=st.sampled_from([(1, "trip"), (2, "per_order"), (3, "per_order"),
                                (2, "trip")]))
def test_ta_matching_is_optimal_against_bfs_costs(starts, orders, inventory_seed, variant):
    cap, cost = variant
    w = world_for(starts, inventory_seed, cap, cost)
    w.add_orders([Order(i, 0, sku, station, 1) for i, (sku, station) in enumerate(orders)])
    out = TaskAssignment(w.scenario.scheduler).assign(w, np.random.default_rng(0))

    cell_of = {a.id: w.cell(a.node) for a in w.agvs}
    groups: dict[int, list[int]] = {}
    for i, (sku, _) in enumerate(orders):
        groups.setdefault(sku, []).append(i)
    skus = sorted(groups)
    shelves_of = {sku: [s.id for s in w.layout.shelves if sku in s.skus] for sku in skus}

    # What TA chose, costed here: distinct AGVs and shelves, each trip serving orders of one
    # SKU group (one SKU per shelf), the group's first orders by id.
    assert len({a.agv for a in out}) == len(out) == len({a.shelf for a in out})
    got = 0.0
    for a in out:
        sku = w.orders[a.orders[0]].sku
        assert sku in w.layout.shelves[a.shelf].skus
        assert list(a.orders) == groups[sku][:cap]
        got += oracle_cost(w, cell_of[a.agv], a.shelf, a.orders, cost)

    # The optimum over every matching of idle AGVs to SKU groups, each pair at its
    # cheapest shelf.
    def pair(agv: int, sku: int) -> float:
        return min(oracle_cost(w, cell_of[agv], s, groups[sku][:cap], cost)
                   for s in shelves_of[sku])

    table = {(a, s): pair(a, s) for a in cell_of for s in skus}
    n = min(len(cell_of), len(skus))
    best = min(sum(table[p] for p in zip(agvs, chosen, strict=True))
               for agvs in itertools.permutations(cell_of, n)
               for chosen in itertools.permutations(skus, n))
    assert len(out) == n
    assert math.isclose(got, best, rel_tol=1e-9), (got, best, table)


def test_the_oracle_distances_go_round_walls_and_shelves():
    """The oracle's own legs on the floor above, counted by hand."""
    # unloaded, under the wall at (0..2, 6): down to row 3 and back up: 4, not 2
    assert bfs((2, 5), unloaded)[(2, 7)] == 4
    # unloaded AGVs drive under shelves: (0, 1) to (2, 1) straight through shelf (1, 1)
    assert bfs((0, 1), unloaded)[(2, 1)] == 2
    # loaded from shelf (4, 2): wall above, shelves beside: down to row 5, along, down
    assert bfs((4, 2), loaded)[(6, 7)] == 7
    # loaded, (0, 1) to (2, 1) goes round the shelf row: left, down 2, right
    assert bfs((0, 1), loaded)[(2, 1)] == 4
    assert trip_cost((6, 0), (1, 1), [(0, 0)]) == 6 + 2
