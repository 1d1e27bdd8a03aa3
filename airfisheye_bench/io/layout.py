"""Paths of every file of a dataset, from the templates in ``dataset.yaml`` (``layout``)."""

from __future__ import annotations

from pathlib import Path

from airfisheye_bench.geometry.cubemap import FACE_NAMES
from airfisheye_bench.io.dataset_spec import DATASET_YAML, DEFAULT_LAYOUT, FileEncodings
from airfisheye_bench.io.splits import parse_sample_id

MODALITIES = ("rgb", "seg", "depth")
MANIFEST_NAME = "manifest.json"
#: The generator's preview image at the dataset root: a view of the data, not part of it (not in the manifest).
CONTACT_SHEET_NAME = "contact_sheet.png"


class DatasetLayout:
    """Builds file paths; knows nothing about file contents.

    Args:
        root: Dataset root folder.
        templates: Path templates (``DatasetSpec.layout``); defaults to :data:`DEFAULT_LAYOUT`.
        files: File encodings (decide the extensions of image/label/depth files).

    Example:
        >>> layout = DatasetLayout("/data")
        >>> layout.cubemap("suburban/traj00/000003", "left", "depth").as_posix()
        '/data/suburban/traj00/cubemap/left/depth/000003.png'
        >>> layout.lidar("suburban/traj00/000003").as_posix()
        '/data/suburban/traj00/lidar/000003.npy'
    """

    def __init__(
        self, root: str | Path, templates: dict[str, str] | None = None, files: FileEncodings | None = None
    ) -> None:
        self.root = Path(root)
        self.templates = dict(DEFAULT_LAYOUT if templates is None else templates)
        self.files = files or FileEncodings()

    # ------------------------------------------------------------------------------ dataset level
    @property
    def dataset_yaml(self) -> Path:
        return self.root / DATASET_YAML

    @property
    def manifest(self) -> Path:
        return self.root / MANIFEST_NAME

    def split_file(self, relpath: str) -> Path:
        return self.root / relpath

    # --------------------------------------------------------------------------- trajectory level
    def _traj(self, kind: str, trajectory: str) -> Path:
        env, traj = _parse_trajectory(trajectory)
        return self.root / self.templates[kind].format(env=env, traj=traj)

    def calib(self, trajectory: str) -> Path:
        """``calib.yaml`` of ``"<env>/<traj>"``."""
        return self._traj("calib", trajectory)

    def poses(self, trajectory: str) -> Path:
        return self._traj("poses", trajectory)

    def imu(self, trajectory: str) -> Path:
        return self._traj("imu", trajectory)

    def lidar_scan(self, trajectory: str) -> Path:
        """``lidar_scan.csv`` (per-frame scan phase) of ``"<env>/<traj>"``."""
        return self._traj("lidar_scan", trajectory)

    # -------------------------------------------------------------------------------- frame level
    def cubemap(self, sample_id: str, face: str, modality: str) -> Path:
        """One cube-face file of ``"<env>/<traj>/<frame>"``."""
        if face not in FACE_NAMES:
            raise ValueError(f"face must be one of {FACE_NAMES}, got {face!r}")
        env, traj, frame = parse_sample_id(sample_id)
        ext = self.files.extension(modality)
        return self.root / self.templates["cubemap"].format(
            env=env, traj=traj, frame=frame, face=face, modality=modality, ext=ext
        )

    def fisheye(self, sample_id: str, modality: str) -> Path:
        """One pre-rendered fisheye file of ``"<env>/<traj>/<frame>"``."""
        env, traj, frame = parse_sample_id(sample_id)
        ext = self.files.extension(modality)
        return self.root / self.templates["fisheye"].format(
            env=env, traj=traj, frame=frame, modality=modality, ext=ext
        )

    def lidar(self, sample_id: str) -> Path:
        env, traj, frame = parse_sample_id(sample_id)
        return self.root / self.templates["lidar"].format(env=env, traj=traj, frame=frame)

    def lidar_visible(self, sample_id: str) -> Path:
        env, traj, frame = parse_sample_id(sample_id)
        return self.root / self.templates["lidar_visible"].format(env=env, traj=traj, frame=frame)

    def lidar_beam(self, sample_id: str) -> Path:
        env, traj, frame = parse_sample_id(sample_id)
        return self.root / self.templates["lidar_beam"].format(env=env, traj=traj, frame=frame)


def _parse_trajectory(trajectory: str) -> tuple[str, str]:
    parts = trajectory.split("/")
    if len(parts) == 3:  # a sample id names its trajectory too
        parts = parts[:2]
    if len(parts) != 2 or not all(parts):
        raise ValueError(f"trajectory must look like '<env>/<trajectory>', got {trajectory!r}")
    return parts[0], parts[1]


def trajectory_of(sample_id: str) -> str:
    """``"<env>/<traj>"`` of a sample id."""
    env, traj, _ = parse_sample_id(sample_id)
    return f"{env}/{traj}"


#: A trajectory's calibration file in the default layout (``<env>/<traj>/calib.yaml``).
_CALIB_YAML = Path(DEFAULT_LAYOUT["calib"]).name


def calibration_beside(path: Path, levels: int = 3) -> Path | None:
    """The ``calib.yaml`` of the dataset trajectory that the frames at ``path`` belong to (its folder or one of the
    ``levels`` above it, in a folder that a ``dataset.yaml`` above says is a dataset), or ``None``.

    The AirFisheye layout keeps a trajectory's lens in ``<env>/<traj>/calib.yaml`` and its frames in
    ``<env>/<traj>/fisheye/rgb/`` (``docs/design.md``, "On-disk dataset layout"): predicting on those frames needs
    no ``camera=``.
    """
    folder = path if path.is_dir() else path.parent
    for candidate in [folder, *folder.parents][: levels + 1]:
        calib = candidate / _CALIB_YAML
        if calib.is_file() and any((up / DATASET_YAML).is_file() for up in candidate.parents):
            return calib
    return None
