"""``poses.csv`` (body pose at each sensor's own timestamp) and ``imu.csv``, plus motion compensation.

``poses.csv`` has one row per frame::

    frame,t_cam,cam_tx,cam_ty,cam_tz,cam_qw,cam_qx,cam_qy,cam_qz,t_lidar,lidar_tx,...,lidar_qz

``cam_*`` is ``T_world_body`` at ``t_cam`` (when the camera exposed), ``lidar_*`` is ``T_world_body`` at
``t_lidar`` (when the LiDAR scanned); quaternions are ``w, x, y, z``. Because the two timestamps differ while the
drone moves, the LiDAR-to-camera transform of a frame is

    ``T_cam_lidar = (T_world_body(t_cam) @ T_body_cam)^-1 @ T_world_body(t_lidar) @ T_body_lidar``

(:func:`camera_from_lidar`), not the static ``T_body_cam^-1 @ T_body_lidar``.

``imu.csv`` has columns ``t, ax, ay, az, wx, wy, wz``: specific force (acceleration minus gravity, m/s^2) and
angular rate (rad/s), both in the body frame (FLU), at the IMU rate.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.geometry.transforms import (
    make_transform,
    matrix_to_quaternion,
    quaternion_to_matrix,
    relative_transform,
)
from airfisheye_bench.io.errors import DatasetFormatError

_POSE_FIELDS = ("tx", "ty", "tz", "qw", "qx", "qy", "qz")
POSES_HEADER = (
    "frame",
    "t_cam",
    *(f"cam_{f}" for f in _POSE_FIELDS),
    "t_lidar",
    *(f"lidar_{f}" for f in _POSE_FIELDS),
)
IMU_HEADER = ("t", "ax", "ay", "az", "wx", "wy", "wz")


def _pose_to_row(T: np.ndarray) -> np.ndarray:
    return np.concatenate([T[..., :3, 3], matrix_to_quaternion(T[..., :3, :3])], axis=-1)


def _row_to_pose(row: np.ndarray) -> np.ndarray:
    return make_transform(quaternion_to_matrix(row[..., 3:7]), row[..., :3])


@dataclass
class PoseTable:
    """Per-frame body poses of one trajectory.

    Attributes:
        frames: Frame names (``"000000"``...), in file order.
        t_cam: ``[N]`` camera timestamps (s).
        T_world_body_cam: ``[N, 4, 4]`` body pose at ``t_cam``.
        t_lidar: ``[N]`` LiDAR timestamps (s).
        T_world_body_lidar: ``[N, 4, 4]`` body pose at ``t_lidar``.

    Example:
        >>> import numpy as np
        >>> T = np.tile(np.eye(4), (2, 1, 1))
        >>> table = PoseTable(["000000", "000001"], np.array([0.0, 0.1]), T, np.array([0.03, 0.13]), T)
        >>> table.index("000001")
        1
    """

    frames: list[str]
    t_cam: np.ndarray
    T_world_body_cam: np.ndarray
    t_lidar: np.ndarray
    T_world_body_lidar: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.frames)
        for name in ("t_cam", "t_lidar"):
            arr = np.asarray(getattr(self, name), np.float64)
            if arr.shape != (n,):
                raise ValueError(f"{name} must have shape [{n}], got {list(arr.shape)}")
            setattr(self, name, arr)
        for name in ("T_world_body_cam", "T_world_body_lidar"):
            arr = np.asarray(getattr(self, name), np.float64)
            if arr.shape != (n, 4, 4):
                raise ValueError(f"{name} must have shape [{n}, 4, 4], got {list(arr.shape)}")
            setattr(self, name, arr)
        if len(set(self.frames)) != n:
            raise ValueError("frames must be unique")
        self._index = {f: i for i, f in enumerate(self.frames)}

    def __len__(self) -> int:
        return len(self.frames)

    def index(self, frame: str) -> int:
        """Row of ``frame``; ``KeyError`` naming it if absent."""
        try:
            return self._index[frame]
        except KeyError:
            raise KeyError(f"frame {frame!r} is not in the pose table") from None

    def save(self, path: str | Path) -> None:
        """Atomically write ``poses.csv`` (fixed 9/12-decimal formatting, so output is deterministic)."""
        cam = _pose_to_row(self.T_world_body_cam)
        lid = _pose_to_row(self.T_world_body_lidar)
        lines = [",".join(POSES_HEADER)]
        for i, frame in enumerate(self.frames):
            vals = [f"{self.t_cam[i]:.9f}", *_fmt_pose(cam[i]), f"{self.t_lidar[i]:.9f}", *_fmt_pose(lid[i])]
            lines.append(",".join([frame, *vals]))
        atomic_write_text(path, "\n".join(lines) + "\n")

    @classmethod
    def load(cls, path: str | Path) -> PoseTable:
        """Read ``poses.csv``; errors name the file and the line."""
        path = Path(path)
        rows = _read_csv(path, POSES_HEADER, first_column_str=True)
        frames = [r[0] for r in rows]
        values = np.array([[float(v) for v in r[1:]] for r in rows], np.float64).reshape(len(rows), 16)
        try:
            return cls(
                frames,
                values[:, 0],
                _row_to_pose(values[:, 1:8]),
                values[:, 8],
                _row_to_pose(values[:, 9:16]),
            )
        except ValueError as exc:
            raise DatasetFormatError(path, str(exc)) from None


def _fmt_pose(row: np.ndarray) -> list[str]:
    return [f"{v + 0.0:.9f}" for v in np.round(row[:3], 9)] + [
        f"{v + 0.0:.12f}" for v in np.round(row[3:], 12)
    ]


def camera_from_lidar(poses: PoseTable, T_body_cam: np.ndarray, T_body_lidar: np.ndarray) -> np.ndarray:
    """Motion-compensated ``T_cam_lidar`` per frame, ``[N, 4, 4]``.

    Each sensor's pose is taken at its own timestamp:
    ``T_cam_lidar = (T_world_body(t_cam) T_body_cam)^-1 T_world_body(t_lidar) T_body_lidar``.

    Example:
        >>> import numpy as np
        >>> from airfisheye_bench.geometry.transforms import make_transform
        >>> T0 = make_transform(np.eye(3), np.zeros(3)); T1 = make_transform(np.eye(3), np.array([1.0, 0, 0]))
        >>> table = PoseTable(["000000"], np.array([0.0]), T0[None], np.array([0.05]), T1[None])
        >>> camera_from_lidar(table, np.eye(4), np.eye(4))[0, :3, 3].tolist()  # the body moved 1 m forward
        [1.0, 0.0, 0.0]
    """
    T_world_cam = poses.T_world_body_cam @ np.asarray(T_body_cam, np.float64)
    T_world_lidar = poses.T_world_body_lidar @ np.asarray(T_body_lidar, np.float64)
    return relative_transform(T_world_cam, T_world_lidar)


@dataclass
class ImuTable:
    """IMU samples of one trajectory: ``t [N]`` (s), ``accel [N, 3]`` specific force and ``gyro [N, 3]`` angular rate,
    body frame (FLU).

    Example:
        >>> import numpy as np
        >>> imu = ImuTable(np.arange(3) * 0.01, np.tile([0.0, 0.0, 9.81], (3, 1)), np.zeros((3, 3)))
        >>> imu.rate_hz
        100.0
    """

    t: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, np.float64)
        n = self.t.shape[0]
        if self.t.ndim != 1:
            raise ValueError(f"t must have shape [N], got {list(self.t.shape)}")
        for name in ("accel", "gyro"):
            arr = np.asarray(getattr(self, name), np.float64)
            if arr.shape != (n, 3):
                raise ValueError(f"{name} must have shape [{n}, 3], got {list(arr.shape)}")
            setattr(self, name, arr)
        if n > 1 and not (np.diff(self.t) > 0).all():
            raise ValueError("t must be strictly increasing")

    @property
    def rate_hz(self) -> float:
        return float(np.round(1.0 / np.median(np.diff(self.t)), 6)) if len(self.t) > 1 else 0.0

    def save(self, path: str | Path) -> None:
        """Atomically write ``imu.csv``."""
        # Rounding then adding +0.0 turns tiny negatives into +0.0, so no "-0.000000000" appears in the file.
        data = np.round(np.concatenate([self.t[:, None], self.accel, self.gyro], axis=1), 9) + 0.0
        buf = io.StringIO()
        np.savetxt(
            buf, data, fmt=["%.6f"] + ["%.9f"] * 6, delimiter=",", header=",".join(IMU_HEADER), comments=""
        )
        atomic_write_text(path, buf.getvalue())

    @classmethod
    def load(cls, path: str | Path) -> ImuTable:
        path = Path(path)
        rows = _read_csv(path, IMU_HEADER, first_column_str=False)
        data = np.array(rows, np.float64).reshape(len(rows), 7)
        try:
            return cls(data[:, 0], data[:, 1:4], data[:, 4:7])
        except ValueError as exc:
            raise DatasetFormatError(path, str(exc)) from None


def _read_csv(path: Path, header: tuple[str, ...], first_column_str: bool) -> list[list]:
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise DatasetFormatError(path, "file does not exist") from None
    if not lines or tuple(c.strip() for c in lines[0].split(",")) != header:
        raise DatasetFormatError(path, f"first line must be the header {','.join(header)}", key="line 1")
    rows: list[list] = []
    for lineno, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        cells = [c.strip() for c in line.split(",")]
        if len(cells) != len(header):
            raise DatasetFormatError(
                path, f"expected {len(header)} columns, got {len(cells)}", key=f"line {lineno}"
            )
        try:
            start = 1 if first_column_str else 0
            nums = [float(c) for c in cells[start:]]
        except ValueError:
            raise DatasetFormatError(path, "non-numeric value", key=f"line {lineno}") from None
        if not np.isfinite(nums).all():
            raise DatasetFormatError(path, "non-finite value", key=f"line {lineno}")
        rows.append(([cells[0]] if first_column_str else []) + nums)
    return rows
