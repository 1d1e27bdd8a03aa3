"""Benchmark metrics: segmentation (pooled mIoU), monocular depth (Eigen), depth completion (NLSPN), and a
fisheye breakdown by incidence-angle ring or depth range; :class:`TaskScorer` updates a task's metric and its
breakdown together (training and evaluation score through it).

Every class is a :class:`torchmetrics.Metric` with sum-reduced states, so a DDP run gives the same numbers
as one process. The maths lives in :mod:`airfisheye_bench.metrics.functional`.
"""

from airfisheye_bench.metrics import functional
from airfisheye_bench.metrics.binned import (
    DEFAULT_DEPTH_EDGES_M,
    DEFAULT_RING_EDGES_DEG,
    BinnedMetrics,
    bin_index,
    ring_edges_for,
)
from airfisheye_bench.metrics.completion import CompletionMetrics
from airfisheye_bench.metrics.coverage import RingCoverage
from airfisheye_bench.metrics.depth import DepthMetrics
from airfisheye_bench.metrics.functional import (
    COMPLETION_METRIC_KEYS,
    DEPTH_METRIC_KEYS,
    completion_errors,
    confusion_matrix,
    depth_errors,
    iou_from_confusion,
    mean_iou_from_confusion,
    pixel_accuracy_from_confusion,
)
from airfisheye_bench.metrics.scorer import TaskScorer
from airfisheye_bench.metrics.segmentation import SegmentationMetrics

__all__ = [
    "COMPLETION_METRIC_KEYS",
    "DEFAULT_DEPTH_EDGES_M",
    "DEFAULT_RING_EDGES_DEG",
    "DEPTH_METRIC_KEYS",
    "BinnedMetrics",
    "CompletionMetrics",
    "DepthMetrics",
    "RingCoverage",
    "SegmentationMetrics",
    "TaskScorer",
    "bin_index",
    "completion_errors",
    "confusion_matrix",
    "depth_errors",
    "functional",
    "iou_from_confusion",
    "mean_iou_from_confusion",
    "pixel_accuracy_from_confusion",
    "ring_edges_for",
]
