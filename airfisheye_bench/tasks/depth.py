"""Monocular depth (paper IV-B): AdaBins loss (SILog + bin Chamfer), Eigen metrics up to 120 m."""

from __future__ import annotations

from typing import Any

import numpy as np
from torch import Tensor

from airfisheye_bench.metrics import DepthMetrics
from airfisheye_bench.metrics.scorer import task_metric
from airfisheye_bench.tasks.base import BenchmarkTask
from airfisheye_bench.viz import panel_row
from models.losses import AdaBinsLoss


class DepthTask(BenchmarkTask):
    """Monocular depth with any zoo ``depth`` model (AdaBins by default).

    Args:
        model: ``{"name": "adabins", ...}``.
        min_depth: Evaluation and loss lower bound (paper convention 1e-3 m).
        max_depth: Evaluation and loss upper bound (paper: 120 m).
        w_chamfer: Weight of the bins Chamfer loss (AdaBins: 0.1).
        **kwargs: See :class:`BenchmarkTask`.
    """

    task = "depth"

    def __init__(
        self,
        model: dict[str, Any],
        min_depth: float = 1e-3,
        max_depth: float = 120.0,
        w_chamfer: float = 0.1,
        **kwargs: Any,
    ) -> None:
        self.min_depth, self.max_depth = float(min_depth), float(max_depth)
        super().__init__(model, **kwargs)
        self.loss = AdaBinsLoss(w_chamfer=w_chamfer, min_depth=min_depth, max_depth=max_depth)

    def make_metric(self) -> DepthMetrics:
        return task_metric("depth", min_depth=self.min_depth, max_depth=self.max_depth)

    def target(self, batch: dict) -> Tensor:
        return batch["depth"]

    def loss_terms(self, outputs: dict[str, Tensor], batch: dict) -> dict[str, Tensor]:
        return self.loss.terms(outputs, batch["depth"])

    def prediction(self, outputs: dict[str, Tensor]) -> Tensor:
        return outputs["depth"]

    def panel_row(self, batch: dict, prediction: Tensor, index: int) -> list[np.ndarray]:
        return panel_row("depth", batch, prediction, index, max_depth=self.max_depth)
