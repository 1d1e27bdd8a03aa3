"""Semantic-segmentation metrics from a confusion matrix pooled over the whole split."""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor
from torchmetrics import Metric

from airfisheye_bench.metrics.functional import (
    confusion_matrix,
    iou_from_confusion,
    pixel_accuracy_from_confusion,
)

__all__ = ["SegmentationMetrics"]


class SegmentationMetrics(Metric):
    """Mean IoU, pixel accuracy and per-class IoU over a whole split (Cityscapes / mmseg convention).

    One ``int64`` confusion matrix is summed over every pixel of every batch (and every DDP process), and
    the IoUs are computed from it at the end -- never a mean of per-batch or per-image IoUs, which weights
    small batches and rare classes differently (``torchmetrics.segmentation.MeanIoU`` does that).

    Pixels whose target equals ``ignore_index`` (255: unlabelled and outside the fisheye image circle) are
    left out. A class absent from both prediction and target over the whole split has no IoU: its
    ``IoU/<class>`` is NaN and it is excluded from the ``mIoU`` mean (as torchmetrics'
    ``MulticlassJaccardIndex`` and mmseg's ``nanmean``). ``mIoU`` and ``pixel_acc`` are NaN when no pixel was
    evaluated.

    Output keys: ``mIoU``, ``pixel_acc`` and ``IoU/<name>`` per class (``name`` from ``class_names``,
    else the class index). Values are fractions in [0, 1].

    Args:
        num_classes: Number of training classes ``C``.
        ignore_index: Target value to leave out, outside ``[0, C)``; None to count every pixel.
        class_names: Optional ``C`` names used in the ``IoU/<name>`` keys.
        kwargs: Passed to :class:`torchmetrics.Metric`.

    Example:
        >>> import torch
        >>> metric = SegmentationMetrics(num_classes=3, class_names=["sky", "road", "tree"])
        >>> target = torch.tensor([[[0, 1, 1, 255]]])
        >>> metric.update(torch.tensor([[[0, 1, 2, 2]]]), target)
        >>> {k: round(v.item(), 3) for k, v in metric.compute().items()}
        {'mIoU': 0.5, 'pixel_acc': 0.667, 'IoU/sky': 1.0, 'IoU/road': 0.5, 'IoU/tree': 0.0}
    """

    # torchmetrics' direction of the main output (MetricTracker); the task spec holds every column's direction.
    higher_is_better = True
    is_differentiable = False
    full_state_update = False

    confmat: Tensor

    def __init__(
        self,
        num_classes: int,
        ignore_index: int | None = 255,
        class_names: Sequence[str] | None = None,
        **kwargs,
    ) -> None:
        if not isinstance(num_classes, int) or num_classes < 1:
            raise ValueError(f"`num_classes` must be a positive int, got {num_classes!r}")
        if ignore_index is not None and 0 <= ignore_index < num_classes:
            raise ValueError(
                f"`ignore_index` must be outside [0, num_classes={num_classes}) or None, got {ignore_index}"
            )
        if class_names is not None:
            class_names = [str(n) for n in class_names]
            if len(class_names) != num_classes or len(set(class_names)) != num_classes:
                raise ValueError(f"`class_names` must be {num_classes} distinct names, got {class_names}")
        super().__init__(**kwargs)
        self.num_classes = num_classes
        self.ignore_index = ignore_index
        self.class_names = class_names or [str(c) for c in range(num_classes)]
        self.add_state(
            "confmat", torch.zeros(num_classes, num_classes, dtype=torch.int64), dist_reduce_fx="sum"
        )

    def update(self, preds: Tensor, target: Tensor, mask: Tensor | None = None) -> None:
        """Add a batch.

        Args:
            preds: Integer labels ``[B, H, W]`` or scores/logits ``[B, C, H, W]`` (argmax over ``C``).
            target: Integer labels ``[B, H, W]`` or ``[B, 1, H, W]``.
            mask: Optional bool ``[H, W]``, ``[B, H, W]`` or ``[B, 1, H, W]``: count only where True.
        """
        self.confmat += confusion_matrix(preds, target, self.num_classes, self.ignore_index, mask=mask)

    def compute(self) -> dict[str, Tensor]:
        """``mIoU``, ``pixel_acc`` and ``IoU/<class>`` (float64 scalars) from the pooled confusion matrix."""
        iou = iou_from_confusion(self.confmat)
        out = {"mIoU": iou.nanmean(), "pixel_acc": pixel_accuracy_from_confusion(self.confmat)}
        out.update({f"IoU/{name}": v for name, v in zip(self.class_names, iou.unbind(), strict=True)})
        return out
