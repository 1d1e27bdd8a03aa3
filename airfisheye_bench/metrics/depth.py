"""Monocular depth metrics (Eigen et al.), with the conventions of AdaBins/BTS evaluation."""

from __future__ import annotations

from typing import ClassVar

from airfisheye_bench.metrics._per_image import PerImageAverage
from airfisheye_bench.metrics.functional import DEPTH_METRIC_KEYS, depth_errors

__all__ = ["DepthMetrics"]


class DepthMetrics(PerImageAverage):
    """Eigen depth metrics, computed per image and averaged over images (AdaBins ``compute_errors``).

    Per image, on pixels with ``min_depth < gt <= max_depth``, the prediction clipped to
    ``[min_depth, max_depth]`` (``nan`` -> ``min_depth``, ``inf`` -> ``max_depth``):
    ``abs_rel``, ``sq_rel``, ``rmse``, ``rmse_log``, ``log10``, ``silog``, ``delta1..3``
    (formulas in :func:`~airfisheye_bench.metrics.functional.depth_errors`; ``silog`` is
    ``100 * sqrt(mean(d^2) - mean(d)^2)`` with ``d = ln(pred) - ln(gt)``, as AdaBins/BTS report it).
    The values are then averaged over images. Images without a valid pixel are left out of the average; if
    no image had one, every value is NaN. Lower is better except for the deltas.

    Args:
        min_depth: Lower evaluation bound in metres (ground truth must be above it).
        max_depth: Upper evaluation bound in metres (ground truth at most this).
        kwargs: Passed to :class:`torchmetrics.Metric` (e.g. ``sync_on_compute``).

    Example:
        >>> import torch
        >>> metric = DepthMetrics(max_depth=120.0)
        >>> gt = torch.full((2, 1, 4, 4), 10.0)
        >>> metric.update(gt * 1.1, gt)
        >>> out = metric.compute()
        >>> round(out["abs_rel"].item(), 6), out["delta1"].item()
        (0.1, 1.0)
    """

    keys: ClassVar[tuple[str, ...]] = DEPTH_METRIC_KEYS
    errors_fn = staticmethod(depth_errors)
    # torchmetrics' direction of the main output (MetricTracker); the task spec holds every column's direction.
    higher_is_better = False

    def __init__(self, min_depth: float = 1e-3, max_depth: float = 120.0, **kwargs) -> None:
        if not 0 < min_depth < max_depth:
            raise ValueError(
                f"need 0 < min_depth < max_depth, got min_depth={min_depth}, max_depth={max_depth}"
            )
        super().__init__(**kwargs)
        self.min_depth = float(min_depth)
        self.max_depth = float(max_depth)

    def settings(self) -> dict[str, float]:
        return {"min_depth": self.min_depth, "max_depth": self.max_depth}
