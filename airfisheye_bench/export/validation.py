"""The run's validation frames, without augmentation: the parity batch, static calibration, the int8 comparison."""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import torch
from torch import Tensor

__all__ = ["validation_batches", "validation_frames"]


def validation_batches(datamodule, limit: int = 0) -> Iterator[dict]:
    """Validation batches (no augmentation), stopping after ``limit`` frames (0: all)."""
    seen = 0
    for batch in datamodule.val_dataloader():
        # data.remap_on=device: the cube faces become images here (Lightning calls this hook in training)
        batch = datamodule.on_after_batch_transfer(batch, 0)
        if "image" not in batch:  # every frame of the batch was skipped (skip_bad_frames)
            continue
        if limit:
            batch = {k: v[: limit - seen] for k, v in batch.items() if isinstance(v, Tensor | list)}
        yield batch
        seen += int(batch["image"].shape[0])
        if limit and seen >= limit:
            return


def validation_frames(datamodule, count: int, names: Sequence[str]) -> dict[str, Tensor]:
    """The first ``count`` validation frames (fewer if the split is smaller) as one batch."""
    parts: dict[str, list[Tensor]] = {}
    for batch in validation_batches(datamodule, count):
        for key, value in batch.items():
            if isinstance(value, Tensor):
                parts.setdefault(key, []).append(value)
    missing = [n for n in names if n not in parts]
    if missing:
        raise ValueError(f"the validation split gave no {missing} (data.task={datamodule.task})")
    return {k: torch.cat(v) for k, v in parts.items()}
