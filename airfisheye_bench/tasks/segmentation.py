"""Semantic segmentation (paper IV-A): cross-entropy, dataset-pooled mIoU."""

from __future__ import annotations

from typing import Any

import numpy as np
from torch import Tensor

from airfisheye_bench.metrics import SegmentationMetrics
from airfisheye_bench.metrics.scorer import task_metric
from airfisheye_bench.tasks.base import BenchmarkTask
from airfisheye_bench.viz import panel_row
from models.losses import SegmentationCELoss


class SegmentationTask(BenchmarkTask):
    """Segmentation with any zoo ``seg`` model.

    Args:
        model: ``{"name": "deeplabv3plus", ...}``; ``num_classes`` is set from ``class_names``.
        class_names: Training class names (from ``dataset.yaml``), in id order.
        palette: ``[num_classes][3]`` colours for panels.
        ignore_index: Label ignored by loss and metrics.
        **kwargs: See :class:`BenchmarkTask`.
    """

    task = "seg"

    def __init__(
        self,
        model: dict[str, Any],
        class_names: list[str],
        palette: list[list[int]] | None = None,
        ignore_index: int = 255,
        **kwargs: Any,
    ) -> None:
        self.class_names = list(class_names)
        self.ignore_index = ignore_index
        super().__init__({**model, "num_classes": len(self.class_names)}, **kwargs)
        self.loss = SegmentationCELoss(ignore_index=ignore_index)
        pal = np.zeros((256, 3), np.uint8)
        if palette is not None:
            pal[: len(palette)] = np.asarray(palette, np.uint8)
        self.palette = pal

    def make_metric(self) -> SegmentationMetrics:
        return task_metric("seg", class_names=self.class_names, ignore_index=self.ignore_index)

    def target(self, batch: dict) -> Tensor:
        return batch["label"]

    def loss_terms(self, outputs: dict[str, Tensor], batch: dict) -> dict[str, Tensor]:
        return {"loss": self.loss(outputs["logits"], batch["label"])}

    def prediction(self, outputs: dict[str, Tensor]) -> Tensor:
        return outputs["logits"].argmax(1)

    def panel_row(self, batch: dict, prediction: Tensor, index: int) -> list[np.ndarray]:
        return panel_row("seg", batch, prediction, index, palette=self.palette)
