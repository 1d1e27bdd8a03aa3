"""Monocular depth (paper IV-B): the loss its config chooses (AdaBins: SILog + bin Chamfer), Eigen metrics up to
120 m."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from airfisheye_bench.tasks.base import BenchmarkTask


class DepthTask(BenchmarkTask):
    """Monocular depth with any zoo ``depth`` model (AdaBins by default).

    Args:
        model: ``{"name": "adabins", ...}``.
        min_depth: Evaluation lower bound (paper convention 1e-3 m), and the default loss's.
        max_depth: Evaluation upper bound (paper: 120 m), and the default loss's.
        loss: See :class:`BenchmarkTask`; the depth config picks ``loss=adabins`` (``configs/loss/``):
            :class:`~models.losses.AdaBinsLoss` with its Chamfer term, the one reader of the model's bins, off;
            ``loss=silog`` is the plain :class:`~models.losses.SILogLoss`. Default: :meth:`default_loss`.
        **kwargs: See :class:`BenchmarkTask`; the deprecated ``w_chamfer`` and ``chamfer_reference_range`` set
            the default loss's (``loss.w_chamfer``, ``loss.chamfer_reference_range``).
    """

    task = "depth"
    legacy_loss_args = ("w_chamfer", "chamfer_reference_range")

    def __init__(
        self, model: dict[str, Any], min_depth: float = 1e-3, max_depth: float = 120.0, **kwargs: Any
    ) -> None:
        self.min_depth, self.max_depth = float(min_depth), float(max_depth)
        super().__init__(model, **kwargs)

    @classmethod
    def default_loss(cls, hparams: Mapping[str, Any]) -> dict[str, Any]:
        """AdaBins' loss with Chamfer weight 0.1 (upstream's), bounded by the task's depth range."""
        return {
            "_target_": "models.losses.AdaBinsLoss",
            "w_chamfer": hparams.get("w_chamfer", 0.1),
            "min_depth": hparams["min_depth"],
            "max_depth": hparams["max_depth"],
            "chamfer_reference_range": hparams.get("chamfer_reference_range"),
        }

    def metric_options(self) -> dict[str, Any]:
        return {"min_depth": self.min_depth, "max_depth": self.max_depth}
