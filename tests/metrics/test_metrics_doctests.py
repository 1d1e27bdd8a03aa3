"""The docstring examples of the metrics package run and print what they claim."""

from __future__ import annotations

import pytest

from tests.doctests import assert_doctests_pass

MODULES = [
    "airfisheye_bench.metrics.functional",
    "airfisheye_bench.metrics.segmentation",
    "airfisheye_bench.metrics.depth",
    "airfisheye_bench.metrics.completion",
    "airfisheye_bench.metrics.binned",
    "airfisheye_bench.metrics.scorer",
]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    assert_doctests_pass(name)
