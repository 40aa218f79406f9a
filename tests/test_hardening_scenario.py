"""Numbers in scenarios are finite, strictly typed and within documented ranges; a bad one
is one :class:`ScenarioError` naming the file, the field and the value (CLI: exit 2)."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml
from hardening_helpers import LAYOUTS, assert_clean_error, run_cli

from warerover_phys.config import load_scenario
from warerover_phys.errors import ScenarioError
from warerover_phys.world import World

TINY: dict[str, Any] = {
    "name": "tiny",
    "max_ticks": 200,
    "layout": {"grid": ["#########", "#R.....P#", "#..S.S..#", "#R.....P#", "#########"]},
    "fleet": {"types": {"agv": {"max_speed_mps": 1.5}}, "agvs": [{"type": "agv", "count": 2}]},
    "orders": {"pattern": "oneshot", "oneshot": {"count": 3}},
}


def setpath(data: dict, path: str, value: Any) -> dict:
    data = copy.deepcopy(data)
    node: Any = data
    parts = path.split(".")
    for part in parts[:-1]:
        node = node[int(part)] if isinstance(node, list) else node.setdefault(part, {})
    last = parts[-1]
    if isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value
    return data


# (field path, value, what the message must name: the field as the error prints it)
BAD: list[tuple[str, Any, str]] = [
    ("tick_s", float("inf"), "tick_s"),
    ("tick_s", float("nan"), "tick_s"),
    ("tick_s", 1e308, "tick_s"),
    ("tick_s", True, "tick_s"),
    ("tick_s", "1.0", "tick_s"),
    ("max_ticks", True, "max_ticks"),
    ("max_ticks", 10**30, "max_ticks"),
    ("max_ticks", 2.5, "max_ticks"),
    ("max_ticks", float("inf"), "max_ticks"),
    ("seed", 1e308, "seed"),
    ("seed", 2**70, "seed"),
    ("seed", False, "seed"),
    ("layout.cell_m", float("inf"), "layout.cell_m"),
    ("layout.cell_m", -1.0, "layout.cell_m"),
    ("layout.cell_m", 1e308, "layout.cell_m"),
    ("fleet.agvs.0.count", 10**12, "fleet.agvs[0].count"),
    ("fleet.agvs.0.count", True, "fleet.agvs[0].count"),
    ("fleet.types.agv.max_speed_mps", float("nan"), "fleet.types.agv.max_speed_mps"),
    ("fleet.types.agv.max_speed_mps", 1e-300, "fleet.types.agv.max_speed_mps"),
    ("fleet.types.agv.body_m", [float("inf"), 0.7], "fleet.types.agv.body_m[0]"),
    ("fleet.types.agv.mass_kg", 1e308, "fleet.types.agv.mass_kg"),
    ("orders.oneshot.count", 10**12, "orders.oneshot.count"),
    ("orders.oneshot.count", 1e308, "orders.oneshot.count"),
    ("orders.duration_ticks", 10**18, "orders.duration_ticks"),
    ("orders.large_fraction", float("nan"), "orders.large_fraction"),
    ("orders.hotspot.scale", float("inf"), "orders.hotspot.scale"),
    ("orders.wave.max_mult", 1e308, "orders.wave.max_mult"),
    ("tasks.pick_ticks", -1, "tasks.pick_ticks"),
    ("tasks.pick_ticks", True, "tasks.pick_ticks"),
    ("planner.time_budget_s", float("inf"), "planner.time_budget_s"),
    ("planner.max_expansions", 10**30, "planner.max_expansions"),
    ("executor.dt_s", float("nan"), "executor.dt_s"),
    ("executor.dt_s", 2.0, "executor.dt_s"),          # longer than tick_s = 1.0
    ("executor.dt_s", 1e-6, "executor.dt_s"),         # a million physics steps per tick
    ("orders.hotspot.alpha", 1e-6, "orders.hotspot.alpha"),
    ("layout.inventory.skus_per_shelf", 10**6, "layout.inventory.skus_per_shelf"),
    ("executor.adg", "yes please", "executor.adg"),
    ("executor.adg", 1, "executor.adg"),
    ("executor.trajectory_hz", float("inf"), "executor.trajectory_hz"),
    ("faults.random.prob_per_tick", float("nan"), "faults.random.prob_per_tick"),
    ("faults.corridor_margin_m", float("inf"), "faults.corridor_margin_m"),
    ("layout.inventory.seed", -3, "layout.inventory.seed"),
    ("name", "../../x", "name"),
    ("name", "/tmp/evil", "name"),
    ("name", "a/b", "name"),
    ("name", ".hidden", "name"),
    ("name", "", "name"),
    ("name", "x" * 500, "name"),
]


@pytest.mark.parametrize("field,value,named", BAD, ids=[f"{f}={v!r}"[:50] for f, v, _ in BAD])
def test_bad_number_is_a_clean_error(tmp_path, field, value, named):
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(setpath(TINY, field, value)), encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        World.build(load_scenario(path))
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith(str(path)), text
    assert named in text, text


def test_inf_from_yaml_text(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(TINY) + "tick_s: .inf\n", encoding="utf-8")
    with pytest.raises(ScenarioError, match="tick_s"):
        load_scenario(path)


def test_huge_layout_size(tmp_path):
    data = setpath(TINY, "layout", {"size": [4000, 4000], "stations": [[0, 0]]})
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(ScenarioError, match="layout.size"):
        load_scenario(path)


def test_huge_generated_layout(tmp_path):
    data = setpath(TINY, "layout", {"generator": {"block_rows": 100000, "block_cols": 100000}})
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(ScenarioError, match="layout.generator"):
        World.build(load_scenario(path))


def test_huge_order_stream(tmp_path):
    data = setpath(TINY, "orders", {"pattern": "constant", "duration_ticks": 1_000_000,
                                    "constant": {"batch": 1000, "every_ticks": 1}})
    data["max_ticks"] = 1_000_000
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(ScenarioError, match="orders.constant"):
        load_scenario(path)


def test_shipped_scenarios_still_load():
    for path in sorted(LAYOUTS.glob("*.yaml")):
        load_scenario(path)


@pytest.fixture(scope="module")
def cli_cases(tmp_path_factory):
    """A few of the cases above through the real console script, run together."""
    from concurrent.futures import ThreadPoolExecutor

    root = tmp_path_factory.mktemp("cli")
    cases = {"inf": ("tick_s", float("inf")), "bool": ("max_ticks", True),
             "dt": ("executor.dt_s", 2.0), "count": ("orders.oneshot.count", 10**12),
             "name": ("name", "../../escaped")}
    paths = {}
    for key, (field, value) in cases.items():
        paths[key] = root / f"{key}.yaml"
        paths[key].write_text(yaml.safe_dump(setpath(TINY, field, value)), encoding="utf-8")
    with ThreadPoolExecutor(2) as pool:
        futs = {k: pool.submit(run_cli, "run", p, "--json", cwd=root) for k, p in paths.items()}
        return root, paths, {k: f.result() for k, f in futs.items()}


@pytest.mark.parametrize("key,field", [("inf", "tick_s"), ("bool", "max_ticks"),
                                       ("dt", "executor.dt_s"),
                                       ("count", "orders.oneshot.count"), ("name", "name")])
def test_cli_exit_2(cli_cases, key, field):
    root, paths, procs = cli_cases
    assert_clean_error(procs[key], str(paths[key].name), field)
    assert not (root / "runs").exists()
    assert not Path(root.parent / "escaped-seed0").exists()
