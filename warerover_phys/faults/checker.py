"""The corridor checkers by name (``faults.checker``): :func:`make_checker`.

Its own module so that :mod:`.intrusion` and :mod:`.intrusion_fcl` (which builds on it)
import in one direction only; python-fcl is imported on the first ``fcl`` checker.
"""

from __future__ import annotations

import numpy as np

from .intrusion import IntrusionChecker

__all__ = ["CHECKERS", "make_checker"]

CHECKERS = ("fcl", "numpy")
"""The corridor checkers (``faults.checker``)."""


def make_checker(kind: str, half_sizes: np.ndarray) -> IntrusionChecker:
    """The ``faults.checker`` named ``kind`` for AGV bodies of ``half_sizes`` (``(N, 2)``
    m): ``numpy`` (:class:`IntrusionChecker`) or ``fcl``
    (:class:`~warerover_phys.faults.intrusion_fcl.FclIntrusionChecker`, imported on
    first use)."""
    if kind == "numpy":
        return IntrusionChecker(half_sizes)
    if kind == "fcl":
        from .intrusion_fcl import FclIntrusionChecker

        return FclIntrusionChecker(half_sizes)
    raise ValueError(f"faults.checker must be one of {', '.join(CHECKERS)}, got {kind!r}")
