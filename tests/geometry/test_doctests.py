"""The runnable examples in the LiDAR and occlusion docstrings."""

from __future__ import annotations

import pytest

from tests.doctests import assert_doctests_pass


@pytest.mark.parametrize("name", ["lidar", "occlusion"])
def test_docstring_examples(name: str) -> None:
    assert_doctests_pass(f"airfisheye_bench.geometry.{name}")
