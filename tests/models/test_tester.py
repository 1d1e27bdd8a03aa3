"""The shared model tester's own wiring."""

from __future__ import annotations

import importlib

import pytest

from tests.models import test_adabins, test_nlspn, test_segmentation  # noqa: F401  (their tester classes)
from tests.models.base import BaseModelTester


@pytest.mark.parametrize(
    "tester", [c for c in BaseModelTester.__subclasses__() if c.deployed_by], ids=lambda c: c.__name__
)
def test_a_model_deployed_elsewhere_is_exported_by_a_default_test(tester: type[BaseModelTester]) -> None:
    """``deployed_by`` names a test that exists and is not ``slow``: the model keeps one export in the default
    suite while its own ONNX tests run with ``-m slow``."""
    path, name = tester.deployed_by.split("::")
    module = importlib.import_module(path.removesuffix(".py").replace("/", "."))
    test = getattr(module, name)
    assert callable(test)
    marks = [getattr(obj, "pytestmark", []) for obj in (module, test)]  # a mark or a list of them
    assert "slow" not in {m.name for ms in marks for m in (ms if isinstance(ms, list) else [ms])}
