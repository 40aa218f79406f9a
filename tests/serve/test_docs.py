"""The examples in the serve modules' docstrings run."""

from __future__ import annotations

import doctest
import importlib

import pytest

from .conftest import REPO


@pytest.mark.parametrize("module", ["warerover_phys.serve.protocol",
                                    "warerover_phys.serve.session",
                                    "warerover_phys.serve.layout_edit"])
def test_docstring_examples(module, monkeypatch):
    monkeypatch.chdir(REPO)
    result = doctest.testmod(importlib.import_module(module))
    assert result.attempted > 0
    assert result.failed == 0
