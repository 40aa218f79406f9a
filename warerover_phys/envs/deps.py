"""Optional dependencies of the environments, imported when first needed.

A module of its own: ``loop``, ``parallel`` and ``single`` import :func:`require` from here,
not from the package's ``__init__`` (which imports them), so the package has no import
circle.
"""

from __future__ import annotations

import importlib

__all__ = ["require"]


def require(module: str) -> None:
    """Import ``module`` or raise an ImportError that names the install command."""
    try:
        importlib.import_module(module)
    except ImportError as err:
        raise ImportError(f"{module} is needed for warerover_phys.envs: "
                          "pip install 'warerover-phys[envs]'") from err
