"""The runnable examples in the docstrings of the segmentation / AdaBins / loss / shared model modules."""

from __future__ import annotations

import pytest

from tests.doctests import assert_doctests_pass

MODULES = [
    "models.input_checks",
    "models.weights",
    "models.segmentation",
    "models.segmentation.smp_model",
    "models.adabins",
    "models.adabins.model",
    "models.adabins.mini_vit",
    "models.adabins.decoder",
    "models.losses.depth",
    "models.losses.segmentation",
]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    assert_doctests_pass(name)
