"""The KITTI-360 devkit's own formulas, re-implemented line by line and not through the project's code: the
reference the reader of ``data.format=kitti360`` is checked against (``tests/io/datasets/test_kitti360.py``) and the
curl is timed against (``scripts/bench_kitti360.py``).

The devkit's code re-implemented (github:autonomousvision/kitti360Scripts, commit 40ee015):

- ``kitti360scripts/devkits/commons/loadCalibration.py``: ``loadCalibrationCameraToPose`` (``readVariable``: the
  first line starting with the camera's name, 12 numbers), ``loadCalibrationRigid`` (``np.loadtxt().reshape(3, 4)``).
- ``kitti360scripts/viewer/kitti360Viewer3DRaw.py`` ``loadExtrinsics``: ``TrVeloToPose = TrCamToPose['image_00'] @
  inv(TrCam0ToVelo)``; ``TrVeloToCam[k] = inv(TrCam0ToVelo @ inv(TrCamToPose['image_00']) @ TrCamToPose[k])``.
- ``kitti360scripts/helpers/project.py`` ``CameraFisheye.cam2image``: unit sphere, ``x /= z + xi``, ``ro2``,
  ``x *= 1 + k1 ro2 + k2 ro2^2``, ``gamma1 x + u0``; depth = ``norm * sign(z)``.
- ``kitti360scripts/helpers/curlVelodyneData_impl.c`` ``curl_velodyne_data`` with the parameters of
  ``kitti360scripts/devkits/accumuLaser/src/accumulation.cpp`` ``CurlParametersFromPoses``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

__all__ = [
    "devkit_cam2image",
    "devkit_curl",
    "devkit_read_variable",
    "devkit_velo_to_cam",
    "devkit_velo_to_pose",
    "rodrigues",
]


def devkit_read_variable(path: Path, name: str) -> np.ndarray:
    for line in path.read_text().splitlines():
        if line.startswith(name):
            values = [float(x) for x in line.replace(f"{name}:", "").split()]
            return np.vstack([np.array(values).reshape(3, 4), [0, 0, 0, 1]])
    raise AssertionError(name)


def devkit_velo_to_cam(root: Path, cam: str) -> np.ndarray:
    to_pose = {
        c: devkit_read_variable(root / "calibration/calib_cam_to_pose.txt", c) for c in ("image_00", cam)
    }
    cam0_to_velo = np.vstack(
        [np.loadtxt(root / "calibration/calib_cam_to_velo.txt").reshape(3, 4), [0, 0, 0, 1]]
    )
    camk_to_cam0 = np.linalg.inv(to_pose["image_00"]) @ to_pose[cam]
    return np.linalg.inv(cam0_to_velo @ camk_to_cam0)


def devkit_velo_to_pose(root: Path) -> np.ndarray:
    cam0_to_velo = np.vstack(
        [np.loadtxt(root / "calibration/calib_cam_to_velo.txt").reshape(3, 4), [0, 0, 0, 1]]
    )
    return devkit_read_variable(root / "calibration/calib_cam_to_pose.txt", "image_00") @ np.linalg.inv(
        cam0_to_velo
    )


def devkit_cam2image(root: Path, cam: str, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    fi = {}
    for line in (root / f"calibration/{cam}.yaml").read_text().splitlines():
        key, _, value = line.strip().partition(":")
        if key in ("xi", "k1", "k2", "gamma1", "gamma2", "u0", "v0"):
            fi[key] = float(value)
    norm = np.linalg.norm(points, axis=1)
    x, y, z = (points[:, i] / norm for i in range(3))
    x = x / (z + fi["xi"])
    y = y / (z + fi["xi"])
    ro2 = x * x + y * y
    x = x * (1 + fi["k1"] * ro2 + fi["k2"] * ro2 * ro2)
    y = y * (1 + fi["k1"] * ro2 + fi["k2"] * ro2 * ro2)
    return (
        fi["gamma1"] * x + fi["u0"],
        fi["gamma2"] * y + fi["v0"],
        norm * points[:, 2] / np.abs(points[:, 2]),
    )


def rodrigues(R: np.ndarray) -> np.ndarray:
    """cv::Rodrigues of a rotation matrix (angle in (0, pi))."""
    angle = math.acos(max(-1.0, min(1.0, (np.trace(R) - 1.0) / 2.0)))
    if angle < 1e-12:
        return np.zeros(3)
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / (2.0 * math.sin(angle))
    return axis * angle


def devkit_curl(root: Path, seq: str, frame: int, pcd: np.ndarray) -> np.ndarray:
    poses = np.loadtxt(root / "data_poses" / seq / "poses.txt")
    world = {int(row[0]): np.vstack([row[1:].reshape(3, 4), [0, 0, 0, 1]]) for row in poses}
    tr = np.eye(4)
    if frame == 0:
        if frame + 1 in world:
            tr = np.linalg.inv(world[frame + 1]) @ world[frame]
    elif frame - 1 in world:
        tr = np.linalg.inv(world[frame]) @ world[frame - 1]
    velo_pose = devkit_velo_to_pose(root)
    delta = np.linalg.inv(velo_pose) @ tr @ velo_pose
    r, t = rodrigues(delta[:3, :3]), delta[:3, 3]
    out = np.empty_like(pcd)
    for i, (vx, vy, vz) in enumerate(pcd):
        s = 0.5 * math.atan2(vy, vx) / math.pi
        rx, ry, rz = s * r
        tx, ty, tz = s * t
        theta = math.sqrt(rx * rx + ry * ry + rz * rz)
        if theta > 1e-10:
            kx, ky, kz = rx / theta, ry / theta, rz / theta
            ct, st = math.cos(theta), math.sin(theta)
            kv = kx * vx + ky * vy + kz * vz
            out[i] = (
                vx * ct + (ky * vz - kz * vy) * st + kx * kv * (1 - ct) + tx,
                vy * ct + (kz * vx - kx * vz) * st + ky * kv * (1 - ct) + ty,
                vz * ct + (kx * vy - ky * vx) * st + kz * kv * (1 - ct) + tz,
            )
        else:
            out[i] = (vx + tx, vy + ty, vz + tz)
    return out
