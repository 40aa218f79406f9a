"""The generated reference pages (docs/_hooks/reference.py) cover the code they come from:
every command and option of the typer app, every model and field of the scenario schema.
(The site build itself runs in `make docs`; this needs no MkDocs.)"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def hook():
    spec = importlib.util.spec_from_file_location("docs_reference_hook",
                                                  REPO / "docs" / "_hooks" / "reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_cli_page_has_every_command_and_option(hook):
    import typer

    from warerover_phys.cli import app

    text = hook.cli_markdown(app)
    group = typer.main.get_command(app)
    ctx = group.context_class(group, info_name="warerover")
    names = group.list_commands(ctx)
    assert {"run", "execute", "gap", "render", "serve", "solve", "lorr"} <= set(names)
    for name in names:
        section = text.split(f"## `{name}`\n", 1)[1].split("\n## `", 1)[0]
        assert f"warerover {name}" in section  # the usage line
        cmd = group.get_command(ctx, name)
        for param in cmd.params:
            if param.param_type_name == "option" and not param.hidden:
                row = next((ln for ln in section.splitlines()
                            if ln.startswith("| `") and param.opts[0] in ln.split("|")[1]), None)
                assert row is not None and all(o in row for o in param.opts), (name, param.opts)
    run = text.split("## `run`\n", 1)[1].split("\n## `", 1)[0]
    assert re.search(r"\| `--seed <int>` \| Episode seed", run)


def test_schema_page_has_every_model_and_field(hook):
    from warerover_phys import Scenario

    text = hook.schema_markdown(Scenario)
    models = hook._models(Scenario)
    assert {"Scenario", "FleetSpec", "PlannerSpec", "ExecutorSpec"} <= set(models)
    for name, model in models.items():
        assert f"\n## {name}\n" in f"\n{text}", name
        table = text.split(f"## {name}\n", 1)[1].split("\n## ", 1)[0]
        for field, info in model.model_fields.items():
            shown = f"| `{field}` |" in table
            assert shown != bool(info.exclude), (name, field)  # excluded: set by the loader
    assert "`source`" not in text.split("## Scenario\n", 1)[1].split("\n## ", 1)[0]
    # a field's docstring becomes its description
    assert "Explicit start anchors" in text


def test_markers_expand_in_a_page(hook):
    page = "# x\n\n<!-- generated: schema warerover_phys:Scenario -->\n"
    out = hook.on_page_markdown(page, None, None, None)
    assert "<!-- generated" not in out and "## Scenario" in out
