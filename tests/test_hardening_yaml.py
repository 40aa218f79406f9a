"""YAML is read with limits on size, nesting and aliases: a hostile file is one clean error."""

from __future__ import annotations

import time

import pytest

from warerover_phys.config import load_scenario, parse_override
from warerover_phys.errors import ScenarioError
from warerover_phys.util import safe_yaml

LAUGHS = "\n".join(
    ["a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    + [f"{chr(98 + i)}: &{chr(98 + i)} [" + ", ".join([f"*{chr(97 + i)}"] * 9) + "]"
       for i in range(8)]
    + ["layout: *i", "fleet: {agvs: [{count: 1}]}"]) + "\n"


@pytest.mark.no_cover  # a CPU-time bound: measured without coverage's tracer
def test_billion_laughs_is_refused_quickly(tmp_path):
    path = tmp_path / "laughs.yaml"
    path.write_text(LAUGHS)
    t0 = time.process_time()  # CPU time: a loaded machine does not stretch it
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert time.process_time() - t0 < 10
    assert str(path) in str(info.value) and "YAML refused" in str(info.value)


def test_too_many_aliases(tmp_path):
    path = tmp_path / "aliases.yaml"
    path.write_text("a: &x 1\nb: [" + ", ".join(["*x"] * (safe_yaml.MAX_ALIASES + 1)) + "]\n")
    with pytest.raises(ScenarioError, match="aliases"):
        load_scenario(path)


def test_too_deep(tmp_path):
    path = tmp_path / "deep.yaml"
    path.write_text("a: " + "[" * 1000 + "]" * 1000 + "\n")
    with pytest.raises(ScenarioError, match="deeper"):
        load_scenario(path)


def test_too_deep_block_style(tmp_path):
    path = tmp_path / "deep.yaml"
    path.write_text("".join(" " * i + f"k{i}:\n" for i in range(200)))
    with pytest.raises(ScenarioError, match="deeper"):
        load_scenario(path)


def test_too_large(tmp_path, monkeypatch):
    monkeypatch.setattr(safe_yaml, "MAX_BYTES", 1000)
    path = tmp_path / "big.yaml"
    path.write_text("a: " + "x" * 2000 + "\n")
    with pytest.raises(ScenarioError, match="larger than"):
        load_scenario(path)


def test_recursive_alias_is_refused(tmp_path):
    path = tmp_path / "loop.yaml"
    path.write_text("a: &a [*a]\n")
    with pytest.raises(ScenarioError, match="YAML refused"):
        load_scenario(path)


def test_laughs_in_a_set_value():
    flow = "x=[" + "&a [1,1,1,1,1,1,1,1,1,1], " + ", ".join(
        f"&{c} [" + ", ".join([f"*{p}"] * 10) + "]" for p, c in zip("abcdefgh", "bcdefghi", strict=True)) + "]"
    with pytest.raises(ScenarioError, match="--set|x"):
        parse_override(flow)


def test_ordinary_yaml_still_loads():
    assert safe_yaml.load("a: &x {b: 1}\nc: *x\n") == {"a": {"b": 1}, "c": {"b": 1}}
