"""The runnable examples in the evaluation, checkpoint and sampling docstrings."""

from __future__ import annotations

import doctest

import pytest

from tests.doctests import assert_doctests_pass

MODULES = [
    "airfisheye_bench.evaluation.predictors",
    "airfisheye_bench.evaluation.submission",
    "airfisheye_bench.tasks.checkpoint",
    "datamodules.sampling",
]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str) -> None:
    assert_doctests_pass(name, doctest.IGNORE_EXCEPTION_DETAIL)
