"""The examples in the physics docstrings run and give what they say."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = [
    "physics.config",
    "physics.geometry",
    "physics.simulator",
    "physics.campaign",
    "physics.recordio",
    "physics.kernel",
]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str) -> None:
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.failed == 0
