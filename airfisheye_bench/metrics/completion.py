"""Depth-completion metrics, with the conventions of NLSPN (``src/metric/nlspnmetric.py``)."""

from __future__ import annotations

from typing import ClassVar

from airfisheye_bench.metrics._per_image import PerImageAverage
from airfisheye_bench.metrics.functional import (
    COMPLETION_METRIC_KEYS,
    COMPLETION_VALID_MIN,
    completion_errors,
)

__all__ = ["CompletionMetrics"]


class CompletionMetrics(PerImageAverage):
    """Depth-completion metrics, computed per image and averaged over images (NLSPN conventions).

    Per image, on pixels with ``1e-4 < gt <= max_depth``, the prediction clamped to ``[0, max_depth]``
    (``nan`` -> 0): ``abs_rel``, ``rmse`` and ``mae`` in metres, ``irmse`` and ``imae`` in 1/m (the inverse
    of a value <= 1e-4 is taken as 0), and ``delta1..3`` (a prediction of 0 fails every delta); formulas in
    :func:`~airfisheye_bench.metrics.functional.completion_errors`. Note the units: the KITTI benchmark
    reports mm and 1/km. Images without a valid pixel are left out of the average; if no image had one,
    every value is NaN. Lower is better except for the deltas.

    Args:
        max_depth: Upper evaluation bound and prediction clamp in metres.
        kwargs: Passed to :class:`torchmetrics.Metric`.

    Example:
        >>> import torch
        >>> metric = CompletionMetrics(max_depth=120.0)
        >>> gt = torch.full((2, 1, 4, 4), 10.0)
        >>> metric.update(gt + 2.0, gt)
        >>> out = metric.compute()
        >>> out["mae"].item(), out["rmse"].item()
        (2.0, 2.0)
    """

    keys: ClassVar[tuple[str, ...]] = COMPLETION_METRIC_KEYS
    errors_fn = staticmethod(completion_errors)
    # torchmetrics' direction of the main output (MetricTracker); the task spec holds every column's direction.
    higher_is_better = False

    def __init__(self, max_depth: float = 120.0, **kwargs) -> None:
        if not max_depth > COMPLETION_VALID_MIN:
            raise ValueError(f"`max_depth` must be > {COMPLETION_VALID_MIN}, got {max_depth}")
        super().__init__(**kwargs)
        self.max_depth = float(max_depth)

    def settings(self) -> dict[str, float]:
        return {"max_depth": self.max_depth}
