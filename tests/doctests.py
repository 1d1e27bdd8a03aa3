"""Run a module's docstring examples as a test (every public example in the project is runnable)."""

from __future__ import annotations

import doctest
import importlib
from types import ModuleType


def assert_doctests_pass(module: str | ModuleType, flags: int = 0, min_examples: int = 1) -> None:
    """Run the examples of ``module`` (a module or its dotted name) with ``ELLIPSIS``; all must pass.

    Args:
        module: The module, or its import name.
        flags: Extra ``doctest`` option flags.
        min_examples: Fewest examples the module must have (a module listed here without any is a mistake).
    """
    if isinstance(module, str):
        module = importlib.import_module(module)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | flags)
    assert result.attempted >= min_examples, f"{module.__name__} has {result.attempted} docstring examples"
    assert result.failed == 0, f"{result.failed} docstring example(s) of {module.__name__} failed"
