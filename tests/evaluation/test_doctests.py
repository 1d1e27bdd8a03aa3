"""The runnable examples in the evaluation, checkpoint and sampling docstrings."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = [
    "airfisheye_bench.evaluation.scorer",
    "airfisheye_bench.evaluation.submission",
    "airfisheye_bench.evaluation.leaderboard",
    "airfisheye_bench.tasks.checkpoint",
    "datamodules.sampling",
]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str) -> None:
    result = doctest.testmod(
        importlib.import_module(name), optionflags=doctest.ELLIPSIS | doctest.IGNORE_EXCEPTION_DETAIL
    )
    assert result.attempted > 0
    assert result.failed == 0
