"""The runnable examples in the io docstrings."""

from __future__ import annotations

import pytest

from tests.doctests import assert_doctests_pass

MODULES = [
    "calib",
    "codecs",
    "errors",
    "layout",
    "manifest",
    "poses",
    "reader",
    "spec",
    "splits",
    "transcode",
    "yamlio",
]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    assert_doctests_pass(f"airfisheye_bench.io.{name}", min_examples=0)  # not every io module has one
