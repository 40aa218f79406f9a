"""Scenario schema details: shorthands, overrides, frozen models, cross-field checks."""

from __future__ import annotations

import pydantic
import pytest

from warerover_phys.config import apply_overrides, parse_override, scenario_from_dict
from warerover_phys.errors import ScenarioError

BASE = {"layout": {"grid": ["P..SR"]}, "fleet": {"agvs": [{"count": 1}]}}


def test_shorthands_and_defaults():
    sc = scenario_from_dict({**BASE, "scheduler": "rd", "planner": {"name": "astar"}})
    assert sc.scheduler.name == "rd" and sc.scheduler.max_orders_per_trip == 4
    assert sc.orders.pattern == "oneshot" and sc.orders.oneshot.count == 20
    assert sc.fleet.types["default"].ticks_per_move(1.0, 1.0) == 1


def test_overrides_reach_any_field_and_keep_the_input():
    data = {**BASE, "scheduler": "ta"}
    sc = scenario_from_dict(data, overrides=[parse_override("orders.pattern=burst"),
                                             parse_override("orders.burst.start_prob=0.5"),
                                             parse_override("scheduler.name=rd"),
                                             parse_override("fleet.agvs.0.count=1"),
                                             parse_override("tick_s=0.5")])
    assert sc.orders.pattern == "burst" and sc.orders.burst.start_prob == 0.5
    assert sc.scheduler.name == "rd" and sc.tick_s == 0.5
    assert data["scheduler"] == "ta"  # the caller's dict is not changed
    assert apply_overrides({"a": {"b": 1}}, [("a.c", [1, 2])]) == {"a": {"b": 1, "c": [1, 2]}}


def test_ticks_per_move_follows_speed_and_tick():
    spec = scenario_from_dict(BASE).fleet.types["default"]
    assert spec.ticks_per_move(1.0, 1.0) == 1          # 1.5 m/s covers a 1 m cell in a tick
    assert spec.ticks_per_move(1.0, 0.5) == 2          # 0.75 m per half-second tick
    assert spec.ticks_per_move(2.0, 1.0) == 2


def test_scenarios_are_frozen():
    sc = scenario_from_dict(BASE)
    with pytest.raises(pydantic.ValidationError):
        sc.seed = 3
    assert sc.with_seed(3).seed == 3 and sc.seed == 0


def test_scheduled_fault_must_name_a_real_agv():
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict({**BASE, "faults": {"scheduled": [{"agv": 3, "tick": 5}]}},
                           source="x.yaml")
    assert err.value.field == "faults.scheduled[0].agv" and err.value.value == 3
