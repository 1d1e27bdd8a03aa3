"""LightningModules of the three benchmark tasks."""

from airfisheye_bench.tasks.base import BenchmarkTask
from airfisheye_bench.tasks.completion import CompletionTask
from airfisheye_bench.tasks.depth import DepthTask
from airfisheye_bench.tasks.segmentation import SegmentationTask

TASKS = {"seg": SegmentationTask, "depth": DepthTask, "completion": CompletionTask}

__all__ = ["TASKS", "BenchmarkTask", "CompletionTask", "DepthTask", "SegmentationTask"]
