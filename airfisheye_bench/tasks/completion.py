"""Depth completion (paper IV-C): image + occlusion-corrected sparse LiDAR depth, L1 + L2 loss, NLSPN metrics."""

from __future__ import annotations

from typing import Any

import numpy as np
from torch import Tensor

from airfisheye_bench.metrics import CompletionMetrics
from airfisheye_bench.metrics.scorer import task_metric
from airfisheye_bench.tasks.base import BenchmarkTask
from airfisheye_bench.viz import panel_row
from models.losses import L1L2Loss


class CompletionTask(BenchmarkTask):
    """Depth completion with any zoo ``completion`` model (NLSPN by default).

    Args:
        model: ``{"name": "nlspn", ...}``.
        max_depth: Loss clamp and evaluation upper bound (paper: 120 m).
        l1_weight: Weight of the L1 term (paper: L1 + L2).
        l2_weight: Weight of the L2 term.
        **kwargs: See :class:`BenchmarkTask`.
    """

    task = "completion"

    def __init__(
        self,
        model: dict[str, Any],
        max_depth: float = 120.0,
        l1_weight: float = 1.0,
        l2_weight: float = 1.0,
        **kwargs: Any,
    ) -> None:
        self.max_depth = float(max_depth)
        super().__init__(model, **kwargs)
        self.loss = L1L2Loss(max_depth=max_depth, l1_weight=l1_weight, l2_weight=l2_weight)

    def make_metric(self) -> CompletionMetrics:
        return task_metric("completion", max_depth=self.max_depth)

    def model_inputs(self, batch: dict) -> tuple[Tensor, ...]:
        return batch["image"], batch["sparse_depth"]

    def target(self, batch: dict) -> Tensor:
        return batch["depth"]

    def loss_terms(self, outputs: dict[str, Tensor], batch: dict) -> dict[str, Tensor]:
        return self.loss.terms(outputs["depth"], batch["depth"])

    def prediction(self, outputs: dict[str, Tensor]) -> Tensor:
        return outputs["depth"]

    def panel_row(self, batch: dict, prediction: Tensor, index: int) -> list[np.ndarray]:
        return panel_row("completion", batch, prediction, index, max_depth=self.max_depth)
