"""The examples in the ingest.can docstrings run and give what they show."""

from __future__ import annotations

import doctest
import importlib

import pytest


@pytest.mark.parametrize("module", ["protocol", "assembler", "emulator"])
def test_docstring_examples(module: str) -> None:
    result = doctest.testmod(importlib.import_module(f"ingest.can.{module}"), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0
