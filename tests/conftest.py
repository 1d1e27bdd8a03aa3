"""Shared fixtures: the ``tiny`` synthetic dataset, generated once per test session."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Root of the ``tiny`` preset (seed 0) in the AirFisheye layout: 3 trajectories / 12 frames, one per split
    location, with cube faces, ray-cast fisheye, LiDAR and visibility. Read-only: copy it before modifying."""
    from airfisheye_bench.synth.writer import generate_dataset

    return generate_dataset(
        "tiny", tmp_path_factory.mktemp("datasets") / "tiny", seed=0, workers=1, progress=False
    )


@pytest.fixture(scope="session")
def tiny_dataset_seed1(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The ``tiny`` preset generated with ``seed=1``: another dataset in the AirFisheye layout, with the same
    classes, camera and sample ids as :func:`tiny_dataset` (a second source for runs on several datasets)."""
    from airfisheye_bench.synth.writer import generate_dataset

    return generate_dataset(
        "tiny", tmp_path_factory.mktemp("datasets") / "tiny_seed1", seed=1, workers=1, progress=False
    )
