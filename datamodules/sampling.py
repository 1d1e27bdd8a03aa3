"""Epoch-seeded randomness, so a run gives the same batches whatever the worker count, restarts or DDP.

Shuffling and per-sample augmentation draws are functions of ``(seed, epoch, index)`` only: a run resumed from a
checkpoint replays exactly the epochs an uninterrupted run would have seen, and ``num_workers`` changes nothing.
"""

from __future__ import annotations

from collections.abc import Iterator

import torch
import torch.distributed as dist
from torch.utils.data import DistributedSampler, Sampler


def draw_seed(seed: int, epoch: int, index: int) -> int:
    """A 63-bit seed for one sample's random draws in one epoch."""
    x = (seed * 0x9E3779B97F4A7C15 + epoch * 0xBF58476D1CE4E5B9 + index * 0x94D049BB133111EB) & (2**64 - 1)
    x ^= x >> 31
    x = (x * 0xD6E8FEB86659FD93) & (2**64 - 1)
    return (x ^ (x >> 32)) & (2**63 - 1)


class EpochSeededSampler(Sampler[int]):
    """Random permutation seeded by ``(seed, epoch)``; Lightning calls :meth:`set_epoch` every epoch.

    Under DDP Lightning swaps it for a ``DistributedSampler``, which is epoch-seeded in the same way.
    """

    def __init__(self, num_samples: int, seed: int = 0) -> None:
        self.num_samples = int(num_samples)
        self.seed = int(seed)
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)

    def __iter__(self) -> Iterator[int]:
        generator = torch.Generator().manual_seed(draw_seed(self.seed, self.epoch, -1))
        return iter(torch.randperm(self.num_samples, generator=generator).tolist())

    def __len__(self) -> int:
        return self.num_samples


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
