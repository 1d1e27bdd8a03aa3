"""KITTI-360's fisheye splits: by sequence (no official fisheye split exists), or as ``format_options.sequences``.

Example:
    >>> split_by_sequence(["2013_05_28_drive_0003_sync", "2013_05_28_drive_0000_sync", "2013_05_28_drive_0010_sync"])
    {'train': ['2013_05_28_drive_0000_sync'], 'val': ['2013_05_28_drive_0003_sync'], 'test': ['2013_05_28_drive_0010_sync']}
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.io.errors import DatasetFormatError

log = logging.getLogger(__name__)

SPLITS = ("train", "val", "test")


def split_by_sequence(sequences: list[str]) -> dict[str, list[str]]:
    """The default rule: sorted by name, the last is ``test``, the one before ``val``, the others ``train``; two
    sequences: ``train`` the first, ``val`` and ``test`` the second; one: every split is that one (logged)."""
    seqs = sorted(sequences)
    if len(seqs) == 1:
        log.warning("KITTI-360: one sequence (%s): train, val and test are the same frames", seqs[0])
        return {name: seqs for name in SPLITS}
    if len(seqs) == 2:
        return {"train": seqs[:1], "val": seqs[1:], "test": seqs[1:]}
    return {"train": seqs[:-2], "val": seqs[-2:-1], "test": seqs[-1:]}


def usable_sequences(root: Path, camera: str) -> list[str]:
    """Sequences with the camera's images, ``poses.txt`` and Velodyne scans (held-out sequences without poses are
    left out, logged)."""
    folder = root / "data_2d_raw"
    if not folder.is_dir():
        raise DatasetFormatError(folder, "no such folder: expected data_2d_raw/<seq>/image_0X/data_rgb/")
    seqs = sorted(p.name for p in folder.iterdir() if (p / camera / "data_rgb").is_dir())
    usable = [
        s
        for s in seqs
        if (root / "data_poses" / s / "poses.txt").is_file()
        and (root / "data_3d_raw" / s / "velodyne_points" / "data").is_dir()
    ]
    if not usable:
        raise DatasetFormatError(
            folder, f"no sequence with {camera}/data_rgb/, data_poses/<seq>/poses.txt and velodyne scans"
        )
    if len(usable) < len(seqs):
        log.info(
            "KITTI-360: without poses or scans, not used: %s", ", ".join(sorted(set(seqs) - set(usable)))
        )
    return usable


def check_sequences(root: Path, sequences) -> dict[str, list[str]] | None:
    """``format_options.sequences`` (``{split: [sequence, ...]}``, or ``None``) checked against ``root``."""
    if sequences is None:
        return None
    key = "data.format_options.sequences"
    if not hasattr(sequences, "items") or set(sequences) - set(SPLITS):
        raise ConfigError(f"{key}: expected a mapping of {', '.join(SPLITS)} to lists of sequence names")
    out = {name: [str(s) for s in sequences.get(name) or []] for name in SPLITS}
    for name, seqs in out.items():
        for seq in seqs:
            if not (root / "data_2d_raw" / seq).is_dir():
                raise ConfigError(f"{key}.{name}: {root / 'data_2d_raw' / seq} is not a folder")
    return out


def frame_numbers(folder: Path, suffix: str) -> np.ndarray:
    """Sorted frame numbers of the ``<frame><suffix>`` files in ``folder``."""
    if not folder.is_dir():
        raise DatasetFormatError(folder, "no such folder")
    names = (p.name[: -len(suffix)] for p in folder.iterdir() if p.name.endswith(suffix))
    return np.asarray(sorted(int(n) for n in names if n.isdigit()), np.int64)


__all__ = ["SPLITS", "check_sequences", "frame_numbers", "split_by_sequence", "usable_sequences"]
