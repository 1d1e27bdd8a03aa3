"""Score a predictor on a split: one loop for checkpoints, ONNX models and prediction folders.

The ground truth is served by the same :class:`~datamodules.AirFisheyeDataset` as in training (the split's
evaluation form: no augmentation), the predictions come from a :mod:`~airfisheye_bench.evaluation.predictors`
object, and a :class:`~airfisheye_bench.evaluation.scorer.TaskScorer` accumulates the metrics and their breakdown.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset

from airfisheye_bench.evaluation.predictors import FilePredictor, Predictor
from airfisheye_bench.evaluation.scorer import TaskScorer
from airfisheye_bench.viz import panel_row

__all__ = ["EvaluationResult", "evaluate_predictions", "format_results_table"]


@dataclass
class EvaluationResult:
    """Metrics of one evaluation, its per-ring / per-range breakdown and qualitative panels.

    Attributes:
        metrics: ``{key: value}`` of the task metric.
        breakdown: ``{"ring_0-30/rmse": value, "range_0-10/rmse": value, ...}``.
        num_frames: Frames scored.
        seconds: Wall time of the loop (loading, predicting, scoring).
        panels: ``(sample_id, tiles)`` of the first frames: image | (sparse) | ground truth | prediction | error.
    """

    metrics: dict[str, float]
    breakdown: dict[str, float]
    num_frames: int
    seconds: float
    panels: list[tuple[str, list[np.ndarray]]] = field(default_factory=list)


def evaluate_predictions(
    predictor: Predictor,
    dataset: Dataset,
    scorer: TaskScorer,
    theta_deg: torch.Tensor,
    batch_size: int = 8,
    num_workers: int = 0,
    num_panels: int = 4,
    palette: np.ndarray | None = None,
    max_depth: float = 120.0,
    on_batch: Callable[[dict, torch.Tensor], None] | None = None,
) -> EvaluationResult:
    """Run ``predictor`` over every frame of ``dataset`` and score it.

    Args:
        predictor: Checkpoint, ONNX or file predictor (a :class:`FilePredictor` decodes its files in the workers).
        dataset: The split's evaluation dataset (samples with ``sample_id``, ``image``, ``valid_mask`` and the
            task's ground truth).
        scorer: Fresh scorer of the task.
        theta_deg: Incidence angle of every served pixel in degrees ``[H, W]``.
        batch_size: Frames per batch.
        num_workers: DataLoader workers.
        num_panels: Frames drawn as qualitative panels (the first ones of the split).
        palette: Class colours (seg panels).
        max_depth: Far end of the depth colour maps.
        on_batch: Called with ``(batch, prediction)`` after scoring each batch (e.g. to save predictions).

    Returns:
        An :class:`EvaluationResult`.
    """
    from datamodules.dataset import collate

    if isinstance(predictor, FilePredictor):
        dataset = predictor.wrap(dataset)
    loader = DataLoader(
        dataset, batch_size=batch_size, shuffle=False, num_workers=num_workers, collate_fn=collate
    )
    scorer.reset()
    panels: list[tuple[str, list[np.ndarray]]] = []
    frames = 0
    start = time.perf_counter()
    for batch in loader:
        if "image" not in batch:  # every frame skipped (skip_bad_frames)
            continue
        prediction = predictor(batch)
        target = batch["label"] if predictor.task == "seg" else batch["depth"]
        expected = tuple(target.shape[-2:])
        if tuple(prediction.shape[-2:]) != expected or prediction.shape[0] != target.shape[0]:
            raise ValueError(
                f"prediction of shape {tuple(prediction.shape)} does not match the ground truth {tuple(target.shape)}"
            )
        scorer.update(prediction, target, theta=theta_deg, mask=batch["valid_mask"])
        frames += target.shape[0]
        for i in range(min(target.shape[0], num_panels - len(panels))):
            tiles = panel_row(predictor.task, batch, prediction, i, palette=palette, max_depth=max_depth)
            panels.append((batch["sample_id"][i], tiles))
        if on_batch is not None:
            on_batch(batch, prediction)
    seconds = time.perf_counter() - start
    if frames == 0:
        raise ValueError("no frame was evaluated (empty split, or every frame skipped)")
    scores = scorer.compute()
    return EvaluationResult(scores["metrics"], scores["breakdown"], frames, seconds, panels)


def format_results_table(task: str, result: EvaluationResult | dict[str, Any], primary: str) -> str:
    """A plain-text table of the metrics and of the primary metric per ring and range (for the terminal)."""
    metrics = result.metrics if isinstance(result, EvaluationResult) else result["metrics"]
    breakdown = result.breakdown if isinstance(result, EvaluationResult) else result["breakdown"]
    lines = [f"{task} metrics", "-" * 36]
    lines += [f"{key:<28}{_fmt(value)}" for key, value in metrics.items() if not key.startswith("IoU/")]
    per_class = {k[4:]: v for k, v in metrics.items() if k.startswith("IoU/")}
    if per_class:
        lines += ["", "IoU per class", "-" * 36]
        lines += [f"{name:<28}{_fmt(value)}" for name, value in per_class.items()]
    bins = {k.split("/")[0]: v for k, v in breakdown.items() if k.endswith(f"/{primary}")}
    if bins:
        lines += ["", f"{primary} by incidence-angle ring (deg) and depth range (m)", "-" * 36]
        lines += [f"{name:<28}{_fmt(value)}" for name, value in bins.items()]
    return "\n".join(lines)


def _fmt(value: float | None) -> str:
    if value is None or value != value:
        return "-"
    return f"{value:.4f}"
