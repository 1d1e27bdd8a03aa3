"""The runnable examples in the datamodules docstrings."""

from __future__ import annotations

import pytest

from tests.doctests import assert_doctests_pass


@pytest.mark.parametrize("name", ["augment", "config", "sampling"])
def test_docstring_examples(name: str) -> None:
    assert_doctests_pass(f"datamodules.{name}")
