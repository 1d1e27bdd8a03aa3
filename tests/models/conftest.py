"""The model tests' collection: the ONNX tests of a model that the default suite exports elsewhere are ``slow``."""

from __future__ import annotations

import pytest

from tests.helpers.model_tester import DEPLOYED_BY, BaseModelTester


@pytest.hookimpl(tryfirst=True)  # before ``-m`` deselects by mark
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        cls = getattr(item, "cls", None)
        if (
            isinstance(cls, type)
            and issubclass(cls, BaseModelTester)
            and cls.model_name in DEPLOYED_BY
            and item.name.startswith("test_onnx_")
        ):
            item.add_marker(pytest.mark.slow)
