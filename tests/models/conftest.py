"""The model tests' collection: the ONNX tests of a model that the default suite exports elsewhere are ``slow``."""

from __future__ import annotations

import pytest


@pytest.hookimpl(tryfirst=True)  # before ``-m`` deselects by mark
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        cls = getattr(item, "cls", None)
        if getattr(cls, "deployed_by", None) and getattr(item, "originalname", "").startswith("test_onnx_"):
            item.add_marker(pytest.mark.slow)
