"""A plain name -> constructor registry, so configs pick models by name.

Every registered model follows one calling convention (see ``models/__init__.py``):
``forward`` returns the primary output only (exportable to ONNX), ``forward_with_aux`` returns a dict
with the primary output under ``"logits"`` / ``"depth"`` plus whatever the training loss needs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from torch import nn

from airfisheye_bench.specs import get_task

_MODELS: dict[str, Callable[..., nn.Module]] = {}
_MODEL_TASKS: dict[str, str] = {}

F = TypeVar("F", bound=Callable[..., nn.Module])


def register_model(name: str, task: str) -> Callable[[F], F]:
    """Register a model constructor under ``name`` for ``task`` (a registered task, see :mod:`airfisheye_bench.specs`).

    Raises:
        ValueError: ``task`` is not registered (the message lists the registered tasks).
    """
    get_task(task)

    def decorator(fn: F) -> F:
        key = name.lower()
        if key in _MODELS:
            raise ValueError(f"model {name!r} is already registered")
        _MODELS[key] = fn
        _MODEL_TASKS[key] = task
        return fn

    return decorator


def list_models(task: str | None = None) -> list[str]:
    """Names of the registered models, optionally only those for ``task``."""
    return sorted(k for k, t in _MODEL_TASKS.items() if task is None or t == task)


def model_task(name: str) -> str:
    """The task a registered model solves."""
    _check_name(name)
    return _MODEL_TASKS[name.lower()]


def create_model(name: str, **kwargs) -> nn.Module:
    """Build a registered model by name.

    Raises:
        KeyError: ``name`` is not registered; the message lists the valid names.
    """
    _check_name(name)
    return _MODELS[name.lower()](**kwargs)


def _check_name(name: str) -> None:
    if name.lower() not in _MODELS:
        raise KeyError(f"unknown model {name!r}; registered models: {', '.join(list_models()) or '(none)'}")
