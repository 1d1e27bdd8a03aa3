"""Inspect any :class:`~airfisheye_bench.io.datasets.base.DatasetSource`: a public dataset in its own layout.

A format's files are its source's business, so this goes through the source, as training does: per split the
sample count, then per sample its calibration and the files of its modalities (``rgb`` and whatever else its
``modalities`` and ``spec.contents`` say: ``seg``, ``depth``, the LiDAR scan). By default it checks that each file
exists and that an image's header reads; ``deep=True`` loads every map through the source and checks it: the size
its calibration gives (a source may crop what it serves, so sizes are a deep check), label ids known to its
classes, depth finite and non-negative, LiDAR scans non-empty and finite, ``T_cam_lidar`` finite. Every problem is
reported with the file the source names (its :class:`~airfisheye_bench.io.errors.DatasetFormatError`).

Example:
    >>> report = inspect_source("/data/woodscape", "woodscape", {"views": ["FV"]}, deep=True)  # doctest: +SKIP
    >>> report.splits, report.ok                                                              # doctest: +SKIP
    ({'train': 1990, 'val': 50}, True)
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from airfisheye_bench.dataset_tools.inspect import InspectReport
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.cubemap import FACE_NAMES
from airfisheye_bench.io.datasets import DATASET_FORMATS, DatasetSource, modalities_of, open_dataset
from airfisheye_bench.io.errors import DatasetFormatError

__all__ = ["inspect_source"]

_LOAD_ERRORS = (DatasetFormatError, OSError, ValueError)


def inspect_source(
    root: str | Path, format: str, options: dict[str, Any] | None = None, deep: bool = False
) -> InspectReport:
    """Check every sample of every split of ``root`` read as ``format`` (with its ``data.format_options``).

    Raises:
        ConfigError: an unknown format or format option (the command's mistake, not the dataset's).
    """
    root = Path(root)
    report = InspectReport(root)
    if format not in DATASET_FORMATS:
        raise ConfigError(f"format={format!r}: expected one of {', '.join(DATASET_FORMATS)}")
    if not root.is_dir():
        report.add(root, f"missing: not a folder (the root of the {format} dataset)")
        return report
    try:
        source = open_dataset(root, format, options)
    except DatasetFormatError as err:
        report.add(err.path, err.message)
        return report
    except ValueError as err:  # a bad option value
        raise ConfigError(f"format_options: {err}") from None
    for split in source.split_names:
        try:
            ids = source.split(split)
        except _LOAD_ERRORS as err:
            _add(report, err, root)
            continue
        report.splits[split] = len(ids)
        report.samples += len(ids)
        for sid in ids:
            _check_sample(source, sid, deep, report)
    return report


def _check_sample(source: DatasetSource, sid: str, deep: bool, report: InspectReport) -> None:
    spec = source.spec
    report.files += 1
    try:
        calib = source.calib(sid)
    except _LOAD_ERRORS as err:
        _add(report, err, source.root)
        return
    readers = {"fisheye": source.fisheye, "cubemap": source.cubemap, "equirect": source.equirect}
    for kind in [k for k in readers if spec.has(k)]:
        for modality in modalities_of(source):
            report.files += 1
            path = source.path_of(sid, modality, kind)
            if not deep:
                _check_file(path, report)
                continue
            try:
                data = readers[kind](sid, modality)
            except _LOAD_ERRORS as err:
                _add(report, err, path)
                continue
            _check_map(path, kind, modality, data, calib, spec, report)
    if spec.has("lidar"):
        report.files += 1
        if deep:
            _check_lidar(source, sid, report)


def _check_file(path: Path, report: InspectReport) -> None:
    if not path.exists():
        report.add(path, "missing")
        return
    if path.suffix.lower() in (".png", ".jpg", ".jpeg"):
        try:
            with Image.open(path):  # the header only
                pass
        except OSError as err:
            report.add(path, f"unreadable image ({err})")


def _check_map(path: Path, kind: str, modality: str, data: np.ndarray, calib, spec, report) -> None:
    if kind == "fisheye":
        size, shape = (int(calib.camera["height"]), int(calib.camera["width"])), data.shape[:2]
    elif kind == "equirect":
        size, shape = spec.equirect_size, data.shape[:2]
    else:
        size, shape = (len(FACE_NAMES), calib.face_size, calib.face_size), data.shape[:3]
    if tuple(shape) != size:
        report.add(
            path,
            f"{modality} is {'x'.join(map(str, shape))}, the calibration says {'x'.join(map(str, size))}",
        )
    if modality == "seg":
        unknown = spec.unknown_label_ids(np.asarray(data, np.uint8))
        if unknown:
            report.add(path, f"label ids {unknown} are not classes of the dataset")
    if modality == "depth" and not (np.isfinite(data).all() and (data >= 0).all()):
        report.add(path, "depth must be finite and >= 0 (0 marks invalid)")


def _check_lidar(source, sid: str, report: InspectReport) -> None:
    try:
        scan = source.lidar_scan(sid)
        transform = np.asarray(source.T_cam_lidar(sid), np.float64)
    except _LOAD_ERRORS as err:
        _add(report, err, source.root)
        return
    if len(scan.points) == 0:
        report.add(scan.path, "the LiDAR scan is empty")
    elif not np.isfinite(scan.points).all():
        report.add(scan.path, "the LiDAR scan has non-finite coordinates")
    if transform.shape != (4, 4) or not np.isfinite(transform).all():
        report.add(scan.path, f"T_cam_lidar of {sid} must be a finite 4x4 matrix")


def _add(report: InspectReport, err: Exception, fallback: Path) -> None:
    if isinstance(err, DatasetFormatError):
        report.add(err.path, err.message if err.key is None else f"key '{err.key}': {err.message}")
    else:
        report.add(getattr(err, "filename", None) or fallback, str(err))
