"""The cache of generated presets the datamodules read: :func:`ensure_dataset` generates a preset on first use.

A preset lives at ``<root>/<preset>[-<lidar_preset>]-v<version>[-seed<seed>]`` (root: ``$AIRFISHEYE_DATA`` or
``~/.cache/airfisheye-bench``). It is generated into ``<path>.partial`` under an exclusive lock file and renamed when
complete, so concurrent processes generate it once and an interrupted generation resumes. A cached preset is
checked against the installed generator (:func:`~airfisheye_bench.synth.writer.stale_file`: a sample of its frames
re-rendered; once per change of the installed code, recorded in :data:`CURRENT_MARKER`) and generated again, with a
warning naming the file that differs, when this version writes something else, so that the cache does not serve
data the code no longer produces.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import logging
import os
import shutil
from pathlib import Path

import numpy as np
import torch

from airfisheye_bench.atomic import atomic_write_text, exclusive_lock
from airfisheye_bench.io.manifest import sha256_file
from airfisheye_bench.synth.presets import GENERATOR_VERSION, SynthConfig, get_preset
from airfisheye_bench.synth.writer import generate_dataset, stale_file

log = logging.getLogger(__name__)

DATA_ENV_VAR = "AIRFISHEYE_DATA"

#: Where a cached dataset records the code it was last found current with (left out of the manifest by its prefix).
CURRENT_MARKER = ".airfisheye-current.json"
#: Cached datasets found current in this process (path, manifest mtime).
_CURRENT: set[tuple[str, int]] = set()


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
    if _is_current(target, config, seed, device):
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    with exclusive_lock(target.with_name(target.name + ".lock")):
        if _is_current(target, config, seed, device, warn=False):  # another process finished meanwhile
            return target
        partial = target.with_name(target.name + ".partial")
        if partial.exists() and stale_file(partial, config, seed, device) is not None:
            log.warning("%s was begun by another version of the generator: starting it again", partial)
            shutil.rmtree(partial)
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
        if target.exists():  # stale (another generator's) or incomplete (e.g. removed manifest): replace it
            old = target.with_name(target.name + ".old")
            shutil.rmtree(old, ignore_errors=True)
            os.replace(target, old)
            os.replace(partial, target)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(partial, target)
        _mark_current(target)
    return target


def _is_current(target: Path, config: SynthConfig, seed: int, device: str, warn: bool = True) -> bool:
    """Whether ``target`` is a complete dataset that this generator writes as it is.

    The answer is kept for the process and, in ``target/.airfisheye-current.json``, for the installed code (a hash of
    the package's sources and the torch and numpy versions): the sample is re-rendered once after each change of
    code or libraries, not on every run.
    """
    manifest = target / "manifest.json"
    if not manifest.is_file():
        return False
    key = (str(target), manifest.stat().st_mtime_ns)
    if key in _CURRENT:
        return True
    stamp = _stamp(target)
    with contextlib.suppress(OSError, ValueError):
        if json.loads((target / CURRENT_MARKER).read_text(encoding="utf-8")) == stamp:
            _CURRENT.add(key)
            return True
    differs = stale_file(target, config, seed, device)
    if differs is not None:
        if warn:
            log.warning(
                "the cached dataset %s was written by another version of the generator (%s differs from what this "
                "version writes): generating it again; runs on the old data keep its content identity in their "
                "results.json",
                target,
                differs,
            )
        return False
    _mark_current(target, stamp)
    return True


def _stamp(target: Path) -> dict[str, str]:
    return {"manifest_sha256": sha256_file(target / "manifest.json"), "code": _code_fingerprint()}


def _mark_current(target: Path, stamp: dict[str, str] | None = None) -> None:
    """Record that ``target`` is what the installed generator writes (for this process and the next ones);
    ``stamp``: its :func:`_stamp`, when the caller has it."""
    with contextlib.suppress(OSError):  # a read-only cache is checked again next time
        atomic_write_text(target / CURRENT_MARKER, json.dumps(stamp or _stamp(target)) + "\n")
    _CURRENT.add((str(target), (target / "manifest.json").stat().st_mtime_ns))


@functools.cache
def _code_fingerprint() -> str:
    """SHA-256 of this package's Python sources, with the torch and numpy versions (what the generator's output
    can depend on)."""
    package = Path(__file__).resolve().parents[1]
    h = hashlib.sha256(f"torch {torch.__version__} numpy {np.__version__}".encode())
    for path in sorted(package.rglob("*.py")):
        h.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes())
    return h.hexdigest()
