"""Scan a dataset root and report what is missing or malformed, without loading everything into memory.

By default only headers are read (image size and mode, ``.npy`` shape and dtype through a memory map), so a full
release is checked in minutes; ``deep=True`` also decodes every file and checks its values (non-finite depth,
label ids unknown to ``dataset.yaml``, empty or non-finite LiDAR scans).

Command line (:func:`airfisheye_bench.cli.commands.inspect`; ``--help`` lists the options)::

    airfisheye-inspect root=/path/to/AirFisheye [deep=true] [limit=20] [coverage=true] [size=128] [every=N]

For a sound dataset with LiDAR the command also states its completion input's coverage per incidence-angle ring
(:func:`datamodules.coverage.dataset_coverage`); the command wires it in, ``io`` being below ``datamodules``.

A dataset in another layout (``format=woodscape``, ...) is inspected through its source:
:func:`airfisheye_bench.dataset_tools.inspect_source.inspect_source`.

Example:
    >>> report = inspect_dataset("/path/to/AirFisheye")   # doctest: +SKIP
    >>> report.ok, report.samples, report.problems[:1]      # doctest: +SKIP
    (True, 26000, [])
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image

from airfisheye_bench.geometry.cubemap import FACE_NAMES
from airfisheye_bench.io import codecs
from airfisheye_bench.io.datasets.airfisheye import DatasetReader
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.layout import trajectory_of
from airfisheye_bench.io.scan import load_scan

_IMAGE_MODES = {"rgb": ("RGB", "RGBA", "L"), "seg": ("L", "P"), "depth": ("I;16", "I;16B", "I;16L", "I")}


@dataclass
class InspectReport:
    """What :func:`inspect_dataset` found.

    Attributes:
        root: The dataset root.
        samples: Samples listed in the split files.
        files: Files checked.
        problems: ``(path, what is wrong)`` for every problem, in scan order.
        splits: Samples per split (of the splits that could be read).
    """

    root: Path
    samples: int = 0
    files: int = 0
    problems: list[tuple[str, str]] = field(default_factory=list)
    splits: dict[str, int] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.problems

    def add(self, path: Path | str, message: str) -> None:
        self.problems.append((str(path), message))

    def summary(self, limit: int = 20) -> str:
        head = (
            f"{self.root}: {self.samples} samples, {self.files} files checked, {len(self.problems)} problems"
        )
        lines = [head]
        if self.splits:
            lines.append("  splits: " + ", ".join(f"{name} {n}" for name, n in self.splits.items()))
        lines += [f"  {p}: {m}" for p, m in self.problems[:limit]]
        if len(self.problems) > limit:
            lines.append(f"  ... and {len(self.problems) - limit} more")
        return "\n".join(lines)


def inspect_dataset(root: str | Path, deep: bool = False) -> InspectReport:
    """Check every file the split files refer to against ``dataset.yaml`` and the calibration."""
    root = Path(root)
    report = InspectReport(root)
    if not (root / "dataset.yaml").is_file():
        report.add(root / "dataset.yaml", "missing: not a dataset root (no dataset.yaml)")
        return report
    try:
        reader = DatasetReader(root)
    except (DatasetFormatError, ValueError) as err:
        report.add(root / "dataset.yaml", str(err))
        return report
    spec = reader.spec

    samples: list[str] = []
    for split in reader.split_names:
        try:
            ids = reader.split(split)
            samples += ids
            report.splits[split] = len(ids)
        except (DatasetFormatError, OSError, ValueError) as err:
            report.add(reader.layout.split_file(spec.splits.files[split]), str(err))
    report.samples = len(samples)

    checked_trajectories: dict[str, object] = {}
    for sid in samples:
        traj = trajectory_of(sid)
        if traj not in checked_trajectories:
            checked_trajectories[traj] = _check_trajectory(reader, traj, report)
        calib = checked_trajectories[traj]
        if calib is None:
            continue
        frame = sid.rsplit("/", 1)[1]
        try:
            reader.poses(traj).index(frame)
        except (ValueError, KeyError, DatasetFormatError):
            report.add(reader.layout.poses(traj), f"no pose for frame {frame}")
        _check_sample(reader, sid, calib, deep, report)
    return report


def _check_trajectory(reader: DatasetReader, traj: str, report: InspectReport):
    for path, load in ((reader.layout.calib(traj), reader.calib), (reader.layout.poses(traj), reader.poses)):
        report.files += 1
        try:
            load(traj)
        except (DatasetFormatError, OSError, ValueError) as err:
            report.add(path, str(err))
            return None
    return reader.calib(traj)


def _check_sample(reader, sid: str, calib: np.ndarray, deep: bool, report: InspectReport) -> None:
    spec = reader.spec
    if spec.has("cubemap") and calib.face_size:
        for face in FACE_NAMES:
            for modality in ("rgb", "seg", "depth"):
                path = reader.layout.cubemap(sid, face, modality)
                _check_image(path, modality, (calib.face_size, calib.face_size), reader, deep, report)
    if spec.has("fisheye"):
        size = (int(calib.camera["height"]), int(calib.camera["width"]))
        for modality in ("rgb", "seg", "depth"):
            _check_image(reader.layout.fisheye(sid, modality), modality, size, reader, deep, report)
    n_points = None
    report.files += spec.has("lidar") + spec.has("lidar_visible")
    if spec.has("lidar") and reader.layout.lidar(sid).suffix != ".npy":  # a real sensor's scan files
        try:
            n_points = len(load_scan(reader.layout.lidar(sid)).points)
        except DatasetFormatError as err:
            report.add(err.path, err.message)
    elif spec.has("lidar"):
        n_points = _check_array(reader.layout.lidar(sid), 2, 4, np.floating, deep, report, "LiDAR scan")
    if spec.has("lidar_visible"):
        n_vis = _check_array(reader.layout.lidar_visible(sid), 1, None, np.bool_, False, report, "visibility")
        if n_points is not None and n_vis is not None and n_points != n_vis:
            report.add(reader.layout.lidar_visible(sid), f"{n_vis} flags for {n_points} LiDAR points")
    if spec.has("lidar_beam"):
        report.files += 1
        path = reader.layout.lidar_beam(sid)
        n_beam = _check_array(path, 1, None, np.int32, False, report, "beams")
        if n_points is not None and n_beam is not None and n_points != n_beam:
            report.add(path, f"{n_beam} beams for {n_points} LiDAR points")
        elif deep and n_beam:
            lidar = calib.lidar_spec()
            beam = codecs.read_beams(path)
            if beam.min() < 0 or beam.max() >= lidar.channels * lidar.points_per_channel:
                report.add(
                    path, "beams must be indices in [0, channels * points_per_channel) (calib.yaml lidar)"
                )
    if spec.has("lidar_scan"):
        try:
            reader.lidar_phase(sid)
        except (DatasetFormatError, OSError) as err:
            report.add(reader.layout.lidar_scan(sid), str(err))


def _check_image(path: Path, modality: str, size: tuple[int, int], reader, deep: bool, report) -> None:
    report.files += 1
    if not path.is_file():
        report.add(path, "missing")
        return
    if path.suffix in (".npy", ".pfm"):  # float depth
        if path.suffix == ".npy":
            shape = _check_array(path, 2, None, np.floating, False, report, "depth")
            if shape is not None and not deep:
                return
        try:
            depth = codecs.read_depth(path, scale=reader.spec.files.depth_scale)
        except DatasetFormatError as err:
            report.add(path, err.message)
            return
        _check_values(path, modality, depth, size, reader.spec, report)
        return
    try:
        with Image.open(path) as img:  # reads the header only
            mode, (w, h) = img.mode, img.size
            if (h, w) != size:
                report.add(path, f"image is {w}x{h}, expected {size[1]}x{size[0]} (calib.yaml)")
            if mode not in _IMAGE_MODES[modality]:
                report.add(
                    path, f"{modality} image has mode {mode}, expected one of {_IMAGE_MODES[modality]}"
                )
            if deep:
                img.load()
    except OSError as err:
        report.add(path, f"unreadable image ({err})")
        return
    if deep and modality in ("seg", "depth"):
        try:
            data = reader._read(path, modality)
        except DatasetFormatError as err:
            report.add(path, err.message)
            return
        _check_values(path, modality, data, size, reader.spec, report)


def _check_values(path: Path, modality: str, data: np.ndarray, size, spec, report) -> None:
    if data.shape[:2] != size:
        report.add(
            path, f"array is {data.shape[1]}x{data.shape[0]}, expected {size[1]}x{size[0]} (calib.yaml)"
        )
    if modality == "depth" and not np.isfinite(data).all():
        report.add(path, "depth contains NaN or inf (0 marks invalid)")
    if modality == "seg":
        unknown = spec.unknown_label_ids(data)
        if unknown:
            report.add(path, f"label ids {unknown} are not raw classes of dataset.yaml")


def _check_array(path: Path, ndim: int, cols: int | None, kind, deep: bool, report, what: str) -> int | None:
    """Check a ``.npy`` header (memory-mapped); returns its length or ``None`` on a problem."""
    if not path.is_file():
        report.add(path, "missing")
        return None
    try:
        arr = np.load(path, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError) as err:
        report.add(path, f"unreadable .npy ({err})")
        return None
    if arr.ndim != ndim or (cols is not None and arr.shape[1] != cols) or not np.issubdtype(arr.dtype, kind):
        want = f"[N, {cols}]" if cols else ("[N]" if ndim == 1 else f"{ndim}-D")
        report.add(
            path,
            f"{what} must be {want} {np.dtype(kind).name if kind is not np.floating else 'float'}, got {arr.dtype} {arr.shape}",
        )
        return None
    if deep and what == "LiDAR scan":
        if len(arr) == 0:
            report.add(path, "the LiDAR scan is empty")
        elif not np.isfinite(np.asarray(arr[:, :3])).all():
            report.add(path, "the LiDAR scan has non-finite coordinates")
    return int(arr.shape[0])
