"""Depth completion (paper IV-C): image + occlusion-corrected sparse LiDAR depth, the loss its config chooses
(NLSPN: L1 + L2), NLSPN metrics."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from airfisheye_bench.metrics.functional import COMPLETION_VALID_MIN
from airfisheye_bench.tasks.base import BenchmarkTask


class CompletionTask(BenchmarkTask):
    """Depth completion with any zoo ``completion`` model (NLSPN by default).

    Args:
        model: ``{"name": "nlspn", ...}``.
        max_depth: Evaluation upper bound (paper: 120 m), and the default loss's clamp.
        loss: See :class:`BenchmarkTask`; the completion config picks ``loss=l1l2``
            (:class:`~models.losses.L1L2Loss`, ``configs/loss/``). Default: :meth:`default_loss`.
        **kwargs: See :class:`BenchmarkTask`; the deprecated ``l1_weight`` and ``l2_weight`` set the default
            loss's (``loss.l1_weight``, ``loss.l2_weight``).
    """

    task = "completion"
    legacy_loss_args = ("l1_weight", "l2_weight")

    def __init__(self, model: dict[str, Any], max_depth: float = 120.0, **kwargs: Any) -> None:
        self.max_depth = float(max_depth)
        super().__init__(model, **kwargs)

    @classmethod
    def default_loss(cls, hparams: Mapping[str, Any]) -> dict[str, Any]:
        """The paper's L1 + L2, clamped to the task's ``max_depth``."""
        return {
            "_target_": "models.losses.L1L2Loss",
            "max_depth": hparams["max_depth"],
            "l1_weight": hparams.get("l1_weight", 1.0),
            "l2_weight": hparams.get("l2_weight", 1.0),
        }

    def metric_options(self) -> dict[str, Any]:
        # NLSPN's metric has its own lower bound (COMPLETION_VALID_MIN); stated here for the ONNX metadata.
        return {"min_depth": COMPLETION_VALID_MIN, "max_depth": self.max_depth}
