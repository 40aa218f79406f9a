"""Property-based fuzzing (hypothesis): random and mutated scenarios, YAML text and
trajectory files either load or raise a :class:`WareroverError` — never anything else."""

from __future__ import annotations

import copy
import io
import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hardening_helpers import LAYOUTS
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys.config import load_scenario, scenario_from_dict
from warerover_phys.errors import WareroverError
from warerover_phys.world import World

TINY: dict[str, Any] = {
    "name": "tiny",
    "max_ticks": 50,
    "layout": {"grid": ["#########", "#R.....P#", "#..S.S..#", "#R.....P#", "#########"],
               "inventory": {"num_skus": 4, "skus_per_shelf": 2}},
    "fleet": {"types": {"agv": {"max_speed_mps": 1.5, "body_m": [0.7, 0.7]}},
              "agvs": [{"type": "agv", "count": 2}]},
    "orders": {"pattern": "constant", "duration_ticks": 20,
               "constant": {"batch": 2, "every_ticks": 10}},
    "tasks": {"pick_ticks": 1},
    "scheduler": "ta", "planner": {"name": "astar"},
    "executor": {"name": "grid", "dt_s": 0.05},
    "faults": {"random": {"prob_per_tick": 0.0}, "scheduled": [{"agv": 0, "tick": 3}]},
}
# 150 examples: fuzzed inputs, one cheap parse each
SETTINGS = settings(max_examples=150, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])

SPECIAL = [0, -1, 1, 2, 10**9, 10**30, -(10**30), 1e308, -1e308, math.inf, -math.inf, math.nan,
           0.5, 1e-300, True, False, None, "", "x", "../../x", "1.5", [], {}, [1, 2],
           [[1, 2]], {"a": 1}, "astar", "physics", "burst", "pkg.mod:Cls", "\x00"]
values = st.recursive(
    st.one_of(st.sampled_from(SPECIAL), st.integers(-5, 50), st.floats(allow_nan=True),
              st.text(max_size=8), st.booleans(), st.none()),
    lambda inner: st.one_of(st.lists(inner, max_size=3),
                            st.dictionaries(st.text(max_size=6), inner, max_size=3)),
    max_leaves=6)


def paths_of(node: Any, prefix: tuple = ()) -> list[tuple]:
    out = [prefix] if prefix else []
    if isinstance(node, dict):
        for k, v in node.items():
            out += paths_of(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += paths_of(v, (*prefix, i))
    return out


PATHS = paths_of(TINY)
KEYS = sorted({p[-1] for p in PATHS if isinstance(p[-1], str)})


@st.composite
def mutated(draw) -> dict:
    data = copy.deepcopy(TINY)
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(PATHS))
        node = data
        try:
            for part in path[:-1]:
                node = node[part]
            action = draw(st.sampled_from(["set", "set", "delete", "rename"]))
            if action == "set":
                node[path[-1]] = draw(values)
            elif action == "delete":
                del node[path[-1]]
            elif isinstance(node, dict):
                node[draw(st.sampled_from(KEYS))] = node.pop(path[-1])
        except (KeyError, IndexError, TypeError):
            continue
    return data


def build(data: Any) -> None:
    try:
        if not isinstance(data, dict):
            raise WareroverError("not a mapping")
        World.build(scenario_from_dict(data, source="fuzz.yaml"))
    except WareroverError as err:
        assert "\n" not in str(err), str(err)


@SETTINGS
@given(mutated())
def test_mutated_scenarios(data):
    build(data)


@SETTINGS
@given(st.dictionaries(st.sampled_from(list(TINY) + ["extra"]), values, max_size=6))
def test_random_scenarios(data):
    build(data)


TEXT = (LAYOUTS / "paper_fault.yaml").read_text(encoding="utf-8")


@SETTINGS
@given(st.data())
def test_mutated_yaml_text(data):
    text = TEXT
    for _ in range(data.draw(st.integers(1, 3))):
        i = data.draw(st.integers(0, len(text)))
        op = data.draw(st.sampled_from(["cut", "insert", "delete", "dup"]))
        if op == "cut":
            text = text[:i]
        elif op == "insert":
            text = text[:i] + data.draw(st.sampled_from(
                [":", "-", "[", "{", "&a", "*a", "!!python/object:os.system", "\t", "'",
                 "\n  ", "<<: *a", "~", ".inf", "1e400", "\x00", "é"])) + text[i:]
        elif op == "delete":
            text = text[:i] + text[i + data.draw(st.integers(1, 20)):]
        else:
            text = text[:i] + text[i:i + 40] * 3 + text[i + 40:]
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "paper_fault.yaml"
        path.write_text(text, encoding="utf-8")
        (Path(d) / "maps").mkdir()
        for m in (LAYOUTS / "maps").glob("*.yaml"):
            (Path(d) / "maps" / m.name).write_text(m.read_text())
        try:
            World.build(load_scenario(path))
        except WareroverError as err:
            assert "\n" not in str(err)


@SETTINGS
@given(st.binary(max_size=300))
def test_random_bytes_as_yaml(raw):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "s.yaml"
        path.write_bytes(raw)
        try:
            load_scenario(path)
        except WareroverError:
            pass


# ------------------------------------------------------------------------- trajectories


@pytest.fixture(scope="module")
def traj_arrays(tmp_path_factory) -> dict[str, np.ndarray]:
    from warerover_phys import run_episode
    from warerover_phys.render import grid_trajectory

    sc = load_scenario(LAYOUTS / "paper_homogeneous.yaml", [("max_ticks", 15)])
    return grid_trajectory(run_episode(sc, seed=0))


ARRAYS = st.one_of(
    st.just(np.zeros(0)), st.just(np.array(np.nan)), st.just(np.array("text")),
    st.just(np.ones((3, 2, 2))), st.just(np.array([1, 2, 3], dtype=np.int8)),
    st.just(np.full((2, 2), np.inf)), st.just(np.array(["a", "b"])),
    st.just(np.zeros((0, 0), dtype=np.int64)), st.just(np.array([-1.0])))


@settings(max_examples=100, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(st.data())
def test_mutated_trajectories(traj_arrays, data):
    from warerover_phys.render import load_trajectory

    traj = dict(traj_arrays)
    for _ in range(data.draw(st.integers(1, 3))):
        key = data.draw(st.sampled_from(sorted(traj)))
        op = data.draw(st.sampled_from(["drop", "replace", "slice", "scale"]))
        if op == "drop":
            traj.pop(key)
        elif op == "replace":
            traj[key] = data.draw(ARRAYS)
        elif op == "slice" and np.ndim(traj[key]) >= 1:
            traj[key] = traj[key][: data.draw(st.integers(0, 3))]
        elif op == "scale" and np.asarray(traj[key]).dtype.kind == "f":
            traj[key] = traj[key] * data.draw(st.sampled_from([-1.0, 0.0, np.inf, np.nan]))
        if not traj:
            break
    buf = io.BytesIO()
    np.savez(buf, **traj)
    raw = buf.getvalue()
    if data.draw(st.booleans()):
        i = data.draw(st.integers(0, len(raw)))
        raw = raw[:i] + data.draw(st.binary(max_size=8)) + raw[i + 8:]
    with tempfile.TemporaryDirectory() as d:
        (Path(d) / "trajectories.npz").write_bytes(raw)
        try:
            rec = load_trajectory(d)
        except WareroverError as err:
            assert "\n" not in str(err)
        else:
            rec.at(rec.start_s)
            rec.at(rec.end_s)


# ------------------------------------------------------------------------- MovingAI files

MAP_TEXT = (Path(__file__).parent / "data" / "random-32-32-10.map").read_text()
SCEN_TEXT = "\n".join((Path(__file__).parent / "data" /
                       "random-32-32-10-random-1.scen").read_text().splitlines()[:12]) + "\n"


def mutate_text(data, text: str) -> str:
    for _ in range(data.draw(st.integers(1, 3))):
        i = data.draw(st.integers(0, len(text)))
        op = data.draw(st.sampled_from(["cut", "insert", "delete"]))
        if op == "cut":
            text = text[:i]
        elif op == "insert":
            text = text[:i] + data.draw(st.sampled_from(
                ["\t", "-1", "1e999", "nan", "@", "\n", " ", "x", "99999999999", "é", "\x00"]
            )) + text[i:]
        else:
            text = text[:i] + text[i + data.draw(st.integers(1, 30)):]
    return text


@SETTINGS
@given(st.data())
def test_mutated_movingai_files(data):
    from warerover_phys.problems.movingai import read_map, read_scen

    mutate_map = data.draw(st.booleans())
    map_text = mutate_text(data, MAP_TEXT) if mutate_map else MAP_TEXT
    scen_text = SCEN_TEXT if mutate_map else mutate_text(data, SCEN_TEXT)
    with tempfile.TemporaryDirectory() as d:
        mp, sp = Path(d) / "m.map", Path(d) / "s.scen"
        mp.write_text(map_text, encoding="utf-8")
        sp.write_text(scen_text, encoding="utf-8")
        try:
            grid = read_map(mp)
            read_scen(sp, data.draw(st.integers(0, 12)), grid)
        except WareroverError as err:
            assert "\n" not in str(err)
