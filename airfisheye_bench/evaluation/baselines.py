"""Trivial baselines that a trained model has to beat: the training split's per-pixel mean depth, its majority class.

They are :class:`~airfisheye_bench.evaluation.predictors.Predictor` objects, so they are scored by the same
:func:`~airfisheye_bench.evaluation.evaluate_predictions` loop and metric as a checkpoint. Both ignore their input:
a depth model that does not beat the mean depth of each pixel (a fisheye on a drone sees the ground below and the
horizon at the rim, so the mean depth map is already informative) has learnt nothing from the image.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import torch
from torch import Tensor
from torch.utils.data import DataLoader, Dataset

from airfisheye_bench.specs import get_task
from datamodules.dataset import collate

__all__ = ["BASELINES", "MajorityClassPredictor", "MeanDepthPredictor", "fit_baseline"]


class MeanDepthPredictor:
    """Predicts, for every frame, the per-pixel mean of the training split's valid ground-truth depth.

    Args:
        task: ``depth`` or ``completion`` (the target is the dense depth ``[B, 1, H, W]``).
        mean_depth: ``[1, H, W]`` in metres.

    Example:
        >>> frames = [{"depth": torch.tensor([[[2.0, 0.0]]])}, {"depth": torch.tensor([[[4.0, 0.0]]])}]
        >>> predictor = MeanDepthPredictor.fit("depth", frames)
        >>> predictor.mean_depth  # the pixel never valid gets the mean of every valid pixel
        tensor([[[3., 3.]]])
        >>> predictor({"image": torch.zeros(5, 3, 1, 2)}).shape
        torch.Size([5, 1, 1, 2])
    """

    name = "training-set mean depth per pixel"

    def __init__(self, task: str, mean_depth: Tensor) -> None:
        if get_task(task).target != "depth":
            raise ValueError(f"MeanDepthPredictor predicts a depth target; task {task!r} has none")
        self.task = task
        self.mean_depth = mean_depth

    @classmethod
    def fit(
        cls, task: str, dataset: Dataset, max_depth: float = 120.0, batch_size: int = 16, num_workers: int = 0
    ) -> MeanDepthPredictor:
        """Average every pixel's valid depth (``0 < d <= max_depth``) over ``dataset`` (the training split)."""
        total = count = None
        for batch in _batches(dataset, batch_size, num_workers):
            depth = batch["depth"].double()
            valid = (depth > 0) & (depth <= max_depth)
            if "valid_mask" in batch:
                valid &= batch["valid_mask"].unsqueeze(1)
            s, n = (depth * valid).sum(0), valid.sum(0).double()
            total, count = (s, n) if total is None else (total + s, count + n)
        if total is None or not count.sum() > 0:
            raise ValueError("the training split has no valid depth to average")
        overall = total.sum() / count.sum()
        mean = torch.where(count > 0, total / count.clamp_min(1), overall)
        return cls(task, mean.float())

    def __call__(self, batch: dict) -> Tensor:
        b = batch["image"].shape[0]
        return self.mean_depth.unsqueeze(0).expand(b, -1, -1, -1).clone()

    def identity(self) -> dict[str, Any]:
        return {"source": "baseline", "name": self.name}


class MajorityClassPredictor:
    """Predicts the training split's most frequent class at every pixel (segmentation).

    Args:
        task: ``seg``.
        label: The class index.
        ignore_index: Label value that is not a class (not counted).

    Example:
        >>> frames = [{"label": torch.tensor([[0, 2, 2, 255]])}, {"label": torch.tensor([[1, 2, 255, 255]])}]
        >>> predictor = MajorityClassPredictor.fit("seg", frames)
        >>> predictor.label, predictor({"image": torch.zeros(1, 3, 1, 2)}).tolist()
        (2, [[[2, 2]]])
    """

    name = "training-set majority class"

    def __init__(self, task: str, label: int, ignore_index: int = 255) -> None:
        if not get_task(task).uses_classes:
            raise ValueError(f"MajorityClassPredictor predicts classes; task {task!r} has none")
        self.task, self.label, self.ignore_index = task, int(label), int(ignore_index)

    @classmethod
    def fit(
        cls, task: str, dataset: Dataset, ignore_index: int = 255, batch_size: int = 16, num_workers: int = 0
    ) -> MajorityClassPredictor:
        """Count the labels of ``dataset`` (the training split) inside the image circle."""
        counts = torch.zeros(0, dtype=torch.long)
        for batch in _batches(dataset, batch_size, num_workers):
            labels = batch["label"]
            keep = labels != ignore_index
            if "valid_mask" in batch:
                keep &= batch["valid_mask"]
            found = torch.bincount(labels[keep].long().flatten())
            if found.numel() > counts.numel():
                counts = torch.cat([counts, counts.new_zeros(found.numel() - counts.numel())])
            counts[: found.numel()] += found
        if counts.sum() == 0:
            raise ValueError("the training split has no labelled pixel to count")
        return cls(task, int(counts.argmax()), ignore_index)

    def __call__(self, batch: dict) -> Tensor:
        b, _, h, w = batch["image"].shape
        return torch.full((b, h, w), self.label, dtype=torch.long)

    def identity(self) -> dict[str, Any]:
        return {"source": "baseline", "name": self.name, "label": self.label}


#: The trivial baseline of each task.
BASELINES = {"seg": MajorityClassPredictor, "depth": MeanDepthPredictor, "completion": MeanDepthPredictor}


def fit_baseline(
    task: str, train_dataset: Dataset, **options: Any
) -> MeanDepthPredictor | MajorityClassPredictor:
    """The task's trivial baseline fitted on ``train_dataset`` (pass it without augmentation); ``options`` go to
    its ``fit`` (``max_depth`` or ``ignore_index``, ``batch_size``, ``num_workers``)."""
    try:
        kind = BASELINES[task]
    except KeyError:
        raise ValueError(f"no trivial baseline for task {task!r}; known: {', '.join(BASELINES)}") from None
    return kind.fit(task, train_dataset, **options)


def _batches(dataset: Dataset, batch_size: int, num_workers: int) -> Iterator[dict]:
    loader = DataLoader(
        dataset, batch_size=batch_size, shuffle=False, num_workers=num_workers, collate_fn=collate
    )
    for batch in loader:
        if len(batch) > 1:  # an all-skipped batch holds only num_skipped
            yield batch
