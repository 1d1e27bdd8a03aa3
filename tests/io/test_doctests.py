"""The runnable examples in the io docstrings."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = [
    "atomic",
    "calib",
    "checksum",
    "codecs",
    "errors",
    "layout",
    "poses",
    "reader",
    "spec",
    "splits",
    "yamlio",
]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    result = doctest.testmod(
        importlib.import_module(f"airfisheye_bench.io.{name}"), optionflags=doctest.ELLIPSIS
    )
    assert result.failed == 0
