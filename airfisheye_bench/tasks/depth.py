"""Monocular depth (paper IV-B): AdaBins loss (SILog + bin Chamfer), Eigen metrics up to 120 m."""

from __future__ import annotations

from typing import Any

from torch import Tensor

from airfisheye_bench.tasks.base import BenchmarkTask
from models.losses import AdaBinsLoss


class DepthTask(BenchmarkTask):
    """Monocular depth with any zoo ``depth`` model (AdaBins by default).

    Args:
        model: ``{"name": "adabins", ...}``.
        min_depth: Evaluation and loss lower bound (paper convention 1e-3 m).
        max_depth: Evaluation and loss upper bound (paper: 120 m).
        w_chamfer: Weight of the bins Chamfer loss (AdaBins: 0.1).
        chamfer_reference_range: Measure the Chamfer term in fractions of ``max_depth`` times this range (m)
            instead of metres (None, as upstream): :class:`~models.losses.BinsChamferLoss`.
        **kwargs: See :class:`BenchmarkTask`.
    """

    task = "depth"

    def __init__(
        self,
        model: dict[str, Any],
        min_depth: float = 1e-3,
        max_depth: float = 120.0,
        w_chamfer: float = 0.1,
        chamfer_reference_range: float | None = None,
        **kwargs: Any,
    ) -> None:
        self.min_depth, self.max_depth = float(min_depth), float(max_depth)
        super().__init__(model, **kwargs)
        self.loss = AdaBinsLoss(
            w_chamfer=w_chamfer,
            min_depth=min_depth,
            max_depth=max_depth,
            chamfer_reference_range=chamfer_reference_range,
        )

    def metric_options(self) -> dict[str, Any]:
        return {"min_depth": self.min_depth, "max_depth": self.max_depth}

    def loss_terms(self, outputs: dict[str, Tensor], batch: dict) -> dict[str, Tensor]:
        return self.loss.terms(outputs, batch["depth"])
