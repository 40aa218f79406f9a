"""What every command line entry point shares: the error console and the clean exit.

Bad input ends a command with one line on stderr naming the file, field and value, and exit
code 2 (:func:`fail`); never a traceback.
"""

from __future__ import annotations

from typing import NoReturn

import typer
from rich.console import Console
from rich.markup import escape

from ..errors import WareroverError

__all__ = ["err_console", "fail", "fail_os"]

err_console = Console(stderr=True)


def fail(err: Exception) -> NoReturn:
    """Print ``err`` as one line on stderr and exit with code 2."""
    err_console.print(f"[bold red]error:[/] {escape(str(err))}", highlight=False, soft_wrap=True)
    raise typer.Exit(2)


def fail_os(err: OSError) -> NoReturn:
    """An operating-system error (missing file, no permission, disk full) as a clean exit."""
    fail(WareroverError(f"{getattr(err, 'filename', '') or ''}: {err.strerror or err}"))
