"""Every name users import keeps working: the package's public ``__all__`` lists, the plug-in
base classes and checkers, and every ``from warerover_phys ... import`` / ``import
warerover_phys...`` statement in the README, the docs' code blocks and the examples."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import re
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

PUBLIC = [
    ("warerover_phys", "load_scenario"), ("warerover_phys", "run_episode"),
    ("warerover_phys", "Simulation"), ("warerover_phys", "write_outputs"),
    ("warerover_phys", "Scenario"), ("warerover_phys", "EpisodeResult"),
    ("warerover_phys", "scenario_from_dict"), ("warerover_phys", "ScenarioError"),
    ("warerover_phys.planning", "Planner"), ("warerover_phys.planning", "PlanRequest"),
    ("warerover_phys.planning", "PlanResult"), ("warerover_phys.planning", "make_planner"),
    ("warerover_phys.schedulers", "Scheduler"), ("warerover_phys.schedulers", "Assignment"),
    ("warerover_phys.executors", "Executor"), ("warerover_phys.executors", "GridExecutor"),
    ("warerover_phys.testing", "check_planner"), ("warerover_phys.testing", "check_scheduler"),
    ("warerover_phys.testing", "check_executor"),
    ("warerover_phys.envs", "parallel_env"), ("warerover_phys.envs", "loop_env"),
    ("warerover_phys.envs", "MAPFGymEnv"), ("warerover_phys.envs", "PlannerDriver"),
    ("warerover_phys.render", "recording_from_episode"),
    ("warerover_phys.render", "load_trajectory"), ("warerover_phys.render", "render_video"),
    ("warerover_phys.cli", "app"), ("warerover_phys.cli", "main"),  # house-rewrite: keep
    ("warerover_phys.cli.entry", "main"),
]
"""Names the README and docs name in prose, or that plug-in authors and scripts import."""

PACKAGES = ["warerover_phys", "warerover_phys.planning", "warerover_phys.schedulers",
            "warerover_phys.executors", "warerover_phys.testing", "warerover_phys.envs",
            "warerover_phys.render", "warerover_phys.plans", "warerover_phys.spacetime"]


def _fenced_blocks(text: str):
    """The code blocks of a Markdown text (any language), with ``>>>`` prompts removed."""
    for m in re.finditer(r"^\s*```[^\n]*\n(.*?)^\s*```", text, re.S | re.M):
        lines = [re.sub(r"^(\s*)(>>> |\.\.\. )", r"\1", ln) for ln in m.group(1).splitlines()]
        yield textwrap.dedent("\n".join(lines))


def _import_statements(code: str):
    """``from warerover_phys ...`` and ``import warerover_phys...`` statements of a block
    (each parsed alone, so a block that is not whole Python still counts)."""
    lines = code.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i].strip()
        if re.match(r"(from|import) warerover_phys\b", line):
            stmt = line
            while stmt.count("(") > stmt.count(")") and i + 1 < len(lines):
                i += 1
                stmt += " " + lines[i].strip()
            yield ast.parse(stmt).body[0]
        i += 1


def _documented():
    found = set()
    files = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")),
             *sorted((ROOT / "examples").rglob("*.md"))]
    for f in files:
        for block in _fenced_blocks(f.read_text()):
            for node in _import_statements(block):
                found.update(_pairs(node, f))
    for f in sorted((ROOT / "examples").rglob("*.py")):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                found.update(_pairs(node, f))
    return sorted(p for p in found if p[1].startswith("warerover_phys"))


def _pairs(node, f: Path):
    where = f.relative_to(ROOT).as_posix()
    if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
        return {(where, node.module, a.name) for a in node.names}
    if isinstance(node, ast.Import):
        return {(where, a.name, None) for a in node.names}
    return set()


DOCUMENTED = _documented()


def test_the_docs_import_something():
    """The parser finds the README's own example (a parser that finds nothing tests nothing)."""
    assert ("README.md", "warerover_phys", "load_scenario") in DOCUMENTED


@pytest.mark.parametrize(("where", "module", "name"), DOCUMENTED,
                         ids=[f"{w}:{m}:{n}" for w, m, n in DOCUMENTED])
def test_documented_import_works(where, module, name):
    mod = importlib.import_module(module)
    if name is not None and name != "*":
        assert hasattr(mod, name) or importlib.util.find_spec(f"{module}.{name}"), \
            f"{where}: from {module} import {name}"
        getattr(mod, name, None) or importlib.import_module(f"{module}.{name}")


@pytest.mark.parametrize(("module", "name"), PUBLIC, ids=[f"{m}:{n}" for m, n in PUBLIC])
def test_public_name(module, name):
    assert getattr(importlib.import_module(module), name) is not None


@pytest.mark.parametrize("package", PACKAGES)
def test_every_name_in_all(package):
    mod = importlib.import_module(package)
    missing = [n for n in mod.__all__ if not hasattr(mod, n)]
    assert not missing, f"{package}.__all__ names {missing} that do not import"
