"""Every ``warerover_phys`` name that README.md and docs/ import still imports.

The documentation names public things in four ways, all checked here: Python code
(```python blocks, and any ``from warerover_phys... import ...`` line anywhere in a page,
doctest prompts included), dotted names in code spans (`` `warerover_phys.envs.loop_env` ``),
the API reference's mkdocstrings directives (``::: dotted.path``) and the
generated-reference markers (``<!-- generated: cli module:attr -->``). A module moved
or a name renamed without its documentation fails here, before the site build does.
"""

from __future__ import annotations

import ast
import importlib
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", *sorted(p for p in (REPO / "docs").rglob("*.md")
                                     if "_hooks" not in p.parts)]

_BLOCK = re.compile(r"^```(?:python|py|pycon)[^\n]*\n(.*?)^```", re.M | re.S)
_FROM = re.compile(r"from\s+(warerover_phys[\w.]*)\s+import\s+\(?([\w\s,]+?)\)?\s*(?:#|$)",
                   re.M)
_IMPORT = re.compile(r"^\s*(?:>>>\s*)?import\s+(warerover_phys[\w.]*)", re.M)
_DIRECTIVE = re.compile(r"^:::\s+([\w.]+)\s*$", re.M)
_MARKER = re.compile(r"^<!-- generated: \w+ ([\w.]+):([\w.]+) -->$", re.M)
_SPAN = re.compile(r"`(warerover_phys(?:\.\w+)+)(?:\(\))?`")
# Entry-point group names (plug-ins register under them), not modules.
ENTRY_POINT_GROUPS = {"warerover_phys.schedulers", "warerover_phys.planners",
                      "warerover_phys.executors"}


def _imports_in_code(code: str) -> set[tuple[str, str | None]]:
    """(module, name) for each import of ``warerover_phys`` in a Python block (name None
    for ``import module``); doctest prompts are stripped first."""
    lines = [re.sub(r"^(>>>|\.\.\.) ?", "", ln) for ln in code.splitlines()
             if not ln.startswith(("$ ",))]
    try:
        tree = ast.parse("\n".join(lines))
    except SyntaxError:  # a block with output in it: the line scan below still reads it
        return set()
    found: set[tuple[str, str | None]] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("warerover_phys"):
            found |= {(node.module, a.name) for a in node.names}
        elif isinstance(node, ast.Import):
            found |= {(a.name, None) for a in node.names if a.name.startswith("warerover_phys")}
    return found


def _imports_in_page(text: str) -> set[tuple[str, str | None]]:
    found: set[tuple[str, str | None]] = set()
    for block in _BLOCK.findall(text):
        found |= _imports_in_code(block)
    for module, names in _FROM.findall(text):
        found |= {(module, n.strip()) for n in names.split(",") if n.strip()}
    found |= {(module, None) for module in _IMPORT.findall(text)}
    return found


def _all_imports() -> list[tuple[str, str, str | None]]:
    out = set()
    for page in PAGES:
        rel = page.relative_to(REPO).as_posix()
        out |= {(rel, m, n) for m, n in _imports_in_page(page.read_text(encoding="utf-8"))}
    return sorted(out, key=lambda t: (t[0], t[1], t[2] or ""))


def _references() -> list[tuple[str, str]]:
    out = []
    for page in PAGES:
        rel = page.relative_to(REPO).as_posix()
        text = page.read_text(encoding="utf-8")
        out += [(rel, path) for path in _DIRECTIVE.findall(text)]
        out += [(rel, f"{m}.{a}") for m, a in _MARKER.findall(text)]
        # lines marked "house-rewrite: keep" name old module paths on purpose (the table of
        # moves in docs/layout.md): not references
        current = "\n".join(ln for ln in text.splitlines() if "house-rewrite: keep" not in ln)
        out += [(rel, d) for d in sorted(set(_SPAN.findall(current)) - ENTRY_POINT_GROUPS)]
    return out


def _resolve(dotted: str):
    """Import the longest importable module prefix of ``dotted``, then getattr the rest."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError:
            continue
        for attr in parts[i:]:
            obj = getattr(obj, attr)
        return obj
    raise ModuleNotFoundError(dotted)


IMPORTS = _all_imports()
REFERENCES = _references()


@pytest.mark.parametrize(("page", "module", "name"), IMPORTS,
                         ids=[f"{p}:{m}:{n or '*'}" for p, m, n in IMPORTS])
def test_documented_import_works(page, module, name):
    mod = importlib.import_module(module)
    if name is not None and not hasattr(mod, name):
        importlib.import_module(f"{module}.{name}")  # ``from pkg import submodule``


@pytest.mark.parametrize(("page", "dotted"), REFERENCES,
                         ids=[f"{p}:{d}" for p, d in REFERENCES])
def test_reference_directive_resolves(page, dotted):
    assert _resolve(dotted) is not None


def test_the_scan_finds_what_the_pages_use():
    """The scan is not empty by accident: the README's tour and the API page are in it."""
    readme = {(m, n) for p, m, n in IMPORTS if p == "README.md"}
    assert {("warerover_phys", "load_scenario"), ("warerover_phys", "run_episode")} <= readme
    assert any(p == "docs/reference/api.md" for p, _ in REFERENCES)
    assert any(d.endswith(".Scenario") for _, d in REFERENCES)
    assert _imports_in_page("```python\nfrom warerover_phys.plans import read_plan, Plan\n```") \
        == {("warerover_phys.plans", "read_plan"), ("warerover_phys.plans", "Plan")}
    assert _imports_in_page(">>> from warerover_phys import nope  # x") \
        == {("warerover_phys", "nope")}
    with pytest.raises(AttributeError):
        _resolve("warerover_phys.config.no_such_name")
