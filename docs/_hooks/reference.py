"""MkDocs hook: reference pages generated from the code at build time.

A page asks for a generated block with one marker line (the object is named there, so the
module paths live in ``docs/reference/*.md`` only)::

    <!-- generated: cli warerover_phys.cli.commands:app -->        every command of the typer app
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
from itertools import pairwise
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


def _record(param, ctx) -> tuple[str, str]:
    """What ``--help`` prints for ``param``: its names with the value's kind, and its help
    with the default (typer's own click copy and plain click both have these)."""
    rec = param.get_help_record(ctx) if hasattr(param, "get_help_record") else None
    if rec is None:  # a plain click argument: no help record
        return (param.name or "").upper(), ""
    return rec[0], _plain(rec[1])


def _command_section(name: str, cmd, parent_ctx) -> list[str]:
    ctx = cmd.context_class(cmd, info_name=name, parent=parent_ctx)
    usage = " ".join([ctx.command_path, *cmd.collect_usage_pieces(ctx)])
    out = [f"## `{name}`", "", f"```text\n{usage}\n```", "", _plain(cmd.help), ""]
    # typer may bring its own copy of click: tell parameters apart by their kind's name
    for kind in ("argument", "option"):
        params = [p for p in cmd.params if p.param_type_name == kind and not p.hidden]
        if params:
            out += [f"| {kind} | help |", "|---|---|"]
            out += ["| `{}` | {} |".format(*(_cell(x) for x in _record(p, ctx))) for p in params]
            out.append("")
    return out


def cli_markdown(app) -> str:
    """Every command of the typer ``app``: usage, help, arguments and options."""
    import typer

    group = typer.main.get_command(app)
    root = group.context_class(group, info_name="warerover")
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
        for a, b in pairwise(body):
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


def _excluded(model) -> frozenset[str]:
    """Fields never read from a file (``Field(exclude=True)``: set by the loader)."""
    return frozenset(n for n, f in model.model_fields.items() if f.exclude)


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


def _default_cell(s: dict) -> str:
    if "default" not in s:
        return ""
    ref = s.get("$ref") or next((x["$ref"] for x in s.get("allOf", []) if "$ref" in x), None)
    if ref and isinstance(s["default"], dict):  # a whole sub-model: its own table has them
        name = ref.rsplit("/", 1)[-1]
        return f"the defaults of [{name}](#{name.lower()})"
    return f"`{json.dumps(s['default'])}`"


def _model_table(name: str, schema: dict, docs: dict[str, str],
                 hidden: frozenset[str] = frozenset()) -> list[str]:
    out = [f"## {name}", ""]
    if schema.get("description"):
        out += [inspect.cleandoc(schema["description"]), ""]
    props = schema.get("properties", {})
    if not props:
        return out
    required = set(schema.get("required", []))
    out += ["| field | type | default | limits | description |", "|---|---|---|---|---|"]
    for field, s in props.items():
        if field in hidden:
            continue
        default = "required" if field in required else _default_cell(s)
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
    out += _model_table(model.__name__, schema, _field_docs(model), _excluded(model))
    for name in sorted(defs):
        cls = classes.get(name)
        out += _model_table(name, defs[name], _field_docs(cls) if cls else {},
                            _excluded(cls) if cls else frozenset())
    return "\n".join(out)
