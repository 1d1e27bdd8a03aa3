"""LightningModules of the benchmark tasks; :data:`TASKS` maps each registered task name to its module class."""

from airfisheye_bench.tasks.base import BenchmarkTask
from airfisheye_bench.tasks.completion import CompletionTask
from airfisheye_bench.tasks.depth import DepthTask
from airfisheye_bench.tasks.segmentation import SegmentationTask

#: The module class of each task, keyed by its spec name (``TaskSpec.name``); a new task adds its class here.
TASKS: dict[str, type[BenchmarkTask]] = {
    cls.task: cls for cls in (SegmentationTask, DepthTask, CompletionTask)
}

__all__ = ["TASKS", "BenchmarkTask", "CompletionTask", "DepthTask", "SegmentationTask"]
