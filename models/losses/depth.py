"""Monocular depth losses: Eigen's scale-invariant log loss and AdaBins' bin-centre Chamfer loss.

A depth model is trained with either, chosen in its config (``task.module.loss``): :class:`AdaBinsLoss` (the SI term
plus the bins' Chamfer term, which alone needs the model's ``"bin_edges"``) or the plain :class:`SILogLoss`.

Both follow the official AdaBins code (``loss.py``, ``train.py``): SILog ``10 * sqrt(mean(g^2) - 0.85 mean(g)^2)``
pooled over the valid pixels of the whole batch, and a Chamfer term between the bin centres and the valid
ground-truth depths, weighted 0.1. The Chamfer loss is computed here without pytorch3d: in 1-D the nearest
neighbour is found by sorting and ``searchsorted``, so memory is O(pixels), not O(bins x pixels).
"""

from __future__ import annotations

from collections.abc import Mapping

import torch
import torch.nn.functional as F
from torch import Tensor, nn


def _as_b1hw(t: Tensor, name: str) -> Tensor:
    if t.ndim == 3:
        t = t.unsqueeze(1)
    if t.ndim != 4 or t.shape[1] != 1:
        raise ValueError(f"{name} must have shape [B, 1, H, W] or [B, H, W], got {list(t.shape)}")
    return t


def valid_depth_mask(target: Tensor, min_depth: float = 1e-3, max_depth: float | None = 120.0) -> Tensor:
    """``min_depth < target <= max_depth`` (0 = no ground truth, e.g. sky).

    Example:
        >>> valid_depth_mask(torch.tensor([0.0, 0.5, 130.0]))
        tensor([False,  True, False])
    """
    mask = target > min_depth
    if max_depth is not None:
        mask &= target <= max_depth
    return mask


class SILogLoss(nn.Module):
    """Scale-invariant log loss (Eigen et al. 2014) as trained in AdaBins.

    ``g = log(pred) - log(gt)`` over the valid pixels of the batch (pooled, as the official code);
    loss ``= scale * sqrt(mean(g^2) - lambd * mean(g)^2)``. With ``lambd = 0.85`` this is the official
    ``10 * sqrt(var(g) + 0.15 * mean(g)^2)`` (up to torch.var's N/(N-1) factor). A prediction at another
    resolution is resized to the target (bilinear, ``align_corners=True``, as the official loss).

    Args:
        lambd: weight of the scale term (0.85; 1 makes the loss fully scale-invariant).
        scale: output multiplier (10).
        min_depth: targets ``<= min_depth`` are invalid; predictions are clamped to it before the log.
        max_depth: targets above it are invalid (``None``: no upper bound).

    Example:
        >>> loss = SILogLoss()
        >>> gt = torch.rand(2, 1, 8, 8) * 50 + 1
        >>> round(float(loss(gt, gt)), 4)
        0.0
        >>> round(float(SILogLoss(lambd=1.0)(3 * gt, gt)), 4)  # fully scale-invariant
        0.0
    """

    def __init__(
        self,
        lambd: float = 0.85,
        scale: float = 10.0,
        min_depth: float = 1e-3,
        max_depth: float | None = 120.0,
    ) -> None:
        super().__init__()
        if not 0.0 <= lambd <= 1.0:
            raise ValueError(f"lambd must be in [0, 1], got {lambd}")
        self.lambd, self.scale, self.min_depth, self.max_depth = lambd, scale, min_depth, max_depth

    def forward(self, pred: Tensor, target: Tensor, mask: Tensor | None = None) -> Tensor:
        """Loss for ``pred`` and ``target`` ``[B, 1, H, W]`` (or ``[B, H, W]``); ``mask`` further restricts the
        valid pixels. Returns 0 (with a graph) when no pixel is valid."""
        pred, target = _as_b1hw(pred, "pred"), _as_b1hw(target, "target")
        if pred.shape[0] != target.shape[0]:
            raise ValueError(f"pred and target batch sizes differ: {pred.shape[0]} vs {target.shape[0]}")
        if pred.shape[-2:] != target.shape[-2:]:
            pred = F.interpolate(pred, size=target.shape[-2:], mode="bilinear", align_corners=True)
        valid = valid_depth_mask(target, self.min_depth, self.max_depth)
        if mask is not None:
            valid &= _as_b1hw(mask, "mask").bool()
        if not valid.any():
            return pred.sum() * 0.0
        g = torch.log(pred[valid].clamp_min(self.min_depth)) - torch.log(target[valid])
        # mean(g^2) - lambd mean(g)^2, written as variance + (1 - lambd) mean^2: the same value without the
        # cancellation of two large terms (which costs ~1e-3 in float32 when g is nearly constant).
        mean = g.mean()
        d = ((g - mean) ** 2).mean() + (1.0 - self.lambd) * mean**2
        # clamp: round-off can make d slightly negative; 1e-12 also keeps sqrt's gradient finite at d = 0.
        return self.scale * torch.sqrt(d.clamp_min(1e-12))


class BinsChamferLoss(nn.Module):
    """Chamfer distance between each image's bin centres and its valid ground-truth depths.

    Same value as pytorch3d's ``chamfer_distance`` on 1-D points with its defaults, as used by AdaBins:
    squared distances, ``mean_c min_y (c - y)^2 + mean_y min_c (y - c)^2`` per image (``y`` over the valid pixels
    only), averaged over the images that have a valid pixel.

    The distances are in metres, so the term grows with the square of the depth range while its weight (AdaBins'
    0.1) was set on NYU (10 m) and KITTI (80 m). ``reference_range`` measures them instead in fractions of the bins'
    range (``max_depth``) times that reference, so a weight means at any range what it means at the reference:
    the term is multiplied by ``(reference_range / max_depth)^2``.

    Args:
        min_depth: targets ``<= min_depth`` are invalid (the official code keeps ``gt >= 1e-3``).
        max_depth: targets above it are invalid (``None``: no upper bound).
        reference_range: the depth range (m) the term is normalised to (``None``: metres, as upstream; needs
            ``max_depth``).

    Example:
        >>> edges = torch.tensor([[0.0, 2.0, 4.0]])  # centres 1 and 3
        >>> gt = torch.tensor([[[[1.0, 3.0], [0.0, 0.0]]]])  # 0 = invalid
        >>> float(BinsChamferLoss()(edges, gt))
        0.0
        >>> gt = torch.tensor([[[[2.0, 3.0]]]])  # centre 1 is 1 m from the nearest depth, depth 2 1 m from a centre
        >>> float(BinsChamferLoss()(edges, gt)), float(BinsChamferLoss(max_depth=20.0, reference_range=10.0)(edges, gt))
        (1.0, 0.25)
    """

    def __init__(
        self, min_depth: float = 1e-3, max_depth: float | None = 120.0, reference_range: float | None = None
    ) -> None:
        super().__init__()
        if reference_range is not None and (max_depth is None or reference_range <= 0):
            raise ValueError(
                f"reference_range={reference_range} needs a positive value and a max_depth (got {max_depth})"
            )
        self.min_depth, self.max_depth = min_depth, max_depth
        self.scale = 1.0 if reference_range is None else (reference_range / max_depth) ** 2

    def forward(self, bin_edges: Tensor, target: Tensor) -> Tensor:
        """``bin_edges`` ``[B, n_bins + 1]``, ``target`` ``[B, 1, H, W]`` or ``[B, H, W]`` (any resolution)."""
        if bin_edges.ndim != 2 or bin_edges.shape[1] < 2:
            raise ValueError(f"bin_edges must have shape [B, n_bins + 1], got {list(bin_edges.shape)}")
        target = _as_b1hw(target, "target")
        if bin_edges.shape[0] != target.shape[0]:
            raise ValueError(
                f"bin_edges and target batch sizes differ: {bin_edges.shape[0]} vs {target.shape[0]}"
            )
        centers = 0.5 * (bin_edges[:, 1:] + bin_edges[:, :-1])  # [B, P]
        points = target.flatten(1).to(centers.dtype)  # [B, T]
        valid = valid_depth_mask(points, self.min_depth, self.max_depth)
        count = valid.sum(dim=1)
        has_points = count > 0
        if not has_points.any():
            return centers.sum() * 0.0

        # centres -> nearest valid depth: sort the depths with the invalid ones pushed to +inf at the end.
        sorted_points = torch.where(valid, points, torch.full_like(points, torch.inf)).sort(dim=1).values
        # Rows without any valid depth are dropped below; keep them finite so no inf reaches the graph.
        sorted_points = torch.where(has_points[:, None], sorted_points, torch.zeros_like(sorted_points))
        to_points = _nearest_sq_dist(centers, sorted_points).mean(dim=1)  # [B]
        # valid depth -> nearest centre (centres are sorted by construction, but sort to accept any order).
        sorted_centers = centers.sort(dim=1).values
        from_points = (_nearest_sq_dist(points, sorted_centers) * valid).sum(dim=1) / count.clamp_min(1)
        per_image = to_points + from_points
        return self.scale * per_image[has_points].mean()


def _nearest_sq_dist(queries: Tensor, sorted_refs: Tensor) -> Tensor:
    """Squared distance from each query ``[B, Q]`` to its nearest value in ``sorted_refs`` ``[B, R]`` (rows
    ascending; trailing ``+inf`` entries allowed as long as each row has one finite value)."""
    idx = torch.searchsorted(sorted_refs.detach().contiguous(), queries.detach().contiguous())
    last = sorted_refs.shape[1] - 1
    below = sorted_refs.gather(1, (idx - 1).clamp(0, last))
    above = sorted_refs.gather(1, idx.clamp(0, last))
    # Pick the nearer neighbour first, then square: squaring an infinite candidate would put 0 * inf = NaN
    # into the backward pass even where it is not selected.
    take_below = (queries - below).abs().detach() <= (queries - above).abs().detach()
    return (queries - torch.where(take_below, below, above)) ** 2


class AdaBinsLoss(nn.Module):
    """AdaBins' training loss: ``SILog(depth, gt) + w_chamfer * BinsChamfer(bin_edges, gt)``.

    Called with the model's whole ``forward_with_aux`` outputs (:attr:`takes_model_outputs`). The bins are read only
    when the Chamfer term counts: at ``w_chamfer=0`` a model without bins (no ``"bin_edges"`` output) trains with
    the SI term alone, logged as the same ``silog`` and ``chamfer`` (0) terms.

    Args:
        w_chamfer: weight of the Chamfer term (0.1; 0 disables it, and the need for ``"bin_edges"``).
        lambd: SILog scale-term weight (0.85).
        min_depth, max_depth: the valid ground-truth range.
        chamfer_reference_range: :class:`BinsChamferLoss`'s ``reference_range`` (None: metres, as upstream).

    Example:
        >>> import models
        >>> net = models.create_model("adabins", encoder_name="resnet18", n_bins=16, decoder_features=64,
        ...     decoder_out_channels=16, patch_size=4, embedding_dim=16, num_heads=2, num_layers=1,
        ...     n_query_channels=16, pos_grid_size=8)
        >>> gt = torch.rand(2, 1, 64, 64) * 100
        >>> terms = AdaBinsLoss().terms(net.forward_with_aux(torch.randn(2, 3, 64, 64)), gt)
        >>> sorted(terms)
        ['chamfer', 'loss', 'silog']
        >>> round(float(AdaBinsLoss(w_chamfer=0.0)({"depth": gt}, gt)), 4)  # no bins without the Chamfer term
        0.0
    """

    #: The task hands the loss the model's ``forward_with_aux`` mapping (``"depth"``, ``"bin_edges"``), not only
    #: the primary output (``BenchmarkTask.loss_terms``).
    takes_model_outputs = True

    def __init__(
        self,
        w_chamfer: float = 0.1,
        lambd: float = 0.85,
        min_depth: float = 1e-3,
        max_depth: float | None = 120.0,
        chamfer_reference_range: float | None = None,
    ) -> None:
        super().__init__()
        self.w_chamfer = w_chamfer
        self.silog = SILogLoss(lambd=lambd, min_depth=min_depth, max_depth=max_depth)
        self.chamfer = BinsChamferLoss(min_depth, max_depth, reference_range=chamfer_reference_range)

    def terms(self, outputs: Mapping[str, Tensor], target: Tensor) -> dict[str, Tensor]:
        """``{"loss", "silog", "chamfer"}`` from ``model.forward_with_aux(...)`` outputs (``"depth"``, and
        ``"bin_edges"`` when ``w_chamfer > 0``) and the ground truth."""
        needed = ("depth", "bin_edges") if self.w_chamfer else ("depth",)
        missing = sorted(set(needed) - set(outputs))
        if missing:
            raise ValueError(
                f"outputs must hold {' and '.join(map(repr, needed))} (forward_with_aux) with "
                f"w_chamfer={self.w_chamfer}, missing {missing}"
                + (
                    "; a model without bins trains with w_chamfer=0 or SILogLoss"
                    if "bin_edges" in missing
                    else ""
                )
            )
        silog = self.silog(outputs["depth"], target)
        chamfer = self.chamfer(outputs["bin_edges"], target) if self.w_chamfer else silog.new_zeros(())
        return {"loss": silog + self.w_chamfer * chamfer, "silog": silog, "chamfer": chamfer}

    def forward(self, outputs: Mapping[str, Tensor], target: Tensor) -> Tensor:
        """The total loss (see :meth:`terms` for the parts)."""
        return self.terms(outputs, target)["loss"]
