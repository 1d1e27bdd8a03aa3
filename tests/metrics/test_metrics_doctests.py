"""The docstring examples of the metrics package run and print what they claim."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = [
    "airfisheye_bench.metrics.functional",
    "airfisheye_bench.metrics.segmentation",
    "airfisheye_bench.metrics.depth",
    "airfisheye_bench.metrics.completion",
    "airfisheye_bench.metrics.binned",
]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0
    assert result.failed == 0
