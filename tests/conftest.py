"""Shared fixtures: the ``tiny`` synthetic dataset and the tiny runs of each task, made once per test session.

Under pytest-xdist (``pytest`` runs ``-n auto``, see ``pyproject.toml``) the session's workers share them: the first
worker to ask makes each one, under a lock, in a folder beside the workers' own temporary folders.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
import torch

from airfisheye_bench.atomic import exclusive_lock
from tests.helpers.runs import shared_export, shared_run


def pytest_configure(config: pytest.Config) -> None:
    # Each of the n workers of an n-core machine computes on one core: torch's default (a thread per core in every
    # worker) would run n x n threads on n cores, slower than the same tests one after the other.
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if workers > 1:
        torch.set_num_threads(max(1, (os.cpu_count() or 1) // workers))


@pytest.fixture(scope="session", autouse=True)
def _runs_outside_the_checkout(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """A command left to its default run directory (``logs/<task>/runs/<name>`` under ``paths.root_dir``, the working
    folder: the checkout) writes under this session's temporary folder instead; the commands' subprocesses
    inherit it. A test that needs another ``PROJECT_ROOT`` sets its own."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("PROJECT_ROOT", str(tmp_path_factory.mktemp("project")))
        yield


@pytest.fixture(scope="session")
def shared_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder every worker of this session sees (the session's base temporary folder under xdist)."""
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent
    folder = base / "shared"
    folder.mkdir(exist_ok=True)
    return folder


def _tiny(shared_dir: Path, seed: int) -> Path:
    from airfisheye_bench.synth.writer import generate_dataset

    root = shared_dir / "datasets" / (f"tiny_seed{seed}" if seed else "tiny")
    with exclusive_lock(root.with_name(root.name + ".lock")):
        if not (root / "manifest.json").is_file():
            generate_dataset("tiny", root, seed=seed, workers=1, progress=False)
    return root


@pytest.fixture(scope="session")
def tiny_dataset(shared_dir: Path) -> Path:
    """Root of the ``tiny`` preset (seed 0) in the AirFisheye layout: 3 trajectories / 12 frames, one per split
    location, with cube faces, ray-cast fisheye, LiDAR and visibility. Read-only: copy it before modifying."""
    return _tiny(shared_dir, 0)


@pytest.fixture(scope="session")
def tiny_dataset_seed1(shared_dir: Path) -> Path:
    """The ``tiny`` preset generated with ``seed=1``: another dataset in the AirFisheye layout, with the same
    classes, camera and sample ids as :func:`tiny_dataset` (a second source for runs on several datasets)."""
    return _tiny(shared_dir, 1)


@pytest.fixture(scope="session")
def tiny_runs(tiny_dataset: Path, shared_dir: Path):
    """``tiny_runs(task)``: the session's finished tiny run of ``task`` (``tests.helpers.runs.shared_run``: debug
    trainer, 64² tiny data, CSV logger), trained on first use. Read-only: ``copy_run`` it before changing it."""

    def run(task: str) -> Path:
        return shared_run(task, tiny_dataset, shared_dir / "runs" / task)

    return run


@pytest.fixture(scope="session")
def tiny_rays_runs(tiny_dataset: Path, shared_dir: Path):
    """``tiny_rays_runs(task)``: as :func:`tiny_runs`, of a camera-aware model (``model.camera_input=rays``: the ray
    map of each sample's lens beside the image). Read-only."""

    def run(task: str) -> Path:
        return shared_run(
            task, tiny_dataset, shared_dir / "runs" / f"{task}-rays", ["model.camera_input=rays"]
        )

    return run


@pytest.fixture(scope="session")
def tiny_rays_exports(tiny_rays_runs, shared_dir: Path):
    """``tiny_rays_exports(task, baked=False)``: as :func:`tiny_exports`, of the session's camera-aware run of
    ``task``: the ray map a second input ``rays`` (with an int8 copy: ``quantize=dynamic``), or with ``baked`` held
    in the file (``bake_camera=true``). Read-only."""

    def exported(task: str, baked: bool = False) -> tuple[Path, int, str]:
        name, extra = (
            (f"{task}-rays-baked", "bake_camera=true") if baked else (f"{task}-rays", "quantize=dynamic")
        )
        return shared_export(task, tiny_rays_runs(task), shared_dir / "exports" / name, [extra])

    return exported


@pytest.fixture(scope="session")
def tiny_exports(tiny_runs, shared_dir: Path):
    """``tiny_exports(task)``: ``(onnx_path, exit status, printed report)`` of ``airfisheye-export`` on the session's
    tiny run of ``task`` (``tests.helpers.runs.shared_export``), exported on first use. Read-only."""

    def exported(task: str) -> tuple[Path, int, str]:
        return shared_export(task, tiny_runs(task), shared_dir / "exports" / task)

    return exported
