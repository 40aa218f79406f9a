"""The ``warerover`` command line: one module per command, the typer app assembled in
:mod:`.commands`, the console script in :mod:`.entry`.

Library modules never import from here. Importing this package imports nothing else
(``warerover solve``'s fast path loads :mod:`.solve` without typer); ``app`` and ``main``
are loaded on first use.
"""

__all__ = ["app", "main"]


def __getattr__(name: str):
    if name in ("app", "main"):
        from . import commands

        return getattr(commands, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
