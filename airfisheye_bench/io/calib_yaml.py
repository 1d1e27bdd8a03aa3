"""``calib.yaml``: per-trajectory sensor calibration.

Contents: the fisheye camera (its flat dict, ``CameraModel.to_dict()``: any model of ``geometry/cameras/``; a
calibration file of another tool becomes one with :func:`~airfisheye_bench.io.calibration_files.load_camera`), the
cube-face size, the body -> sensor extrinsics
``T_body_cam`` and ``T_body_lidar`` (4x4, mapping sensor-frame points to the body frame) and the LiDAR
specification (``LidarSpec.to_dict``). Anything else is kept under ``extras`` (e.g. the gimbal pitch).

Example:
    >>> import numpy as np, tempfile, pathlib
    >>> calib = Calibration(camera={"width": 64, "height": 64}, face_size=32,
    ...                     T_body_cam=np.eye(4), T_body_lidar=np.eye(4), lidar={"channels": 16})
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "calib.yaml"
    >>> calib.save(p)
    >>> Calibration.load(p).face_size
    32
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from airfisheye_bench.geometry import camera_from_dict
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.transforms import check_rigid, relative_transform
from airfisheye_bench.io.yamlio import FieldReader, read_yaml, write_yaml

_KNOWN_KEYS = {"camera", "cubemap", "T_body_cam", "T_body_lidar", "lidar"}


@dataclass
class Calibration:
    """Sensor calibration of one trajectory.

    Attributes:
        camera: ``to_dict()`` of the (pre-rendered) fisheye camera, any camera model.
        face_size: Cube-face size in pixels (``None`` if the trajectory has no cube faces).
        T_body_cam: ``[4, 4]`` camera (OpenCV axes) -> body (FLU).
        T_body_lidar: ``[4, 4]`` LiDAR (FLU axes) -> body.
        lidar: ``LidarSpec.to_dict()``.
        extras: Other top-level keys (informational).
    """

    camera: dict
    face_size: int | None
    T_body_cam: np.ndarray
    T_body_lidar: np.ndarray
    lidar: dict
    extras: dict = field(default_factory=dict)

    def fisheye_camera(self):
        """The camera described by ``camera`` (``camera_from_dict``: any model)."""
        return camera_from_dict(self.camera)

    def lidar_spec(self):
        """The :class:`~airfisheye_bench.geometry.lidar.LidarSpec` described by ``lidar``."""
        return LidarSpec.from_dict(self.lidar)

    @property
    def T_cam_lidar_static(self) -> np.ndarray:
        """``T_cam_lidar`` for a stationary platform (no motion between the two sensors' timestamps)."""
        return relative_transform(self.T_body_cam, self.T_body_lidar)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"camera": dict(self.camera)}
        if self.face_size is not None:
            out["cubemap"] = {"face_size": int(self.face_size)}
        out["T_body_cam"] = np.asarray(self.T_body_cam, np.float64).tolist()
        out["T_body_lidar"] = np.asarray(self.T_body_lidar, np.float64).tolist()
        out["lidar"] = dict(self.lidar)
        out.update(self.extras)
        return out

    def save(self, path: str | Path) -> None:
        """Atomically write ``calib.yaml``."""
        write_yaml(
            path, self.to_dict(), header="Sensor calibration. T_a_b maps points in frame b to frame a."
        )

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        """Read and validate ``calib.yaml``; errors name the file and key."""
        return cls.from_dict(read_yaml(path), path)

    @classmethod
    def from_dict(cls, data: dict, path: str | Path = "calib.yaml") -> Calibration:
        r = FieldReader(path, data)
        camera = r.mapping("camera")
        for key in ("width", "height"):
            r.int(f"camera.{key}", minimum=1)
        face_size = r.int("cubemap.face_size", minimum=1) if "cubemap" in data else None
        mats = {}
        for key in ("T_body_cam", "T_body_lidar"):
            mats[key] = r.matrix(key, (4, 4))
            try:
                check_rigid(mats[key], key)
            except ValueError as exc:
                raise r.error(key, str(exc)) from None
        lidar = r.mapping("lidar")
        # Validate the sensor models with their own constructors so that errors point at the right key.

        for key, build, value in (
            ("camera", camera_from_dict, camera),
            ("lidar", LidarSpec.from_dict, lidar),
        ):
            try:
                build(value)
            except (TypeError, ValueError) as exc:
                raise r.error(key, f"invalid description ({exc})") from None
        extras = {k: v for k, v in data.items() if k not in _KNOWN_KEYS}
        return cls(camera, face_size, mats["T_body_cam"], mats["T_body_lidar"], lidar, extras)
