"""MkDocs hook: reference pages generated from the code at build time.

A page asks for a generated block with one marker line (the object is named there, so the
module paths live in ``docs/reference/*.md`` only)::

    <!-- generated: cli warerover_phys.cli:app -->        every command of the typer app
    <!-- generated: schema warerover_phys:Scenario -->    a pydantic model's JSON schema

``cli`` walks the click command tree typer builds (``typer.main.get_command``) and writes each
command's usage, help, arguments and options; ``schema`` renders ``model_json_schema()`` as
one table per model, with the attribute docstrings of the fields as their descriptions.
Nothing here is written by hand: change a command or a field and the page follows.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import json
import re
import textwrap
from typing import Any

_MARKER = re.compile(r"^<!-- generated: (cli|schema) ([\w.]+):([\w.]+) -->$", re.M)


def _resolve(module: str, attr: str) -> Any:
    obj: Any = importlib.import_module(module)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ARG001 (hook API)
    def expand(m: re.Match) -> str:
        obj = _resolve(m.group(2), m.group(3))
        return cli_markdown(obj) if m.group(1) == "cli" else schema_markdown(obj)

    return _MARKER.sub(expand, markdown)


# --- the command line ---------------------------------------------------------------------

def _cell(text: Any) -> str:
    text = " ".join(str(text).split())
    return text.replace("|", "\\|") or " "


def _plain(text: str | None) -> str:
    """Help text without typer's rich markup and its ``\\b`` no-rewrap markers."""
    text = inspect.cleandoc(text or "").replace("\b", "")
    return re.sub(r"\[/?(bold|italic|dim|red|green|yellow|cyan|magenta|blue)\]", "", text)


def _type_name(param) -> str:
    import click

    t = param.type
    if isinstance(t, click.Choice):
        return " \\| ".join(f"`{c}`" for c in t.choices)
    if getattr(param, "is_flag", False):
        return "flag"
    name = getattr(t, "name", str(t)).lower()
    return name + (" (repeatable)" if getattr(param, "multiple", False) else "")


def _default(param) -> str:
    default = param.default
    if getattr(param, "is_flag", False) and getattr(param, "secondary_opts", None):
        return param.opts[0] if default else param.secondary_opts[0]
    if default is None or default == () or getattr(param, "required", False):
        return ""
    if callable(default) or type(default).__name__ in ("Sentinel", "_Missing"):
        return ""
    if getattr(param, "is_flag", False):
        return "on" if default else ""
    return f"`{default}`"


def _command_section(name: str, cmd, parent_ctx) -> list[str]:
    import click

    ctx = click.Context(cmd, info_name=name, parent=parent_ctx)
    usage = " ".join([ctx.command_path, *cmd.collect_usage_pieces(ctx)])
    out = [f"## `{name}`", "", f"```text\n{usage}\n```", "", _plain(cmd.help), ""]
    args = [p for p in cmd.params if isinstance(p, click.Argument)]
    opts = [p for p in cmd.params if isinstance(p, click.Option) and not p.hidden]
    if args:
        out += ["| argument | type | required | help |", "|---|---|---|---|"]
        out += [f"| `{p.human_readable_name}` | {_type_name(p)} | "
                f"{'yes' if p.required else 'no'} | {_cell(_plain(getattr(p, 'help', '')))} |"
                for p in args]
        out.append("")
    if opts:
        out += ["| option | type | default | help |", "|---|---|---|---|"]
        for p in opts:
            names = ", ".join(f"`{o}`" for o in [*p.opts, *p.secondary_opts])
            out.append(f"| {names} | {_type_name(p)} | {_default(p)} | "
                       f"{_cell(_plain(p.help))} |")
        out.append("")
    return out


def cli_markdown(app) -> str:
    """Every command of the typer ``app``: usage, help, arguments and options."""
    import click
    import typer

    group = typer.main.get_command(app)
    root = click.Context(group, info_name="warerover")
    out = [_plain(group.help), ""]
    names = group.list_commands(root)
    out += ["| command | what it does |", "|---|---|"]
    for name in names:
        cmd = group.get_command(root, name)
        short = _plain(cmd.help).split("\n\n")[0]
        out.append(f"| [`{name}`](#{name}) | {_cell(short)} |")
    out.append("")
    for name in names:
        out += _command_section(name, group.get_command(root, name), root)
    return "\n".join(out)


# --- the scenario schema ------------------------------------------------------------------

def _field_docs(model) -> dict[str, str]:
    """Attribute docstrings (a string right after a field) of ``model`` and its bases."""
    docs: dict[str, str] = {}
    for cls in reversed(model.__mro__):
        try:
            tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
        except (OSError, TypeError, SyntaxError):
            continue
        body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
        for a, b in zip(body, body[1:]):
            if (isinstance(a, ast.AnnAssign) and isinstance(a.target, ast.Name)
                    and isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant)
                    and isinstance(b.value.value, str)):
                docs[a.target.id] = inspect.cleandoc(b.value.value)
    return docs


def _models(model) -> dict[str, Any]:
    """Every pydantic model reachable from ``model``'s fields, by class name."""
    from pydantic import BaseModel

    seen: dict[str, Any] = {}

    def walk(tp: Any) -> None:
        if isinstance(tp, type) and issubclass(tp, BaseModel):
            if tp.__name__ in seen:
                return
            seen[tp.__name__] = tp
            for f in tp.model_fields.values():
                walk(f.annotation)
        for arg in getattr(tp, "__args__", ()) or ():
            walk(arg)

    walk(model)
    return seen


def _type(s: dict) -> str:
    if "$ref" in s:
        name = s["$ref"].rsplit("/", 1)[-1]
        return f"[{name}](#{name.lower()})"
    if "const" in s:
        return f"`{json.dumps(s['const'])}`"
    if "enum" in s:
        return " \\| ".join(f"`{json.dumps(v)}`" for v in s["enum"])
    for key in ("anyOf", "oneOf", "allOf"):
        if key in s:
            return " \\| ".join(_type(x) for x in s[key])
    t = s.get("type", "any")
    if t == "array":
        if "prefixItems" in s:
            return "[" + ", ".join(_type(x) for x in s["prefixItems"]) + "]"
        return f"list of {_type(s.get('items', {}))}"
    if t == "object" and isinstance(s.get("additionalProperties"), dict):
        return f"map of name -> {_type(s['additionalProperties'])}"
    return str(t)


_LIMITS = {"minimum": ">=", "exclusiveMinimum": ">", "maximum": "<=", "exclusiveMaximum": "<",
           "minLength": "length >=", "maxLength": "length <=", "minItems": "items >=",
           "maxItems": "items <="}


def _limits(s: dict) -> str:
    parts = [f"{op} {s[k]}" for k, op in _LIMITS.items() if k in s]
    for sub in s.get("anyOf", []):
        parts += [f"{op} {sub[k]}" for k, op in _LIMITS.items() if k in sub]
    return ", ".join(dict.fromkeys(parts))


def _model_table(name: str, schema: dict, docs: dict[str, str]) -> list[str]:
    out = [f"## {name}", ""]
    if schema.get("description"):
        out += [inspect.cleandoc(schema["description"]), ""]
    props = schema.get("properties", {})
    if not props:
        return out
    required = set(schema.get("required", []))
    out += ["| field | type | default | limits | description |", "|---|---|---|---|---|"]
    for field, s in props.items():
        default = "required" if field in required else (
            f"`{json.dumps(s['default'])}`" if "default" in s else "")
        desc = docs.get(field) or s.get("description") or ""
        out.append(f"| `{field}` | {_type(s)} | {_cell(default)} | {_cell(_limits(s))} | "
                   f"{_cell(desc)} |")
    out.append("")
    return out


def schema_markdown(model) -> str:
    """One table per model of ``model.model_json_schema()``, the root first."""
    schema = model.model_json_schema()
    classes = _models(model)
    defs = schema.pop("$defs", {})
    out = [f"The root is [{model.__name__}](#{model.__name__.lower()}); the whole JSON "
           "schema, for editors and validators: `warerover_phys.Scenario.model_json_schema()`.",
           ""]
    out += _model_table(model.__name__, schema, _field_docs(model))
    for name in sorted(defs):
        cls = classes.get(name)
        out += _model_table(name, defs[name], _field_docs(cls) if cls else {})
    return "\n".join(out)
