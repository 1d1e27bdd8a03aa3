"""Evaluation shards under DDP: every frame exactly once across ranks, none repeated."""

from __future__ import annotations

import pytest

from datamodules.sampling import UnpaddedDistributedSampler, evaluation_sampler


@pytest.mark.parametrize(("n", "world"), [(0, 2), (1, 2), (5, 2), (7, 3), (12, 4), (3, 8)])
def test_shards_partition_the_split(n: int, world: int) -> None:
    shards = [list(UnpaddedDistributedSampler(range(n), num_replicas=world, rank=r)) for r in range(world)]
    assert sorted(i for shard in shards for i in shard) == list(range(n))
    assert [len(UnpaddedDistributedSampler(range(n), num_replicas=world, rank=r)) for r in range(world)] == [
        len(s) for s in shards
    ]
    assert max(map(len, shards)) - min(map(len, shards)) <= 1


def test_no_sampler_without_a_process_group() -> None:
    assert evaluation_sampler(range(4)) is None
