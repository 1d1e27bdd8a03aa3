"""Semantic segmentation (paper IV-A): the loss its config chooses (cross-entropy), dataset-pooled mIoU."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from airfisheye_bench.tasks.base import BenchmarkTask


class SegmentationTask(BenchmarkTask):
    """Segmentation with any zoo ``seg`` model.

    Args:
        model: ``{"name": "deeplabv3plus", ...}``; ``num_classes`` is set from ``class_names``.
        class_names: Training class names (from ``dataset.yaml``), in id order.
        palette: ``[num_classes][3]`` colours for panels.
        ignore_index: Label ignored by the metrics, and by the loss, whose own ``ignore_index`` (if it has one)
            must be the same.
        **kwargs: See :class:`BenchmarkTask` (``loss``: the seg config picks ``loss=cross_entropy``,
            :class:`~models.losses.SegmentationCELoss`; default: :meth:`default_loss`).
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
        loss_ignores = getattr(self.loss, "ignore_index", ignore_index)
        if loss_ignores != ignore_index:
            raise ValueError(
                f"the loss ignores label {loss_ignores} but the task ignores {ignore_index}: set the same "
                "ignore_index for both (task.module.loss.ignore_index, task.module.ignore_index)"
            )
        pal = np.zeros((256, 3), np.uint8)
        if palette is not None:
            pal[: len(palette)] = np.asarray(palette, np.uint8)
        self.palette = pal

    @classmethod
    def default_loss(cls, hparams: Mapping[str, Any]) -> dict[str, Any]:
        """Pixel-wise cross-entropy that ignores the task's ``ignore_index``."""
        return {"_target_": "models.losses.SegmentationCELoss", "ignore_index": hparams["ignore_index"]}

    def metric_options(self) -> dict[str, Any]:
        return {"class_names": self.class_names, "ignore_index": self.ignore_index}
