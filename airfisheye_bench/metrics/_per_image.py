"""Shared machinery of the per-image depth metrics: sum per-image values, count images, divide at the end."""

from __future__ import annotations

from collections.abc import Callable
from typing import ClassVar

import torch
from torch import Tensor
from torchmetrics import Metric


class PerImageAverage(Metric):
    """Average of per-image metric values over the images seen, DDP-exact.

    Subclasses set :attr:`keys` and :attr:`errors_fn` (the functional core returning per-image values and
    valid-pixel counts) and return its bounds from :meth:`settings`. The states are one float64 vector of per-image sums and an image count, both sum-reduced, so a
    distributed run gives the same numbers as one process. Images without a valid pixel are skipped; if no
    image was valid, :meth:`compute` returns NaN for every key.
    """

    keys: ClassVar[tuple[str, ...]] = ()
    is_differentiable = False
    full_state_update = False

    sum_values: Tensor
    num_images: Tensor

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.add_state("sum_values", torch.zeros(len(self.keys), dtype=torch.float64), dist_reduce_fx="sum")
        self.add_state("num_images", torch.zeros((), dtype=torch.int64), dist_reduce_fx="sum")

    #: The functional core: ``fn(preds, target, mask=..., groups=..., num_groups=..., **settings())``.
    errors_fn: ClassVar[Callable[..., tuple[dict[str, Tensor], Tensor]]]

    def settings(self) -> dict[str, float]:
        """The evaluation bounds passed to :attr:`errors_fn`; metrics of one class with equal settings can share one
        grouped call (see :class:`~airfisheye_bench.metrics.BinnedMetrics`)."""
        return {}

    def _errors(
        self,
        preds: Tensor,
        target: Tensor,
        mask: Tensor | None,
        groups: Tensor | None = None,
        num_groups: int = 1,
    ) -> tuple[dict[str, Tensor], Tensor]:
        """Per-image values ``{key: [B]}`` and valid counts ``[B]`` (``[B, G]`` for both with ``groups``)."""
        return type(self).errors_fn(
            preds, target, mask=mask, groups=groups, num_groups=num_groups, **self.settings()
        )

    def update(self, preds: Tensor, target: Tensor, mask: Tensor | None = None) -> None:
        """Add a batch.

        Args:
            preds: Predicted depth in metres, ``[B, 1, H, W]`` or ``[B, H, W]``.
            target: Ground-truth depth, same shape (0 = no ground truth).
            mask: Optional bool ``[H, W]``, ``[B, H, W]`` or ``[B, 1, H, W]``: evaluate only where True.
        """
        self._accumulate(*self._errors(preds, target, mask))

    def _accumulate(self, errors: dict[str, Tensor], num_valid: Tensor) -> None:
        """Add per-image values ``{key: [B]}`` with their valid-pixel counts ``[B]`` (images without one are skipped)."""
        has_pixels = num_valid > 0
        per_image = torch.stack([errors[k] for k in self.keys], dim=1)  # [B, K]
        self.sum_values += per_image[has_pixels].sum(dim=0).to(self.sum_values)
        self.num_images += has_pixels.sum().to(self.num_images)

    def compute(self) -> dict[str, Tensor]:
        """Mean over images per key (float64 scalars; NaN if no image had a valid pixel)."""
        means = self.sum_values / self.num_images
        return dict(zip(self.keys, means.unbind(), strict=True))
