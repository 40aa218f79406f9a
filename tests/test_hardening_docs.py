"""The examples in the docstrings of the hardening modules run."""

from __future__ import annotations

import doctest
import importlib

import pytest


@pytest.mark.parametrize("module", ["warerover_phys.util.safe_yaml", "warerover_phys.util.atomic",
                                    "warerover_phys.util.media", "warerover_phys.plugins",
                                    "warerover_phys.shipped"])
def test_docstring_examples(module):
    result = doctest.testmod(importlib.import_module(module))
    assert result.attempted > 0
    assert result.failed == 0
