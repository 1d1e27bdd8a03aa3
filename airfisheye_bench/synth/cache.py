"""The cache of generated presets the datamodules read: :func:`ensure_dataset` generates a preset on first use.

A preset lives at ``<root>/<preset>[-<lidar_preset>]-v<version>[-seed<seed>]`` (root: ``$AIRFISHEYE_DATA`` or
``~/.cache/airfisheye-bench``). It is generated into ``<path>.partial`` under an exclusive lock file and renamed when
complete, so concurrent processes generate it once and an interrupted generation resumes.
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
from pathlib import Path

from airfisheye_bench.synth.presets import GENERATOR_VERSION, get_preset
from airfisheye_bench.synth.writer import generate_dataset

log = logging.getLogger(__name__)

DATA_ENV_VAR = "AIRFISHEYE_DATA"


def default_data_root() -> Path:
    """``$AIRFISHEYE_DATA`` if set, else ``~/.cache/airfisheye-bench``."""
    env = os.environ.get(DATA_ENV_VAR)
    return Path(env).expanduser() if env else Path.home() / ".cache" / "airfisheye-bench"


def cached_dataset_path(
    preset: str, root: str | Path | None = None, seed: int = 0, lidar_preset: str | None = None
) -> Path:
    """Where :func:`ensure_dataset` keeps ``preset``: ``<root>/<preset>[-<lidar_preset>]-v<version>[-seed<seed>]``."""
    base = Path(root).expanduser() if root is not None else default_data_root()
    suffix = f"-seed{seed}" if seed else ""
    lidar = f"-{lidar_preset}" if lidar_preset else ""
    return base / f"{preset}{lidar}-v{GENERATOR_VERSION}{suffix}"


def ensure_dataset(
    preset: str = "quickstart",
    root: str | Path | None = None,
    seed: int = 0,
    workers: int | None = None,
    device: str = "cpu",
    progress: bool = True,
    lidar_preset: str | None = None,
) -> Path:
    """Path of a complete generated ``preset``, generating it on first use.

    The dataset is generated into ``<path>.partial`` and renamed when complete, under an exclusive lock file
    (``<path>.lock``), so two processes asking at once generate it once; an interrupted generation resumes.

    Args:
        preset: Preset name.
        root: Cache folder (default :func:`default_data_root`).
        seed: Base seed.
        workers: Rendering processes (default: the number of CPUs, at most 8).
        device: Torch device for ray casting.
        progress: Show a progress bar.
        lidar_preset: Simulate this real sensor (``SynthConfig.lidar_preset``) instead of the preset's LiDAR;
            cached apart from the preset itself.

    Example:
        >>> path = ensure_dataset("tiny")          # doctest: +SKIP
        >>> (path / "dataset.yaml").exists()       # doctest: +SKIP
        True
    """
    config = get_preset(preset)
    if lidar_preset is not None:
        config = config.replace(lidar_preset=lidar_preset)
    target = cached_dataset_path(preset, root, seed, lidar_preset)
    if (target / "manifest.json").is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    with _exclusive_lock(target.with_name(target.name + ".lock")):
        if (target / "manifest.json").is_file():  # another process finished while we waited
            return target
        partial = target.with_name(target.name + ".partial")
        if workers is None:
            workers = max(1, min(8, os.cpu_count() or 1))
        log.info("generating the %r synthetic dataset into %s (first use)", preset, target)
        generate_dataset(
            preset if lidar_preset is None else config,
            partial,
            seed=seed,
            workers=workers,
            device=device,
            progress=progress,
        )
        if target.exists():  # a stale, incomplete folder (e.g. removed manifest): replace it
            shutil.rmtree(target)
        os.replace(partial, target)
    return target


@contextlib.contextmanager
def _exclusive_lock(path: Path):
    """Blocking inter-process lock on ``path`` (``fcntl`` on POSIX; best effort elsewhere)."""
    with open(path, "a+") as f:
        try:
            import fcntl  # POSIX only
        except ImportError:  # Windows: rely on the atomic rename of the finished dataset
            yield
            return
        fcntl.flock(f.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f.fileno(), fcntl.LOCK_UN)
