"""The shared model tester's own wiring."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import models
from tests.helpers.model_tester import DEPLOYED_BY

ROOT = Path(__file__).resolve().parents[2]


def _marks(node: ast.AST) -> set[str]:
    """The ``pytest.mark.<name>`` names in the decorators or the ``pytestmark`` value ``node`` holds."""
    return {
        n.attr
        for n in ast.walk(node)
        if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Attribute) and n.value.attr == "mark"
    }


@pytest.mark.parametrize("model", sorted(DEPLOYED_BY))
def test_a_model_deployed_elsewhere_is_exported_by_a_default_test(model: str) -> None:
    """Each entry names a registered model and a test of the default suite (it exists, and neither it nor its module
    is ``slow``): the model keeps one export in the default suite while its tester's ONNX tests run with
    ``-m slow``."""
    assert model in models.list_models()
    path, name = DEPLOYED_BY[model].split("::")
    tree = ast.parse((ROOT / path).read_text())
    (test,) = [n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == name]
    module_marks = [
        n.value
        for n in tree.body
        if isinstance(n, ast.Assign)
        and any(isinstance(t, ast.Name) and t.id == "pytestmark" for t in n.targets)
    ]
    assert not any("slow" in _marks(node) for node in [*test.decorator_list, *module_marks])
