"""The metrics of one evaluation: the task's metric plus its fisheye breakdown, in one module.

Training (validation and test stages) and the evaluation command score predictions through the same
:class:`TaskScorer`, so a checkpoint, its ONNX export and a folder of prediction files are measured by one code
path. The breakdown is by ring of incidence angle (every task: fisheye models degrade towards the rim) and, for
depth tasks, by ground-truth range.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from torch import Tensor, nn
from torchmetrics import Metric

from airfisheye_bench.metrics.binned import DEFAULT_DEPTH_EDGES_M, DEFAULT_RING_EDGES_DEG, BinnedMetrics
from airfisheye_bench.metrics.completion import CompletionMetrics
from airfisheye_bench.metrics.depth import DepthMetrics
from airfisheye_bench.metrics.segmentation import SegmentationMetrics

__all__ = ["TaskScorer", "task_metric"]

TASK_NAMES = ("seg", "depth", "completion")


def task_metric(
    task: str,
    class_names: Sequence[str] | None = None,
    ignore_index: int = 255,
    min_depth: float = 1e-3,
    max_depth: float = 120.0,
) -> Metric:
    """A fresh metric of ``task`` with the paper's conventions (``docs/design.md``, Metrics).

    Args:
        task: ``seg``, ``depth`` or ``completion``.
        class_names: Training class names (``seg``; their count is the number of classes).
        ignore_index: Ignored label (``seg``).
        min_depth: Lower evaluation bound (``depth``; completion uses ``1e-4`` by its own convention).
        max_depth: Upper evaluation bound in metres (``depth``, ``completion``).

    Example:
        >>> type(task_metric("completion")).__name__
        'CompletionMetrics'
    """
    if task == "seg":
        if not class_names:
            raise ValueError("task_metric('seg') needs class_names")
        return SegmentationMetrics(len(class_names), ignore_index=ignore_index, class_names=list(class_names))
    if task == "depth":
        return DepthMetrics(min_depth=min_depth, max_depth=max_depth)
    if task == "completion":
        return CompletionMetrics(max_depth=max_depth)
    raise ValueError(f"task must be one of {TASK_NAMES}, got {task!r}")


class TaskScorer(nn.Module):
    """A task metric, its incidence-angle rings and (for depth targets) its depth ranges, updated together.

    Args:
        metric_factory: Zero-argument callable returning a fresh task metric (e.g. ``lambda: task_metric("depth")``).
        ring_edges_deg: Incidence-angle ring edges in degrees.
        depth_edges_m: Ground-truth range bin edges in metres; ``None`` leaves the range breakdown out
            (segmentation targets carry no depth).

    Example:
        >>> import torch
        >>> scorer = TaskScorer(lambda: task_metric("depth"), ring_edges_deg=(0, 45, 95))
        >>> gt = torch.full((1, 1, 2, 2), 10.0)
        >>> pred = torch.tensor([[[[10.0, 12.0], [12.0, 10.0]]]])
        >>> theta = torch.tensor([[10.0, 50.0], [50.0, 10.0]])
        >>> scorer.update(pred, gt, theta=theta)
        >>> result = scorer.compute()
        >>> round(result["metrics"]["rmse"], 3), result["breakdown"]["ring_45-95/rmse"], result["breakdown"]["ring_0-45/rmse"]
        (1.414, 2.0, 0.0)
    """

    def __init__(
        self,
        metric_factory: Callable[[], Metric],
        ring_edges_deg: Sequence[float] = DEFAULT_RING_EDGES_DEG,
        depth_edges_m: Sequence[float] | None = DEFAULT_DEPTH_EDGES_M,
    ) -> None:
        super().__init__()
        self.metric = metric_factory()
        self.rings = BinnedMetrics(metric_factory, edges=ring_edges_deg, key="theta")
        self.ranges = (
            BinnedMetrics(metric_factory, edges=depth_edges_m, key="depth")
            if depth_edges_m is not None
            else None
        )

    def update(self, preds: Tensor, target: Tensor, theta: Tensor, mask: Tensor | None = None) -> None:
        """Add one batch.

        Args:
            preds: Labels/logits (seg) or depth, as the task metric's ``update``.
            target: Labels ``[B, H, W]`` or depth ``[B, 1, H, W]``.
            theta: Incidence angle of every pixel in degrees, ``[H, W]``.
            mask: Optional bool ``[B, H, W]`` of evaluated pixels (the image circle).
        """
        self.metric.update(preds, target, mask=mask)
        self.rings.update(preds, target, theta=theta, mask=mask)
        if self.ranges is not None:
            self.ranges.update(preds, target, mask=mask)

    def compute(self) -> dict[str, dict[str, float]]:
        """``{"metrics": {key: value}, "breakdown": {"ring_0-30/rmse": value, "range_0-10/rmse": ...}}``.

        Values are plain floats; NaN marks a class or bin without a valid pixel.
        """
        metrics = {k: float(v) for k, v in self.metric.compute().items()}
        breakdown = {k: float(v) for k, v in self.rings.compute().items()}
        if self.ranges is not None:
            breakdown.update({k: float(v) for k, v in self.ranges.compute().items()})
        return {"metrics": metrics, "breakdown": breakdown}

    def reset(self) -> None:
        """Clear every accumulated state."""
        self.metric.reset()
        self.rings.reset()
        if self.ranges is not None:
            self.ranges.reset()
