"""Completion metrics on the pixels where occlusion correction can matter, beside the whole image.

An occlusion method only changes the sparse input where a hidden LiDAR point projects, a small part of the image
(docs/results.md, section 4). Whole-image metrics dilute that change with every pixel it cannot touch, so a
comparison of the methods also scores two regions of each frame:

* ``affected``: the pixels whose sparse input differs between ``none`` (every projected point) and ``oracle``
  (the truly visible points), dilated by ``radius`` pixels (a square window: +- ``radius`` in both axes), where a
  network's prediction can be pulled by a wrong point;
* ``near``: ground truth closer than ``near_m`` metres, where the camera-LiDAR parallax, and with it occlusion,
  is largest.

Both are computed per frame from that frame's own two sparse maps and ground truth. The functional core
(:func:`dilate`, :func:`affected_pixels`, :func:`near_pixels`, :func:`input_difference`) is plain torch;
:class:`RegionCompletionMetrics` accumulates :class:`~airfisheye_bench.metrics.CompletionMetrics` per region.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn
from torchmetrics import Metric

from airfisheye_bench.metrics.completion import CompletionMetrics

__all__ = [
    "DEFAULT_NEAR_M",
    "DEFAULT_RADIUS_PX",
    "REGIONS",
    "RegionCompletionMetrics",
    "affected_pixels",
    "dilate",
    "input_difference",
    "near_pixels",
]

#: The regions :class:`RegionCompletionMetrics` scores, in this order.
REGIONS = ("all", "affected", "near")
#: Default dilation of the affected pixels (+- pixels) and near-range bound (metres).
DEFAULT_RADIUS_PX = 2
DEFAULT_NEAR_M = 20.0


def _as_bhw(x: Tensor, name: str) -> Tensor:
    """``[H, W]``, ``[B, H, W]`` or ``[B, 1, H, W]`` -> ``[B, H, W]``."""
    if x.ndim == 4 and x.shape[1] == 1:
        return x[:, 0]
    if x.ndim == 3:
        return x
    if x.ndim == 2:
        return x[None]
    raise ValueError(f"{name} must be [H, W], [B, H, W] or [B, 1, H, W], got shape {tuple(x.shape)}")


def dilate(mask: Tensor, radius: int) -> Tensor:
    """``mask`` grown by ``radius`` pixels in a square window (Chebyshev distance <= ``radius``).

    Args:
        mask: bool ``[H, W]``, ``[B, H, W]`` or ``[B, 1, H, W]``.
        radius: Pixels to grow by, >= 0 (0: ``mask`` itself).

    Returns:
        bool ``[B, H, W]``.

    Example:
        >>> m = torch.zeros(5, 5, dtype=torch.bool)
        >>> m[2, 2] = True
        >>> dilate(m, 1)[0].int().tolist()
        [[0, 0, 0, 0, 0], [0, 1, 1, 1, 0], [0, 1, 1, 1, 0], [0, 1, 1, 1, 0], [0, 0, 0, 0, 0]]
    """
    if isinstance(radius, bool) or not isinstance(radius, int) or radius < 0:
        raise ValueError(f"radius must be an integer >= 0, got {radius!r}")
    m = _as_bhw(mask, "mask").bool()
    if radius == 0:
        return m
    grown = F.max_pool2d(m[:, None].float(), kernel_size=2 * radius + 1, stride=1, padding=radius)
    return grown[:, 0] > 0


def affected_pixels(
    sparse_none: Tensor, sparse_oracle: Tensor, radius: int = DEFAULT_RADIUS_PX, valid: Tensor | None = None
) -> Tensor:
    """Pixels whose sparse input differs between ``none`` and the oracle, dilated by ``radius`` (and valid).

    Example:
        >>> none = torch.zeros(1, 1, 4, 6)
        >>> oracle = none.clone()
        >>> none[0, 0, 1, 1] = 3.0  # a hidden point, which the oracle drops
        >>> affected_pixels(none, oracle, radius=1)[0].int().tolist()
        [[1, 1, 1, 0, 0, 0], [1, 1, 1, 0, 0, 0], [1, 1, 1, 0, 0, 0], [0, 0, 0, 0, 0, 0]]
    """
    a, b = _as_bhw(sparse_none, "sparse_none"), _as_bhw(sparse_oracle, "sparse_oracle")
    if a.shape != b.shape:
        raise ValueError(f"sparse maps differ in shape: {tuple(a.shape)} vs {tuple(b.shape)}")
    out = dilate(a != b, radius)
    return out & _as_bhw(valid, "valid").bool() if valid is not None else out


def near_pixels(target: Tensor, near_m: float = DEFAULT_NEAR_M) -> Tensor:
    """Pixels with ground truth (``> 0``) closer than ``near_m`` metres, ``[B, H, W]``.

    Example:
        >>> near_pixels(torch.tensor([[0.0, 5.0, 19.9, 20.0, 50.0]]), 20.0).tolist()
        [[[False, True, True, False, False]]]
    """
    if not near_m > 0:
        raise ValueError(f"near_m must be a positive number of metres, got {near_m!r}")
    t = _as_bhw(target, "target")
    return (t > 0) & (t < near_m)


def input_difference(sparse: Tensor, reference: Tensor, valid: Tensor | None = None) -> dict[str, int]:
    """Counts of how much a sparse input differs from a reference (``none``), pixel by pixel.

    Returns:
        ``differing``: valid pixels whose value differs (a point removed, or another point nearest there);
        ``sparse``: valid pixels holding a point in either map (for inputs that only remove points of ``none``,
        ``none``'s sparse pixels); ``valid``: valid pixels.

    Example:
        >>> ref = torch.tensor([[5.0, 7.0, 0.0, 9.0]])
        >>> input_difference(torch.tensor([[5.0, 0.0, 0.0, 12.0]]), ref)
        {'differing': 2, 'sparse': 3, 'valid': 4}
    """
    s, r = _as_bhw(sparse, "sparse"), _as_bhw(reference, "reference")
    if s.shape != r.shape:
        raise ValueError(f"sparse maps differ in shape: {tuple(s.shape)} vs {tuple(r.shape)}")
    v = (
        _as_bhw(valid, "valid").bool().expand_as(s)
        if valid is not None
        else torch.ones_like(s, dtype=torch.bool)
    )
    return {
        "differing": int(((s != r) & v).sum()),
        "sparse": int((((s > 0) | (r > 0)) & v).sum()),
        "valid": int(v.sum()),
    }


class RegionCompletionMetrics(Metric):
    """:class:`~airfisheye_bench.metrics.CompletionMetrics` on the whole image and on each region of
    :data:`REGIONS`, plus the pixels and images each region held.

    Per-image averages, as the task metric: an image without a pixel of a region is left out of that region's
    average (``images`` says how many were counted).

    Args:
        radius: Dilation of the affected pixels (+- pixels).
        near_m: Near-range bound in metres.
        max_depth: As :class:`~airfisheye_bench.metrics.CompletionMetrics`.

    Example:
        >>> metric = RegionCompletionMetrics(radius=0, near_m=20.0)
        >>> gt = torch.full((1, 1, 2, 2), 10.0)
        >>> none, oracle = torch.zeros_like(gt), torch.zeros_like(gt)
        >>> none[0, 0, 0, 0] = 4.0  # one hidden point: one affected pixel
        >>> pred = gt.clone()
        >>> pred[0, 0, 0, 0] = 6.0  # wrong by 4 m there
        >>> metric.update(pred, gt, none, oracle)
        >>> out = metric.compute()
        >>> out["affected"]["mae"], out["all"]["mae"], out["near"]["mae"], out["affected"]["pixels"]
        (4.0, 1.0, 1.0, 1)
    """

    is_differentiable = False
    full_state_update = False

    pixels: Tensor
    images: Tensor

    def __init__(
        self,
        radius: int = DEFAULT_RADIUS_PX,
        near_m: float = DEFAULT_NEAR_M,
        max_depth: float = 120.0,
        **kwargs,
    ) -> None:
        super().__init__(**kwargs)
        dilate(
            torch.zeros(1, 1, dtype=torch.bool), radius
        )  # a bad radius fails here, not in the first update
        near_pixels(torch.zeros(1, 1), near_m)
        self.radius = int(radius)
        self.near_m = float(near_m)
        self.regions = nn.ModuleDict({name: CompletionMetrics(max_depth=max_depth) for name in REGIONS})
        self.add_state("pixels", torch.zeros(len(REGIONS), dtype=torch.int64), dist_reduce_fx="sum")
        self.add_state("images", torch.zeros(len(REGIONS), dtype=torch.int64), dist_reduce_fx="sum")

    def masks(
        self, target: Tensor, sparse_none: Tensor, sparse_oracle: Tensor, valid: Tensor | None = None
    ) -> dict[str, Tensor]:
        """The region masks ``[B, H, W]`` of a batch (the whole image: ``valid``, or where ground truth is)."""
        t = _as_bhw(target, "target")
        base = (
            _as_bhw(valid, "valid").bool().expand_as(t)
            if valid is not None
            else torch.ones_like(t, dtype=torch.bool)
        )
        return {
            "all": base,
            "affected": affected_pixels(sparse_none, sparse_oracle, self.radius, base),
            "near": near_pixels(t, self.near_m) & base,
        }

    def update(
        self,
        preds: Tensor,
        target: Tensor,
        sparse_none: Tensor,
        sparse_oracle: Tensor,
        valid: Tensor | None = None,
    ) -> None:
        """Add a batch: predictions and ground truth ``[B, 1, H, W]``, the frames' ``none`` and ``oracle`` sparse
        maps (same shape) and their valid masks."""
        t = _as_bhw(target, "target")
        for k, (name, mask) in enumerate(self.masks(target, sparse_none, sparse_oracle, valid).items()):
            self.regions[name].update(preds, target, mask[:, None])
            counted = mask & (t > 0)
            self.pixels[k] += counted.sum()
            self.images[k] += counted.flatten(1).any(dim=1).sum()

    def compute(self) -> dict[str, dict[str, float]]:
        """``{region: {metric: value, "pixels": n, "images": n}}`` (metric values NaN for an empty region)."""
        out: dict[str, dict[str, float]] = {}
        for k, name in enumerate(REGIONS):
            values = {key: float(v) for key, v in self.regions[name].compute().items()}
            out[name] = {**values, "pixels": int(self.pixels[k]), "images": int(self.images[k])}
        return out

    def reset(self) -> None:
        super().reset()
        for metric in self.regions.values():
            metric.reset()
