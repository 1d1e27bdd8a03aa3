"""Read access to a dataset in the AirFisheye layout (synthetic or real) through ``dataset.yaml``."""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import numpy as np

from airfisheye_bench.geometry.cubemap import FACE_NAMES
from airfisheye_bench.io import codecs
from airfisheye_bench.io.calib_yaml import Calibration
from airfisheye_bench.io.dataset_spec import DatasetSpec
from airfisheye_bench.io.datasets.base import DatasetSource
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.layout import MODALITIES, DatasetLayout, trajectory_of
from airfisheye_bench.io.poses import ImuTable, PoseTable, camera_from_lidar
from airfisheye_bench.io.scan import Scan, load_scan
from airfisheye_bench.io.splits import parse_sample_id, read_split


class DatasetReader(DatasetSource):
    """Reads samples, calibration and poses of a dataset root in the AirFisheye layout (``data.format=airfisheye``).

    The :class:`~airfisheye_bench.io.datasets.base.DatasetSource` of the release and the synthetic data: cube faces
    and pre-rendered fisheye images, recorded (or generated) LiDAR scans taken at one instant (no ``deskew``), and on
    synthetic releases the generator's per-point visibility (``lidar_visible``, the ``oracle`` sparse input).

    Per-trajectory files (calibration, poses, IMU) are parsed once and cached. The object is cheap to pickle
    (the caches are per process), so a DataLoader can hand it to its workers.

    Args:
        root: Dataset root (the folder holding ``dataset.yaml``).
        spec: Already-loaded spec; read from ``root/dataset.yaml`` when ``None``.

    Example:
        >>> reader = DatasetReader("/path/to/dataset")                       # doctest: +SKIP
        >>> sid = reader.split("train")[0]                                    # doctest: +SKIP
        >>> rgb = reader.fisheye(sid, "rgb"); points = reader.lidar(sid)      # doctest: +SKIP
        >>> T_cam_lidar = reader.T_cam_lidar(sid)                             # doctest: +SKIP
    """

    format: ClassVar[str] = "airfisheye"
    OPTIONS: ClassVar[dict[str, object]] = {}
    modalities: ClassVar[tuple[str, ...]] = ("rgb", "seg", "depth")

    def __init__(self, root: str | Path, spec: DatasetSpec | None = None) -> None:
        self.root = Path(root)
        if not self.root.is_dir():
            raise ValueError(f"root must be an existing dataset folder, got {str(self.root)!r}")
        self.spec = spec if spec is not None else DatasetSpec.load(self.root)
        self.layout = DatasetLayout(self.root, self.spec.layout, self.spec.files)
        self._cache: dict[tuple[str, str], object] = {}  # (kind, trajectory) -> parsed file

    def __getstate__(self) -> dict:
        return {"root": self.root, "spec": self.spec}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["root"], state["spec"])

    # -------------------------------------------------------------------------------- splits
    @property
    def split_names(self) -> list[str]:
        return list(self.spec.splits.files)

    def split(self, name: str) -> list[str]:
        """Sample ids of split ``name`` in file order."""
        if name not in self.spec.splits.files:
            raise ValueError(f"split must be one of {self.split_names}, got {name!r}")
        return read_split(self.layout.split_file(self.spec.splits.files[name]))

    def split_rule(self, name: str) -> str:
        """The split file that lists split ``name``."""
        path = self.layout.split_file(self.spec.splits.files[name])
        return f"one sample id <env>/<trajectory>/<frame> a line in {path}"

    def trajectories(self) -> list[str]:
        """All ``"<env>/<traj>"`` named by the split files, sorted."""
        return sorted({trajectory_of(s) for name in self.split_names for s in self.split(name)})

    # ----------------------------------------------------------------------- trajectory level
    def calib(self, trajectory: str) -> Calibration:
        """Calibration of a trajectory (``"<env>/<traj>"`` or any of its sample ids)."""
        key = _traj_key(trajectory)
        return self._cached("calib", key, lambda: Calibration.load(self.layout.calib(key)))

    def poses(self, trajectory: str) -> PoseTable:
        """Pose table of a trajectory (``"<env>/<traj>"`` or any of its sample ids)."""
        key = _traj_key(trajectory)
        return self._cached("poses", key, lambda: PoseTable.load(self.layout.poses(key)))

    def imu(self, trajectory: str) -> ImuTable:
        """IMU samples of a trajectory (not cached: only a few consumers need them)."""
        return ImuTable.load(self.layout.imu(_traj_key(trajectory)))

    def T_cam_lidar(self, sample_id: str) -> np.ndarray:
        """Motion-compensated ``[4, 4]`` LiDAR -> camera transform of one frame (see ``io.poses``)."""
        key = trajectory_of(sample_id)

        def build() -> np.ndarray:
            calib = self.calib(key)
            return camera_from_lidar(self.poses(key), calib.T_body_cam, calib.T_body_lidar)

        return self._cached("T_cam_lidar", key, build)[self.poses(key).index(parse_sample_id(sample_id)[2])]

    # ----------------------------------------------------------------------------- frame level
    def cubemap(self, sample_id: str, modality: str) -> np.ndarray:
        """Stacked faces in :data:`FACE_NAMES` order: ``rgb uint8 [5,S,S,3]``, ``seg uint8 [5,S,S]`` (raw ids) or
        ``depth float32 [5,S,S]`` (range, metres, 0 = invalid)."""
        return np.stack(
            [self._read(self.layout.cubemap(sample_id, f, modality), modality) for f in FACE_NAMES]
        )

    def cube_face(self, sample_id: str, face: str, modality: str) -> np.ndarray:
        return self._read(self.layout.cubemap(sample_id, face, modality), modality)

    def fisheye(self, sample_id: str, modality: str) -> np.ndarray:
        """Pre-rendered fisheye ``rgb [H,W,3]``, ``seg [H,W]`` (raw ids, 255 outside the circle) or ``depth [H,W]``."""
        return self._read(self.layout.fisheye(sample_id, modality), modality)

    def lidar(self, sample_id: str) -> np.ndarray:
        """``float32 [N, 4]``: x, y, z in the LiDAR frame at ``t_lidar``, raw semantic id."""
        return codecs.read_lidar(self.layout.lidar(sample_id))

    def lidar_scan(self, sample_id: str) -> Scan:
        """The LiDAR scan of a frame with its rings where the release records them.

        The layout's own ``lidar/<frame>.npy`` (x, y, z, raw id; the ids in ``extra["raw_id"]``) takes its rings
        from ``lidar_beam`` where the release has it (synthetic scans of a channel-table sensor or a realistic
        scan model); a release whose ``layout.lidar`` names real scan files (``.bin``, ``.pcd.bin``, ``.pcd``,
        ``.ply``, ``.npz``) is read by :func:`~airfisheye_bench.io.scan.load_scan`, rings from the file's field.
        """
        path = self.layout.lidar(sample_id)
        if path.suffix != ".npy":
            return load_scan(path)
        data = codecs.read_lidar(path)
        rings = None
        if self.spec.has("lidar_beam"):
            beams = codecs.read_beams(self.layout.lidar_beam(sample_id), len(data))
            rings = beams.astype(np.int64) // self.calib(sample_id).lidar_spec().points_per_channel
        points = data[:, :3].astype(np.float64)
        return Scan(points, None, rings, False, 0, path, "airfisheye_npy", {"raw_id": data[:, 3]})

    def lidar_visible(self, sample_id: str) -> np.ndarray:
        """``bool [N]`` ground-truth visibility (synthetic releases only; see ``sensors.visibility``)."""
        if not self.spec.has("lidar_visible"):
            raise DatasetFormatError(
                self.layout.dataset_yaml, "this release has no lidar_visible", key="contents"
            )
        return codecs.read_visibility(self.layout.lidar_visible(sample_id))

    def lidar_beam(self, sample_id: str) -> np.ndarray:
        """``int32 [N]`` beam of every point, ``channel * N_PC + column`` (synthetic releases with a realistic
        scan model; see ``sensors.lidar.scan``)."""
        self._require("lidar_beam")
        return codecs.read_beams(self.layout.lidar_beam(sample_id))

    def lidar_phase(self, sample_id: str) -> float:
        """Azimuth phase (radians) of the scan of ``sample_id`` (see ``sensors.lidar.scan``)."""
        self._require("lidar_scan")
        traj = trajectory_of(sample_id)
        phases = self._cached(
            "lidar_scan", traj, lambda: codecs.read_scan_phases(self.layout.lidar_scan(traj))
        )
        frame = sample_id.rsplit("/", 1)[1]
        if frame not in phases:
            raise DatasetFormatError(self.layout.lidar_scan(traj), f"no phase for frame {frame}")
        return phases[frame]

    def path_of(self, sample_id: str, modality: str, source: str) -> Path:
        """The file of a fisheye ``modality`` (``source=fisheye``) or the folder of its cube faces (``cubemap``); the
        scan (``lidar``) or its visibility flags (``lidar_visible``) whatever the source."""
        if modality == "lidar":
            return self.layout.lidar(sample_id)
        if modality == "lidar_visible":
            return self.layout.lidar_visible(sample_id)
        if source == "cubemap":
            return self.layout.cubemap(sample_id, "front", modality).parent.parent
        return self.layout.fisheye(sample_id, modality)

    def missing_reason(self, content: str) -> str:
        return f"{self.root} has no {content} data (dataset.yaml contents)"

    # ------------------------------------------------------------------------------- helpers
    def _require(self, modality: str) -> None:
        if not self.spec.has(modality):
            raise DatasetFormatError(
                self.layout.dataset_yaml, f"this release has no {modality}", key="contents"
            )

    def _read(self, path: Path, modality: str) -> np.ndarray:
        if modality not in MODALITIES:
            raise ValueError(f"modality must be one of {MODALITIES}, got {modality!r}")
        if modality == "rgb":
            return codecs.read_rgb(path)
        if modality == "seg":
            return codecs.read_label(path)
        return codecs.read_depth(path, scale=self.spec.files.depth_scale)

    def _cached(self, kind: str, key: str, load):
        if (kind, key) not in self._cache:
            self._cache[(kind, key)] = load()
        return self._cache[(kind, key)]


def _traj_key(trajectory_or_sample: str) -> str:
    parts = trajectory_or_sample.split("/")
    if len(parts) == 3:
        return trajectory_of(trajectory_or_sample)
    if len(parts) != 2 or not all(parts):
        raise ValueError(f"trajectory must look like '<env>/<trajectory>', got {trajectory_or_sample!r}")
    return trajectory_or_sample
