"""Building plug-in classes (``package.module:ClassName``) so that any failure of the user's
code while it is built is a one-line :class:`~.errors.ScenarioError` naming the field and the
plug-in, not a traceback.

>>> class Broken:
...     def __init__(self, spec):
...         raise RuntimeError("no licence")
>>> build_plugin(Broken, None, "planner.name", "my:Broken")
Traceback (most recent call last):
...
warerover_phys.errors.ScenarioError: <scenario>: planner.name: plugin constructor raised RuntimeError: no licence (got 'my:Broken')
"""

from __future__ import annotations

from typing import Any

from .errors import ScenarioError, WareroverError

__all__ = ["build_plugin"]


def build_plugin(cls: type, spec: Any, field: str, name: str) -> Any:
    """``cls(spec)``; an exception the constructor raises becomes a :class:`ScenarioError`."""
    try:
        return cls(spec)
    except ScenarioError:
        raise
    except WareroverError as err:
        raise ScenarioError(f"plugin constructor failed: {err}", field=field,
                            value=name) from None
    except Exception as err:  # noqa: BLE001 - the plug-in's own bug, reported as bad input
        first = str(err).strip().splitlines()[0] if str(err).strip() else ""
        raise ScenarioError(f"plugin constructor raised {type(err).__name__}"
                            + (f": {first}" if first else ""), field=field,
                            value=name) from None
