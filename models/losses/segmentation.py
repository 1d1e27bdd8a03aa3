"""Segmentation loss: pixel-wise cross-entropy with the dataset's ignore label (255)."""

from __future__ import annotations

from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import Tensor, nn


class SegmentationCELoss(nn.Module):
    """Cross-entropy over pixels, ignoring ``ignore_index`` (255: unlabelled and outside the image circle).

    Args:
        ignore_index: label to ignore.
        weight: optional per-class weights ``[C]`` (a tensor, or a list of numbers as a config writes them).
        label_smoothing: as in :func:`torch.nn.functional.cross_entropy`.

    Example:
        >>> import torch
        >>> logits = torch.zeros(1, 3, 2, 2)
        >>> target = torch.tensor([[[0, 1], [255, 255]]])
        >>> round(float(SegmentationCELoss()(logits, target)), 4)  # log(3) over the 2 labelled pixels
        1.0986
    """

    def __init__(
        self,
        ignore_index: int = 255,
        weight: Tensor | Sequence[float] | None = None,
        label_smoothing: float = 0.0,
    ) -> None:
        super().__init__()
        self.ignore_index = ignore_index
        self.label_smoothing = label_smoothing
        if weight is not None:
            weight = torch.as_tensor(weight, dtype=torch.float32)
        self.register_buffer("weight", weight, persistent=False)

    def forward(self, logits: Tensor, target: Tensor) -> Tensor:
        """``logits`` ``[B, C, H, W]``, ``target`` ``[B, H, W]`` integer labels. Returns 0 (with a graph) when
        every pixel is ignored (plain cross-entropy would give NaN)."""
        if logits.ndim != 4 or target.shape != (logits.shape[0], *logits.shape[2:]):
            raise ValueError(
                f"logits must be [B, C, H, W] and target [B, H, W] with the same B, H, W; "
                f"got {list(logits.shape)} and {list(target.shape)}"
            )
        target = target.long()
        if not (target != self.ignore_index).any():
            return logits.sum() * 0.0
        return F.cross_entropy(
            logits,
            target,
            weight=self.weight,
            ignore_index=self.ignore_index,
            label_smoothing=self.label_smoothing,
        )
