"""Depth-completion reconstruction loss: L1 + L2 on valid ground-truth pixels (NLSPN, Park et al., ECCV 2020).

Follows the official ``L1Loss`` / ``L2Loss`` (zzangjinsun/NLSPN_ECCV20, ``src/loss/submodule``): prediction and
ground truth are clamped to ``[0, max_depth]``, pixels with ``gt > 1e-4`` (after clamping) are valid, and each
term is the per-sample mean over valid pixels. Upstream then *sums* the per-sample terms over the batch; here
the default ``reduction="mean"`` averages them over the samples that have a valid pixel instead, so the loss
value does not grow with the batch size (or shrink on a short last batch) and logs stay comparable across
batch sizes. With Adam/AdamW (the paper's optimiser) a constant loss scale does not change the updates, so this
does not change training; ``reduction="sum"`` reproduces upstream exactly.
"""

from __future__ import annotations

from torch import Tensor, nn

__all__ = ["L1L2Loss", "NLSPNLoss", "masked_l1_l2"]

_REDUCTIONS = ("mean", "sum", "none")


def masked_l1_l2(
    pred: Tensor, target: Tensor, max_depth: float = 120.0, min_valid: float = 1e-4
) -> tuple[Tensor, Tensor, Tensor]:
    """Per-sample masked L1 and L2 (mean squared) errors, as upstream NLSPN.

    Args:
        pred: predicted depth ``[B, 1, H, W]`` or ``[B, H, W]`` in metres.
        target: ground-truth depth of the same shape; ``<= min_valid`` means no ground truth.
        max_depth: both tensors are clamped to ``[0, max_depth]`` first.
        min_valid: validity threshold on the clamped target.

    Returns:
        ``(l1 [B], l2 [B], has_valid [B] bool)``; samples without a valid pixel get 0 for both terms.

    Example:
        >>> import torch
        >>> pred = torch.tensor([[[1.0, 2.0], [3.0, 200.0]]])
        >>> gt = torch.tensor([[[2.0, 0.0], [1.0, 150.0]]])  # 0 = no ground truth; both clamp to 120
        >>> l1, l2, valid = masked_l1_l2(pred, gt)
        >>> l1.item(), l2.item(), valid.item()
        (1.0, 1.6666666269302368, True)
    """
    if pred.shape != target.shape:
        raise ValueError(
            f"pred and target must have the same shape, got {tuple(pred.shape)} and {tuple(target.shape)}"
        )
    if pred.ndim not in (3, 4) or (pred.ndim == 4 and pred.shape[1] != 1):
        raise ValueError(f"pred must be [B, 1, H, W] or [B, H, W], got {tuple(pred.shape)}")
    if max_depth <= 0:
        raise ValueError(f"max_depth must be > 0, got {max_depth}")
    target = target.clamp(0.0, max_depth)
    pred = pred.clamp(0.0, max_depth)
    mask = (target > min_valid).to(pred.dtype)
    dims = tuple(range(1, pred.ndim))
    num_valid = mask.sum(dim=dims)
    diff = (pred - target) * mask
    # + 1e-8 as upstream: a sample without ground truth contributes 0 (and no NaN) instead of 0/0.
    l1 = diff.abs().sum(dim=dims) / (num_valid + 1e-8)
    l2 = diff.square().sum(dim=dims) / (num_valid + 1e-8)
    return l1, l2, num_valid > 0


class L1L2Loss(nn.Module):
    """``l1_weight * L1 + l2_weight * L2`` on valid pixels (the NLSPN / AirFisheye completion loss).

    Args:
        max_depth: clamp range of prediction and ground truth in metres (AirFisheye: 120).
        l1_weight: weight of the L1 term (upstream ``1.0*L1``).
        l2_weight: weight of the L2 (mean squared error) term (upstream ``1.0*L2``).
        min_valid: ground truth ``<= min_valid`` (after clamping) is ignored (upstream ``t_valid = 1e-4``).
        reduction: ``"mean"`` over samples with a valid pixel (default), ``"sum"`` over the batch (upstream), or
            ``"none"`` (per-sample ``[B]``).

    Example:
        >>> import torch
        >>> loss_fn = L1L2Loss(max_depth=10.0)
        >>> pred = torch.full((2, 1, 4, 4), 3.0, requires_grad=True)
        >>> gt = torch.zeros(2, 1, 4, 4)
        >>> gt[0, 0, 0, 0] = 1.0  # sample 0: one valid pixel, error 2; sample 1: no ground truth
        >>> loss = loss_fn(pred, gt)
        >>> round(loss.item(), 4), loss_fn.terms(pred, gt)["l2"].item()
        (6.0, 4.0)
        >>> loss.backward()
    """

    def __init__(
        self,
        max_depth: float = 120.0,
        l1_weight: float = 1.0,
        l2_weight: float = 1.0,
        min_valid: float = 1e-4,
        reduction: str = "mean",
    ) -> None:
        super().__init__()
        if max_depth <= 0:
            raise ValueError(f"max_depth must be > 0, got {max_depth}")
        if l1_weight < 0 or l2_weight < 0:
            raise ValueError(f"l1_weight and l2_weight must be >= 0, got {l1_weight} and {l2_weight}")
        if reduction not in _REDUCTIONS:
            raise ValueError(f"reduction must be one of {_REDUCTIONS}, got {reduction!r}")
        self.max_depth = float(max_depth)
        self.l1_weight = float(l1_weight)
        self.l2_weight = float(l2_weight)
        self.min_valid = float(min_valid)
        self.reduction = reduction

    def extra_repr(self) -> str:
        return (
            f"max_depth={self.max_depth}, l1_weight={self.l1_weight}, l2_weight={self.l2_weight}, "
            f"reduction={self.reduction!r}"
        )

    def forward(self, pred: Tensor, target: Tensor) -> Tensor:
        """The weighted loss, reduced as configured."""
        return self.terms(pred, target)["loss"]

    def terms(self, pred: Tensor, target: Tensor) -> dict[str, Tensor]:
        """The reduced ``"l1"``, ``"l2"`` and weighted total ``"loss"`` (for logging the parts)."""
        l1, l2, has_valid = masked_l1_l2(pred, target, self.max_depth, self.min_valid)
        if self.reduction == "mean":
            count = has_valid.sum().clamp(min=1).to(l1.dtype)
            l1, l2 = l1.sum() / count, l2.sum() / count
        elif self.reduction == "sum":
            l1, l2 = l1.sum(), l2.sum()
        return {"l1": l1, "l2": l2, "loss": self.l1_weight * l1 + self.l2_weight * l2}


#: The NLSPN name of the same loss (upstream ``--loss 1.0*L1+1.0*L2``).
NLSPNLoss = L1L2Loss
