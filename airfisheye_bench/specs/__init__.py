"""One :class:`TaskSpec` per benchmark task, registered once and looked up by every layer.

Importing this package registers ``seg``, ``depth`` and ``completion`` (in that order). A new task registers its
own spec with :func:`register_task` (docs/design.md, "Adding a task").

Example:
    >>> from airfisheye_bench.specs import get_task
    >>> spec = get_task("completion")
    >>> spec.inputs, spec.target, spec.output, spec.primary_metric
    (('image', 'sparse_depth'), 'depth', 'depth', 'rmse')
    >>> type(spec.make_metric(max_depth=80.0)).__name__
    'CompletionMetrics'
"""

from __future__ import annotations

from airfisheye_bench.specs.base import Baseline, ExportSpec, MetricColumn, MetricOptions, TaskSpec
from airfisheye_bench.specs.completion import COMPLETION
from airfisheye_bench.specs.depth import DEPTH
from airfisheye_bench.specs.formats import DEPTH_PNG_SCALE, LABELS, RANGE, PredictionFormat
from airfisheye_bench.specs.registry import (
    UnknownTaskError,
    all_tasks,
    get_task,
    register_task,
    task_names,
    unregister_task,
)
from airfisheye_bench.specs.seg import SEG

__all__ = [
    "COMPLETION",
    "DEPTH",
    "DEPTH_PNG_SCALE",
    "LABELS",
    "RANGE",
    "SEG",
    "Baseline",
    "ExportSpec",
    "MetricColumn",
    "MetricOptions",
    "PredictionFormat",
    "TaskSpec",
    "UnknownTaskError",
    "all_tasks",
    "get_task",
    "register_task",
    "task_names",
    "unregister_task",
]

for _spec in (SEG, DEPTH, COMPLETION):
    register_task(_spec)
