"""YAML with limits: every YAML file or ``--set`` value this package reads goes through here.

``yaml.safe_load`` builds no arbitrary objects, but it still accepts a "billion laughs" file
(nested aliases that expand to billions of nodes once a validator walks them) and unbounded
nesting. :func:`load` refuses, with a :class:`YamlLimitError` that says which limit was hit:

- more than ``MAX_BYTES`` of text,
- more than ``MAX_ALIASES`` alias references (``*name``),
- nesting deeper than ``MAX_DEPTH``,
- more than ``MAX_NODES`` values once aliases are expanded;

and a key given twice in one mapping is a ``yaml.constructor.ConstructorError`` naming the
key and both lines (PyYAML itself keeps the last one silently).

>>> load("a: [1, 2, {b: c}]")
{'a': [1, 2, {'b': 'c'}]}
>>> load("a: &x [1]\\nb: *x")
{'a': [1], 'b': [1]}
>>> load("a: 1\\nb: 2\\na: 3")
Traceback (most recent call last):
...
yaml.constructor.ConstructorError: while constructing a mapping
  in "<unicode string>", line 1, column 1:
    a: 1
    ^
duplicate key 'a' (first on line 1)
  in "<unicode string>", line 3, column 1:
    a: 3
    ^
"""

from __future__ import annotations

from typing import Any

import yaml

__all__ = ["load", "YamlLimitError", "MAX_BYTES", "MAX_ALIASES", "MAX_DEPTH", "MAX_NODES"]

MAX_BYTES = 16 * 1024 * 1024
"""Largest YAML text read (16 MiB; the biggest shipped file is about 1 KiB)."""
MAX_ALIASES = 1_000
"""Alias references (``*name``) in one document."""
MAX_DEPTH = 64
"""Nesting of mappings and lists."""
MAX_NODES = 2_000_000
"""Scalars, mappings and lists in the loaded value, aliases expanded."""


class YamlLimitError(yaml.YAMLError):
    """The YAML text is over one of the limits of this module."""

    def __init__(self, problem: str) -> None:
        super().__init__(problem)
        self.problem = problem
        self.problem_mark = None


class _LimitedLoader(yaml.SafeLoader):
    """``SafeLoader`` that counts aliases and nesting while it composes the node graph."""

    def __init__(self, stream: Any) -> None:
        super().__init__(stream)
        self._aliases = 0
        self._depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:  # noqa: D401 - PyYAML hook
        if self.check_event(yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > MAX_ALIASES:
                raise YamlLimitError(f"more than {MAX_ALIASES} aliases")
            return super().compose_node(parent, index)
        self._depth += 1
        if self._depth > MAX_DEPTH:
            raise YamlLimitError(f"nested deeper than {MAX_DEPTH} levels")
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:  # noqa: D401
        """As PyYAML's, but a key given twice in one mapping is an error (PyYAML keeps the
        last one silently: ``max_ticks: 300`` then ``max_ticks: 5`` ran 5 ticks)."""
        if isinstance(node, yaml.MappingNode):  # before merge keys (<<) are flattened in:
            seen: dict[Any, Any] = {}             # they may repeat a key, as YAML allows
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=deep)
                try:
                    first = seen.setdefault(key, key_node)
                except TypeError:  # an unhashable key: PyYAML's own error follows
                    continue
                if first is not key_node:
                    raise yaml.constructor.ConstructorError(
                        "while constructing a mapping", node.start_mark,
                        f"duplicate key {key!r} (first on line {first.start_mark.line + 1})",
                        key_node.start_mark)
        return super().construct_mapping(node, deep=deep)


def _count(value: Any) -> None:
    """Walk ``value`` with aliases expanded; raise once it holds more than ``MAX_NODES``."""
    seen = 0
    stack = [value]
    while stack:
        v = stack.pop()
        seen += 1
        if seen > MAX_NODES:
            raise YamlLimitError(f"more than {MAX_NODES:,} values once aliases are expanded")
        if isinstance(v, dict):
            stack.extend(v.keys())
            stack.extend(v.values())
        elif isinstance(v, list | tuple | set):
            stack.extend(v)


def load(text: str | bytes) -> Any:
    """``yaml.safe_load(text)`` within the limits above (:class:`YamlLimitError` past one)."""
    if len(text) > MAX_BYTES:
        raise YamlLimitError(f"larger than {MAX_BYTES // (1024 * 1024)} MiB")
    loader = _LimitedLoader(text)
    try:
        value = loader.get_single_data()
    except RecursionError:
        raise YamlLimitError(f"nested deeper than {MAX_DEPTH} levels") from None
    finally:
        loader.dispose()
    _count(value)
    return value
