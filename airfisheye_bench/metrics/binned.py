"""Fisheye breakdown: any metric evaluated separately per ring of incidence angle or per ground-truth depth range.

A fisheye image mixes very different viewing geometry: the centre looks along the optical axis, the rim
(theta near 95 deg for a 190 deg lens) is strongly compressed. A single number hides where a model fails, so
:class:`BinnedMetrics` keeps one child metric per bin and restricts each to the pixels of its bin through
the child's ``mask`` argument. The children are ordinary torchmetrics metrics in an ``nn.ModuleList``, so
each one syncs its own summed states under DDP.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from typing import Any, Literal

import torch
from torch import Tensor, nn
from torchmetrics import Metric
from torchmetrics.wrappers.abstract import WrapperMetric

from airfisheye_bench.metrics._per_image import PerImageAverage
from airfisheye_bench.metrics._torchmetrics_compat import record_update
from airfisheye_bench.metrics.functional import _check_mask

__all__ = ["DEFAULT_DEPTH_EDGES_M", "DEFAULT_RING_EDGES_DEG", "BinnedMetrics", "bin_index", "ring_edges_for"]

#: Rings of incidence angle theta (deg) for the default 190 deg lens: centre, mid, outer, rim beyond 80 deg.
DEFAULT_RING_EDGES_DEG: tuple[float, ...] = (0.0, 30.0, 60.0, 80.0, 95.0)
#: Ground-truth depth (range) bins in metres up to the evaluation limit of 120 m.
DEFAULT_DEPTH_EDGES_M: tuple[float, ...] = (0.0, 10.0, 20.0, 40.0, 80.0, 120.0)

_PREFIX = {"theta": "ring", "depth": "range"}


def ring_edges_for(fov_deg: float, edges: Sequence[float] = DEFAULT_RING_EDGES_DEG) -> tuple[float, ...]:
    """Ring edges that cover a lens of ``fov_deg``: ``edges``, plus a ring out to its rim when it sees further.

    The default rings end at 95 deg (a 190 deg lens); a wider lens (220 deg) would otherwise score its outermost
    pixels in the overall metric but in no ring.

    Example:
        >>> ring_edges_for(190.0), ring_edges_for(220.0)
        ((0.0, 30.0, 60.0, 80.0, 95.0), (0.0, 30.0, 60.0, 80.0, 95.0, 110.0))
    """
    edges = tuple(float(e) for e in edges)
    rim = math.ceil(fov_deg / 2.0)
    return (*edges, float(rim)) if rim > edges[-1] else edges


def bin_index(values: Tensor, edges: Sequence[float], include_lowest: bool) -> Tensor:
    """Bin of every value for right-closed bins ``(edges[i], edges[i + 1]]`` (as ``pandas.cut``).

    Args:
        values: Any-shape tensor (NaN falls in no bin).
        edges: Increasing bin edges, at least two.
        include_lowest: Whether the first bin also includes ``edges[0]`` (``[edges[0], edges[1]]``).

    Returns:
        int64 tensor like ``values``: the bin index, or -1 outside every bin.

    Example:
        >>> bin_index(torch.tensor([0.0, 5.0, 10.0, 10.5, 99.0]), (0, 10, 20), include_lowest=True)
        tensor([ 0,  0,  0,  1, -1])
    """
    boundaries = torch.as_tensor(edges, dtype=values.dtype, device=values.device)
    # bucketize(right=False) returns i with boundaries[i-1] < v <= boundaries[i]; NaN sorts past the end.
    index = torch.bucketize(values, boundaries) - 1
    if include_lowest:
        index = torch.where(values == boundaries[0], 0, index)
    return torch.where((index >= 0) & (index < len(edges) - 1), index, -1)


def _edge_label(x: float) -> str:
    return f"{x:g}"


class BinnedMetrics(WrapperMetric):
    """One child metric per bin of incidence angle (``key="theta"``) or ground-truth depth (``key="depth"``).

    Bins are right-closed, ``(lo, hi]`` -- the same convention as the depth evaluation mask
    ``min_depth < gt <= max_depth`` -- so depth 0 ("no ground truth") falls in no bin. For ``theta`` the first
    bin also includes its lower edge, so the principal point (theta = 0) is counted. Pixels outside every
    bin (e.g. theta > 95 deg or NaN outside the field of view) are not evaluated.

    Output keys are ``<prefix>_<lo>-<hi>/<child key>`` with prefix ``ring`` (theta, degrees) or ``range``
    (depth, metres), e.g. ``ring_60-80/rmse`` or ``range_0-10/mIoU``. Each child follows its own rules: a
    per-image depth metric averages over the images that have a valid pixel *in that bin*, and gives NaN
    for a bin that never had one; a segmentation child pools its confusion matrix over the bin's pixels, so
    the children's confusion matrices add up to the global one when the bins cover every evaluated pixel.

    Args:
        metric_factory: Zero-argument callable returning a fresh metric that accepts
            ``update(preds, target, mask=...)``, e.g. ``DepthMetrics``, ``lambda: SegmentationMetrics(13)``
            or, from Hydra, ``{_target_: airfisheye_bench.metrics.DepthMetrics, _partial_: true}``.
        edges: Increasing bin edges; default :data:`DEFAULT_RING_EDGES_DEG` for ``theta`` and
            :data:`DEFAULT_DEPTH_EDGES_M` for ``depth``.
        key: ``"theta"`` (incidence angle in degrees, from the camera) or ``"depth"`` (ground-truth range).

    Example:
        >>> import torch
        >>> from airfisheye_bench.metrics import DepthMetrics
        >>> rings = BinnedMetrics(lambda: DepthMetrics(), edges=(0, 45, 95), key="theta")
        >>> theta = torch.tensor([[10.0, 50.0], [50.0, 100.0]])  # [H, W] degrees, 100 = outside the FOV
        >>> gt = torch.full((1, 1, 2, 2), 10.0)
        >>> pred = torch.tensor([[[[10.0, 12.0], [12.0, 99.0]]]])
        >>> out = rings(pred, gt, theta=theta)
        >>> out["ring_0-45/rmse"].item(), out["ring_45-95/rmse"].item()
        (0.0, 2.0)
    """

    is_differentiable = False
    full_state_update = False

    def __init__(
        self,
        metric_factory: Callable[[], Metric],
        edges: Sequence[float] | None = None,
        key: Literal["theta", "depth"] = "theta",
    ) -> None:
        super().__init__()
        if key not in _PREFIX:
            raise ValueError(f"`key` must be 'theta' or 'depth', got {key!r}")
        if edges is None:
            edges = DEFAULT_RING_EDGES_DEG if key == "theta" else DEFAULT_DEPTH_EDGES_M
        edges = tuple(float(e) for e in edges)
        if len(edges) < 2 or any(not lo < hi for lo, hi in itertools.pairwise(edges)):
            raise ValueError(f"`edges` must be at least two strictly increasing numbers, got {edges}")
        if not all(torch.isfinite(torch.tensor(edges))):
            raise ValueError(f"`edges` must be finite, got {edges}")
        children = [metric_factory() for _ in range(len(edges) - 1)]
        if not all(isinstance(m, Metric) for m in children):
            raise ValueError("`metric_factory` must return torchmetrics.Metric instances")
        if len({id(m) for m in children}) != len(children):
            raise ValueError("`metric_factory` must return a new metric on every call")
        self.key = key
        self.edges = edges
        self.include_lowest = key == "theta"
        # Children that compute per-image values with equal settings can be evaluated for all bins at once.
        first = children[0]
        self._grouped = isinstance(first, PerImageAverage) and all(
            type(c) is type(first) and c.settings() == first.settings() for c in children
        )
        self.bin_names = [
            f"{_PREFIX[key]}_{_edge_label(lo)}-{_edge_label(hi)}" for lo, hi in itertools.pairwise(edges)
        ]
        self.bins = nn.ModuleList(children)

    def _bin_index_map(self, target: Tensor, theta: Tensor | None, depth: Tensor | None) -> Tensor:
        """Per-pixel bin index ``[H, W]`` or ``[B, H, W]`` for the current batch."""
        if self.key == "theta":
            if theta is None:
                raise ValueError(
                    "BinnedMetrics(key='theta') needs `theta`: incidence angle in degrees, [H, W] or [B, H, W]"
                )
            values = theta
        elif depth is not None:
            values = depth
        elif target.is_floating_point():
            values = target
        else:
            raise ValueError(
                "BinnedMetrics(key='depth') with label targets needs `depth`, the ground-truth range map"
            )
        if not isinstance(values, Tensor):
            raise ValueError(f"`{self.key}` must be a torch.Tensor, got {type(values).__name__}")
        if values.ndim == 4 and values.shape[1] == 1:
            values = values[:, 0]
        if values.ndim not in (2, 3) or values.shape[-2:] != target.shape[-2:]:
            raise ValueError(
                f"`{self.key}` must be [H, W] or [B, H, W] matching target {tuple(target.shape)}, got {tuple(values.shape)}"
            )
        return bin_index(values.to(target.device), self.edges, self.include_lowest)

    def _masked_bin_index(
        self, target: Tensor, theta: Tensor | None, depth: Tensor | None, mask: Tensor | None
    ) -> Tensor:
        """Bin of every pixel (``[H, W]`` or ``[B, H, W]``), -1 where ``mask`` is False or outside every bin."""
        index = self._bin_index_map(target, theta, depth)
        batch_shape = torch.Size((target.shape[0], *target.shape[-2:]))  # [B, H, W] of labels or depth
        mask = _check_mask(mask, batch_shape, index.device)
        return index if mask is None else torch.where(mask, index, -1)

    def _child_masks(self, target: Tensor, theta: Tensor | None, depth: Tensor | None, mask: Tensor | None):
        index = self._masked_bin_index(target, theta, depth, mask)
        return [index == i for i in range(len(self.bins))]

    def update(
        self,
        preds: Tensor,
        target: Tensor,
        theta: Tensor | None = None,
        depth: Tensor | None = None,
        mask: Tensor | None = None,
    ) -> None:
        """Update every bin's child with the pixels of its bin.

        Args:
            preds: As the child metric's ``update``.
            target: As the child metric's ``update``.
            theta: Incidence angle in degrees, ``[H, W]`` (one camera for the batch) or ``[B, H, W]``;
                required for ``key="theta"``, ignored otherwise.
            depth: Ground-truth range for ``key="depth"``; defaults to ``target`` (required when ``target``
                holds labels). Ignored for ``key="theta"``.
            mask: Optional bool mask further restricting every bin.
        """
        if self._grouped:
            # Per-image depth metrics of every bin from one pass over the pixels, not one full pass per bin.
            index = self._masked_bin_index(target, theta, depth, mask)
            index = index.expand(target.shape[0], *target.shape[-2:])
            errors, num_valid = self.bins[0]._errors(
                preds, target, None, groups=index, num_groups=len(self.bins)
            )
            for k, child in enumerate(self.bins):
                child._accumulate({key: value[:, k] for key, value in errors.items()}, num_valid[:, k])
                record_update(child)
            return
        for child, bin_mask in zip(self.bins, self._child_masks(target, theta, depth, mask), strict=True):
            child.update(preds, target, mask=bin_mask)

    def forward(
        self,
        preds: Tensor,
        target: Tensor,
        theta: Tensor | None = None,
        depth: Tensor | None = None,
        mask: Tensor | None = None,
    ) -> dict[str, Tensor]:
        """Update every child and return the values of this batch alone (keys as :meth:`compute`)."""
        masks = self._child_masks(target, theta, depth, mask)
        return self._merge([child(preds, target, mask=m) for child, m in zip(self.bins, masks, strict=True)])

    def compute(self) -> dict[str, Tensor]:
        """``{"<prefix>_<lo>-<hi>/<key>": value}`` for every bin and every key of the child metric."""
        return self._merge([child.compute() for child in self.bins])

    def _merge(self, outputs: list[Any]) -> dict[str, Tensor]:
        merged: dict[str, Tensor] = {}
        for name, out in zip(self.bin_names, outputs, strict=True):
            if isinstance(out, dict):
                merged.update({f"{name}/{k}": v for k, v in out.items()})
            else:
                merged[name] = out
        return merged

    def reset(self) -> None:
        """Reset every child."""
        for child in self.bins:
            child.reset()
        super().reset()
