"""Errors the user can act on.

Every error raised for bad input is a :class:`ScenarioError` (or subclass) that names the
file, the field path and the offending value, so the CLI can print it on one line and exit 2.
"""

from __future__ import annotations

from typing import Any

__all__ = ["WareroverError", "ScenarioError", "LayoutError", "PlanningError", "PlanFormatError"]


class WareroverError(Exception):
    """Base class of every error this package raises on purpose."""


def _short(value: Any, limit: int = 60) -> str:
    text = repr(value)
    if len(text) <= limit:
        return text
    if isinstance(value, str) and "/" in value:  # a path: its end says the most
        return "'..." + text[-(limit - 4):]
    return text[: limit - 3] + "..."


class ScenarioError(WareroverError):
    """Bad scenario or layout input.

    ``str(err)`` is one line: ``FILE: FIELD: MESSAGE (got VALUE)``.
    """

    _MISSING = object()

    def __init__(self, message: str, *, file: str | None = None, field: str | None = None,
                 value: Any = _MISSING) -> None:
        self.message = message
        self.file = file
        self.field = field
        self.value = value
        super().__init__(self.oneline())

    def oneline(self) -> str:
        parts = [self.file or "<scenario>"]
        if self.field:
            parts.append(self.field)
        text = ": ".join(parts) + ": " + self.message.replace("\n", " ")
        if self.value is not ScenarioError._MISSING:
            text += f" (got {_short(self.value)})"
        return text

    def with_file(self, file: str) -> ScenarioError:
        """The same error, naming ``file`` if it did not name one yet."""
        if self.file is None:
            self.file = file
            self.args = (self.oneline(),)
        return self


class LayoutError(ScenarioError):
    """A layout that cannot be used: walled-in cells, unreachable shelves, no parking."""


class PlanningError(WareroverError):
    """A planner was asked something it cannot do (e.g. an unknown planner name)."""


class PlanFormatError(ScenarioError):
    """A plan file that cannot be read (or a plan that a format cannot express).

    ``str(err)`` is one line: ``FILE: WHERE: MESSAGE (got TEXT)``, where ``WHERE`` is a line
    number (``line 12``) or a JSON key path (``actualPaths[3]``) and ``TEXT`` is at most
    about 80 characters of the offending input.
    """
