"""The task registry: one :class:`~airfisheye_bench.specs.TaskSpec` per name, registered once.

The three benchmark tasks register when :mod:`airfisheye_bench.specs` is imported; every layer looks them up here.

Example:
    >>> from airfisheye_bench.specs import get_task, task_names
    >>> task_names()
    ('seg', 'depth', 'completion')
    >>> get_task("seg").primary_metric, get_task("depth").higher_is_better
    ('mIoU', False)
    >>> get_task("normals")
    Traceback (most recent call last):
    ...
    airfisheye_bench.specs.registry.UnknownTaskError: unknown task 'normals'; registered tasks: seg, depth, completion
"""

from __future__ import annotations

from airfisheye_bench.specs.base import TaskSpec

__all__ = ["UnknownTaskError", "all_tasks", "get_task", "register_task", "task_names", "unregister_task"]

_TASKS: dict[str, TaskSpec] = {}  # insertion order is the display order (seg, depth, completion, then others)


class UnknownTaskError(KeyError, ValueError):
    """A task name that is not registered; the message lists the valid names.

    A ``ValueError`` for callers validating input, a ``KeyError`` for lookups.
    """

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


def register_task(spec: TaskSpec) -> TaskSpec:
    """Register ``spec`` under its name and return it.

    Raises:
        ValueError: another spec is already registered under that name.
    """
    if not isinstance(spec, TaskSpec):
        raise TypeError(f"register_task takes a TaskSpec, got {type(spec).__name__}")
    if spec.name in _TASKS and _TASKS[spec.name] is not spec:
        raise ValueError(f"task {spec.name!r} is already registered")
    _TASKS[spec.name] = spec
    return spec


def unregister_task(name: str) -> None:
    """Remove a registered task (tests and plugins that register their own)."""
    _TASKS.pop(name, None)


def get_task(name: str) -> TaskSpec:
    """The spec registered under ``name``.

    Raises:
        UnknownTaskError: ``name`` is not registered; the message lists the registered names.
    """
    try:
        return _TASKS[name]
    except (KeyError, TypeError):
        raise UnknownTaskError(
            f"unknown task {name!r}; registered tasks: {', '.join(_TASKS) or '(none)'}"
        ) from None


def task_names() -> tuple[str, ...]:
    """Names of the registered tasks, in registration order."""
    return tuple(_TASKS)


def all_tasks() -> tuple[TaskSpec, ...]:
    """The registered specs, in registration order."""
    return tuple(_TASKS.values())
