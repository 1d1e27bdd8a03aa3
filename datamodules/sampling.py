"""Epoch-seeded randomness, so a run gives the same batches whatever the worker count, restarts or DDP.

Shuffling and per-sample augmentation draws are functions of ``(seed, epoch, index)`` only: a run resumed from a
checkpoint replays exactly the epochs an uninterrupted run would have seen, and ``num_workers`` changes nothing.
The datamodule saves :func:`training_position` in every checkpoint and restarts the sampler there.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import lightning as L
import torch
import torch.distributed as dist
from torch.utils.data import DataLoader, DistributedSampler, Sampler


def draw_seed(seed: int, epoch: int, index: int) -> int:
    """A 63-bit seed for one sample's random draws in one epoch."""
    x = (seed * 0x9E3779B97F4A7C15 + epoch * 0xBF58476D1CE4E5B9 + index * 0x94D049BB133111EB) & (2**64 - 1)
    x ^= x >> 31
    x = (x * 0xD6E8FEB86659FD93) & (2**64 - 1)
    return (x ^ (x >> 32)) & (2**63 - 1)


class EpochSeededSampler(DistributedSampler):
    """Random permutation seeded by ``(seed, epoch)``, sharded across DDP ranks, resumable mid-epoch.

    Lightning calls :meth:`set_epoch` every epoch. Under DDP every rank draws the same permutation, pads it with
    its first indices to a multiple of the world size (as torch's ``DistributedSampler`` does, so all ranks run
    the same number of steps) and keeps every ``world_size``-th index. Being a ``DistributedSampler``, Lightning
    keeps it instead of wrapping it in its own. ``start`` skips the first indices of this rank's shard once: a run
    resumed mid-epoch continues with exactly the samples the uninterrupted run would have drawn next.

    Example:
        >>> s = EpochSeededSampler(6, seed=0, num_replicas=1, rank=0)
        >>> full = list(s)
        >>> s.start = 4
        >>> list(s) == full[4:], list(s) == full
        (True, True)
        >>> shards = [list(EpochSeededSampler(5, 0, num_replicas=2, rank=r)) for r in (0, 1)]
        >>> [len(x) for x in shards], sorted(set(shards[0] + shards[1])) == list(range(5))
        ([3, 3], True)
    """

    def __init__(
        self, num_samples: int, seed: int = 0, num_replicas: int | None = None, rank: int | None = None
    ) -> None:
        if num_replicas is None or rank is None:
            distributed = dist.is_available() and dist.is_initialized()
            num_replicas = dist.get_world_size() if distributed else 1
            rank = dist.get_rank() if distributed else 0
        super().__init__(
            range(int(num_samples)), num_replicas=num_replicas, rank=rank, shuffle=True, seed=seed
        )
        self.seed = int(seed)
        #: Indices of this rank's shard to skip at the next iteration only (mid-epoch resume).
        self.start = 0

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)

    def epoch_order(self) -> list[int]:
        """The epoch's order of the ``len(dataset)`` draws, the same on every rank (a subclass may draw otherwise)."""
        generator = torch.Generator().manual_seed(draw_seed(self.seed, self.epoch, -1))
        return torch.randperm(len(self.dataset), generator=generator).tolist()

    def __iter__(self) -> Iterator[int]:
        order = self.epoch_order()
        if order:  # pad (repeating the start) so every rank gets num_samples indices
            order = (order * math.ceil(self.total_size / len(order)))[: self.total_size]
        start, self.start = self.start, 0
        return iter(order[self.rank : self.total_size : self.num_replicas][start:])

    def __len__(self) -> int:
        return self.num_samples


def batches_per_rank(num_frames: int, batch_size: int, world_size: int) -> int:
    """Training batches each of ``world_size`` ranks gets from ``num_frames`` frames (incomplete batches dropped).

    Example:
        >>> batches_per_rank(8, 2, 1), batches_per_rank(8, 2, 3), batches_per_rank(8, 4, 3)
        (4, 1, 0)
    """
    return math.ceil(num_frames / world_size) // batch_size


def training_position(trainer: L.Trainer) -> tuple[int, int]:
    """``(epoch, batches of it already trained)`` a run resumed from a checkpoint saved now must continue at.

    Read from the fit loop's progress counters, the ones Lightning itself restores: during an epoch its batches
    done so far (the next epoch once all ran, e.g. while validating at its end); after ``on_train_epoch_end`` the
    next epoch, from its start.
    """
    loop = trainer.fit_loop
    epochs = loop.epoch_progress.current
    batches = loop.epoch_loop.batch_progress.current.processed
    if epochs.started > epochs.processed:  # inside epoch `processed`
        if batches >= trainer.num_training_batches:
            return epochs.processed + 1, 0
        return epochs.processed, batches
    return epochs.processed, 0


class SharedEpoch:
    """An epoch counter in shared memory: set in the main process, read by (persistent) DataLoader workers."""

    def __init__(self) -> None:
        self._value = torch.zeros(1, dtype=torch.int64).share_memory_()

    def set(self, epoch: int) -> None:
        self._value[0] = int(epoch)

    def get(self) -> int:
        return int(self._value[0])


class UnpaddedDistributedSampler(DistributedSampler):
    """Evaluation shard of one rank: every ``world_size``-th frame, in order, with no frame repeated.

    torch's ``DistributedSampler`` (which Lightning inserts for validation and test) pads the dataset with repeated
    frames so all ranks get equal counts; repeated frames would be counted twice by the pooled metrics. The shards
    here differ by at most one frame; evaluation needs no lock-step between ranks (the metrics sync their summed
    states once, at the end).

    Example:
        >>> [list(UnpaddedDistributedSampler(range(5), num_replicas=2, rank=r)) for r in (0, 1)]
        [[0, 2, 4], [1, 3]]
    """

    def __init__(self, dataset, num_replicas: int | None = None, rank: int | None = None) -> None:
        super().__init__(dataset, num_replicas=num_replicas, rank=rank, shuffle=False, drop_last=False)
        self.num_samples = len(range(self.rank, len(dataset), self.num_replicas))
        self.total_size = len(dataset)

    def __iter__(self) -> Iterator[int]:
        return iter(range(self.rank, self.total_size, self.num_replicas))


def evaluation_sampler(dataset) -> Sampler[int] | None:
    """An :class:`UnpaddedDistributedSampler` when a process group with several ranks is running, else ``None``."""
    if dist.is_available() and dist.is_initialized() and dist.get_world_size() > 1:
        return UnpaddedDistributedSampler(dataset)
    return None


class EvaluationLoader(DataLoader):
    """An evaluation ``DataLoader`` whose rank, when its shard is empty (more ranks than frames), yields one empty
    batch: that rank still runs the epoch-end hooks and joins the metric sync, contributing nothing."""

    def __len__(self) -> int:
        return max(super().__len__(), 1)

    def __iter__(self) -> Iterator:
        if len(self.sampler) == 0:
            return iter([self.collate_fn([])])
        return super().__iter__()
