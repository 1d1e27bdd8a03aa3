"""Score a predictor on a split: one loop for checkpoints, ONNX models and prediction folders.

The ground truth is served by the same :class:`~datamodules.AirFisheyeDataset` as in training (the split's
evaluation form: no augmentation), the predictions come from a :mod:`~airfisheye_bench.evaluation.predictors`
object, and a :class:`~airfisheye_bench.metrics.scorer.TaskScorer` accumulates the metrics and their breakdown.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset
from torchmetrics import Metric

from airfisheye_bench.evaluation.predictors import FilePredictor, Predictor
from airfisheye_bench.metrics._torchmetrics_compat import record_update, state_names, sums_every_state
from airfisheye_bench.metrics.scorer import TaskScorer
from airfisheye_bench.specs import get_task
from airfisheye_bench.viz import panel_row, spread_indices
from datamodules.dataset import collate

__all__ = ["EvaluationResult", "evaluate_predictions"]


@dataclass
class EvaluationResult:
    """Metrics of one evaluation, its per-ring / per-range breakdown and qualitative panels.

    Attributes:
        metrics: ``{key: value}`` of the task metric.
        breakdown: ``{"ring_0-30/rmse": value, "range_0-10/rmse": value, ...}``.
        num_frames: Frames scored.
        seconds: Wall time of the loop (loading, predicting, scoring).
        panels: ``(sample_id, tiles)`` of frames spread over the split: image | (sparse) | ground truth |
            prediction | error (:func:`~airfisheye_bench.viz.panel_titles`).
        groups: ``{group: {key: value}}``: the task metric over each group's frames alone (``group_of``; e.g. per
            flight, the unit of a study's intervals), empty without.
    """

    metrics: dict[str, float]
    breakdown: dict[str, float]
    num_frames: int
    seconds: float
    panels: list[tuple[str, list[np.ndarray]]] = field(default_factory=list)
    groups: dict[str, dict[str, float]] = field(default_factory=dict)


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
    group_of: Callable[[str], str] | None = None,
    group_metric: Callable[[], Metric] | None = None,
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
        num_panels: Frames drawn as qualitative panels, spread evenly over the split
            (:func:`~airfisheye_bench.viz.spread_indices`; the first ones when the dataset lists no ``sample_ids``).
        palette: Class colours (panels of tasks that predict labels).
        max_depth: Far end of the depth colour maps.
        on_batch: Called with ``(batch, prediction)`` after scoring each batch (e.g. to save predictions).
        group_of: The group of a sample id (e.g. :func:`~airfisheye_bench.studies.clustered.flight_of`): each
            group's frames are also scored alone by a fresh ``group_metric()`` (``EvaluationResult.groups``).
        group_metric: The task metric's factory, with ``group_of``.

    Returns:
        An :class:`EvaluationResult`.
    """
    scorer.reset()
    target_key = get_task(predictor.task).target
    ids = getattr(dataset, "sample_ids", None)
    panel_ids = None if ids is None else {ids[i] for i in spread_indices(len(ids), num_panels)}
    collate_fn: Callable[[list], dict] = collate
    if isinstance(predictor, FilePredictor):
        dataset = predictor.wrap(dataset)
        if num_workers > 0 and _can_score_in_workers(scorer, theta_deg):
            # The predictions are decoded in the workers: score them there too, in parallel, and merge the
            # per-batch metric states (all sums) here. The main process would otherwise score every frame alone.
            collate_fn = _ScoringCollate(predictor.task, scorer, theta_deg)
    loader = DataLoader(
        dataset, batch_size=batch_size, shuffle=False, num_workers=num_workers, collate_fn=collate_fn
    )
    if (group_of is None) != (group_metric is None):
        raise ValueError("group_of and group_metric go together")
    metrics = _stateful_metrics(scorer)
    groups: dict[str, Metric] = {}
    panels: list[tuple[str, list[np.ndarray]]] = []
    frames = 0
    start = time.perf_counter()
    with _main_process_threads(num_workers):
        for batch in loader:
            if "image" not in batch:  # every frame skipped (skip_bad_frames)
                continue
            states = batch.pop(_STATES, None)
            prediction = predictor(batch)
            target = batch[target_key]
            _check_shape(prediction, target)
            if states is None:
                scorer.update(prediction, target, theta=theta_deg, mask=batch["valid_mask"])
            else:
                _merge_states(metrics, states)
            frames += target.shape[0]
            if group_of is not None:
                _update_groups(groups, group_of, group_metric, batch, prediction, target)
            for i, sample_id in enumerate(batch["sample_id"]):
                if len(panels) < num_panels and (panel_ids is None or sample_id in panel_ids):
                    tiles = panel_row(
                        predictor.task, batch, prediction, i, palette=palette, max_depth=max_depth
                    )
                    panels.append((sample_id, tiles))
            if on_batch is not None:
                on_batch(batch, prediction)
    seconds = time.perf_counter() - start
    if frames == 0:
        raise ValueError("no frame was evaluated (empty split, or every frame skipped)")
    scores = scorer.compute()
    by_group = {
        name: {k: float(v) for k, v in metric.compute().items()} for name, metric in sorted(groups.items())
    }
    return EvaluationResult(scores["metrics"], scores["breakdown"], frames, seconds, panels, by_group)


def _update_groups(
    groups: dict[str, Metric],
    group_of: Callable[[str], str],
    factory: Callable[[], Metric],
    batch: dict,
    prediction: torch.Tensor,
    target: torch.Tensor,
) -> None:
    """Add each frame of a batch to its group's metric (the frames of one group together)."""
    names = [group_of(sample_id) for sample_id in batch["sample_id"]]
    for name in dict.fromkeys(names):
        rows = torch.tensor([i for i, n in enumerate(names) if n == name])
        metric = groups.get(name)
        if metric is None:
            metric = groups[name] = factory()
        metric.update(prediction[rows], target[rows], mask=batch["valid_mask"][rows])


#: Batch key of the metric states a loader worker scored (see :class:`_ScoringCollate`).
_STATES = "_metric_states"


def _check_shape(prediction: torch.Tensor, target: torch.Tensor) -> None:
    expected = tuple(target.shape[-2:])
    if tuple(prediction.shape[-2:]) != expected or prediction.shape[0] != target.shape[0]:
        raise ValueError(
            f"prediction of shape {tuple(prediction.shape)} does not match the ground truth {tuple(target.shape)}"
        )


def _stateful_metrics(scorer: TaskScorer) -> list[Metric]:
    """The scorer's metrics that hold states (the task metric and every bin's child), in a fixed order."""
    return [m for m in scorer.modules() if isinstance(m, Metric) and state_names(m)]


def _can_score_in_workers(scorer: TaskScorer, theta_deg: torch.Tensor) -> bool:
    """Whether the workers can score: CPU states that merge by summing, and a scorer a worker can receive."""
    metrics = _stateful_metrics(scorer)
    if not metrics or theta_deg.device.type != "cpu":
        return False
    for metric in metrics:
        if metric.full_state_update is not False or metric.dist_sync_on_step:
            return False
        if not sums_every_state(metric):
            return False
        if any(
            not isinstance(v, torch.Tensor) or v.device.type != "cpu" for v in metric.metric_state.values()
        ):
            return False
    try:  # a spawned worker receives a pickled copy
        pickle.dumps(scorer)
    except Exception:  # any pickling failure: score in the main process
        return False
    return True


def _merge_states(metrics: list[Metric], states: list[dict[str, torch.Tensor]]) -> None:
    for metric, state in zip(metrics, states, strict=True):
        metric.merge_state(state)
        record_update(metric)


class _ScoringCollate:
    """``collate_fn`` of a file-prediction loader: collates a batch and scores it in the worker.

    The worker's copy of the scorer is reset for every batch, so the batch carries the states of this batch
    alone (``batch[_STATES]``, one dict per stateful metric), which the main process adds up.
    """

    def __init__(self, task: str, scorer: TaskScorer, theta_deg: torch.Tensor) -> None:
        self.task, self.scorer, self.theta_deg = task, scorer, theta_deg

    def __call__(self, samples: list[dict | None]) -> dict:
        batch = collate(samples)
        if "image" not in batch:
            return batch
        prediction = batch["prediction"]
        target = batch[get_task(self.task).target]
        _check_shape(prediction, target)
        self.scorer.reset()
        self.scorer.update(prediction, target, theta=self.theta_deg, mask=batch["valid_mask"])
        batch[_STATES] = [
            {k: v.clone() for k, v in m.metric_state.items()} for m in _stateful_metrics(self.scorer)
        ]
        return batch


@contextlib.contextmanager
def _main_process_threads(num_workers: int) -> Iterator[None]:
    """Leave the loader workers their cores: intra-op threads of the main process beyond the remaining cores
    spin against the workers (on 2 cores with 2 workers, 2 threads made the metric updates ~6x slower)."""
    previous = torch.get_num_threads()
    if num_workers > 0:
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
        torch.set_num_threads(max(1, min(previous, cores - num_workers)))
    try:
        yield
    finally:
        torch.set_num_threads(previous)
