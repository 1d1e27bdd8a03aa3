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

from airfisheye_bench.metrics._torchmetrics_compat import record_update, state_names, sums_every_state
from airfisheye_bench.metrics.binned import DEFAULT_DEPTH_EDGES_M, DEFAULT_RING_EDGES_DEG, BinnedMetrics

__all__ = ["TaskScorer"]


class TaskScorer(nn.Module):
    """A task metric, its incidence-angle rings and (for depth targets) its depth ranges, updated together.

    Args:
        metric_factory: Zero-argument callable returning a fresh task metric (e.g.
            ``get_task("depth").make_metric``, see :mod:`airfisheye_bench.specs`).
        ring_edges_deg: Incidence-angle ring edges in degrees.
        depth_edges_m: Ground-truth range bin edges in metres; ``None`` leaves the range breakdown out
            (segmentation targets carry no depth: ``TaskSpec.depth_breakdown``).

    Example:
        >>> import torch
        >>> from airfisheye_bench.metrics import DepthMetrics
        >>> scorer = TaskScorer(DepthMetrics, ring_edges_deg=(0, 45, 95))
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

    def stateful_metrics(self) -> list[Metric]:
        """The metrics holding states (the task metric and every bin's), in a fixed order."""
        return [m for m in self.modules() if isinstance(m, Metric) and state_names(m)]

    def can_add(self) -> bool:
        """Whether :meth:`add` applies: every state is a sum, merged without a synchronisation of its own."""
        return all(
            m.full_state_update is False and not m.dist_sync_on_step and sums_every_state(m)
            for m in self.stateful_metrics()
        )

    def add(self, other: TaskScorer) -> None:
        """Add the states of ``other`` (a scorer built alike, updated with other frames) to this one's: as if
        this scorer had been updated with those frames too. Needs :meth:`can_add`."""
        for mine, theirs in zip(self.stateful_metrics(), other.stateful_metrics(), strict=True):
            mine.merge_state(dict(theirs.metric_state))
            record_update(mine)

    def reset(self) -> None:
        """Clear every accumulated state."""
        self.metric.reset()
        self.rings.reset()
        if self.ranges is not None:
            self.ranges.reset()
