"""A miniature KITTI-360 root in the real layout and encodings (no real data: KITTI-360 is CC BY-NC-SA 3.0).

Names and encodings as github:autonomousvision/kitti360Scripts (commit 40ee015) reads them (see
``airfisheye_bench/io/datasets/kitti360.py``): ``calibration/image_02.yaml`` / ``image_03.yaml`` (OpenCV
FileStorage ``%YAML:1.0``, ``model_type: MEI``; the real intrinsics (:data:`KITTI360`) scaled to a small sensor,
with ``p1 = p2 = 0`` so that the devkit's ``cam2image``, which ignores them, is exact), ``calib_cam_to_pose.txt``
(``image_0X: <12 numbers>``), ``calib_cam_to_velo.txt`` (12 numbers),
``data_2d_raw/<seq>/image_0X/data_rgb/%010d.png`` (8-bit RGB),
``data_3d_raw/<seq>/velodyne_points/data/%010d.bin`` (float32 x y z reflectance, KITTI's firing order: each
laser's revolution contiguous, top laser first, simulated with the ``hdl64e`` preset by
:func:`~.spinning_scans.simulate`), ``timestamps.txt`` (``YYYY-MM-DD HH:MM:SS.nnnnnnnnn``, line k = frame k) and
``data_poses/<seq>/poses.txt`` (frame + 3x4 row-major).

The rig has the real one's geometry (rounded): the GPS/IMU pose frame x forward, y right, z down; image_00 looks
forward, image_02 left, image_03 right; the Velodyne is x forward, y left, z up, 0.8 m behind image_00. The vehicle
drives about 1 m per frame along a gentle curve (turning 0.02 rad per frame); ``timestamps.txt`` steps 0.1 s.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from PIL import Image

from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.transforms import euler_to_matrix, make_transform
from airfisheye_bench.studies.miniature_datasets.spinning_scans import simulate

SEQUENCES = ("2013_05_28_drive_0000_sync", "2013_05_28_drive_0002_sync")
SIZE = 96  # image side in pixels (the real sensor: 1400)
SPEED_M = 1.0  # per frame, along the pose frame's x
YAW_RAD = 0.02  # per frame, about the pose frame's z
T0 = 1369730762.0  # 2013-05-28 08:46:02 UTC

# KITTI-360 calibration/image_02.yaml and image_03.yaml (MEI), the values of the KITTI-360 calibration download as
# reproduced in github:yuliangguo/depth_any_camera (its KITTI-360 fisheye grid script).
KITTI360 = {
    "image_02": {
        "xi": 2.2134047507854890e00,
        "k1": 1.6798235660113681e-02,
        "k2": 1.6548773243373522e00,
        "p1": 4.2223943394772046e-04,
        "p2": 4.2462134260997584e-04,
        "gamma1": 1.3363220825849971e03,
        "gamma2": 1.3357883350012958e03,
        "u0": 7.1694323510126321e02,
        "v0": 7.0576498308221585e02,
    },
    "image_03": {
        "xi": 2.5535139132482758e00,
        "k1": 4.9370396274089505e-02,
        "k2": 4.5068455478645308e00,
        "p1": 1.3477698472982495e-03,
        "p2": -7.0340482615055284e-04,
        "gamma1": 1.4854388981875156e03,
        "gamma2": 1.4849477411748708e03,
        "u0": 6.9888316784030962e02,
        "v0": 6.9814541887723055e02,
    },
}

# Rotations: columns are the camera's x (right), y (down), z (optical axis) in the pose frame (x fwd, y right, z down).
R_POSE_CAM = {
    "image_00": np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
    "image_01": np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
    "image_02": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),  # looks left (-y)
    "image_03": np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]),  # looks right (+y)
}
t_POSE_CAM = {
    "image_00": (1.575, 0.004, -0.650),
    "image_01": (1.582, 0.596, -0.656),
    "image_02": (0.726, -0.150, -1.069),
    "image_03": (0.702, 0.746, -1.075),
}
# image_00 -> Velodyne: camera x -> -y_velo, y -> -z_velo, z -> +x_velo; image_00 0.80 m ahead of the Velodyne.
R_VELO_CAM0 = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
t_VELO_CAM0 = (0.804, 0.299, -0.177)


def tilt(name: str) -> np.ndarray:
    """A small fixed mounting error per sensor (radians), so no transform is an exact axis permutation."""
    seed = sum(map(ord, name))
    return euler_to_matrix(0.01 * math.sin(seed), 0.012 * math.cos(seed), 0.008 * math.sin(2 * seed))


def cam_to_pose() -> dict[str, np.ndarray]:
    return {n: make_transform(R_POSE_CAM[n] @ tilt(n), np.array(t_POSE_CAM[n])) for n in R_POSE_CAM}


def cam0_to_velo() -> np.ndarray:
    return make_transform(R_VELO_CAM0 @ tilt("velodyne"), np.array(t_VELO_CAM0))


def vehicle_pose(frame: int) -> np.ndarray:
    """``T_world_pose`` of a frame: a gentle curve at 10 m/s."""
    yaw = YAW_RAD * frame
    return make_transform(euler_to_matrix(0.0, 0.0, yaw), np.array([SPEED_M * frame, 0.2 * frame**1.5, 0.0]))


def intrinsics(name: str, size: int = SIZE) -> dict[str, float]:
    """The real camera's MEI parameters on a ``size`` sensor (pixel centres scale about the corner)."""
    p = dict(KITTI360[name])
    s = size / 1400.0
    p.update(
        gamma1=p["gamma1"] * s,
        gamma2=p["gamma2"] * s,
        u0=(p["u0"] + 0.5) * s - 0.5,
        v0=(p["v0"] + 0.5) * s - 0.5,
    )
    p.update(p1=0.0, p2=0.0)
    return p


def _row(T: np.ndarray) -> str:
    return " ".join(f"{v:.10f}" for v in T[:3, :4].reshape(-1))


def _stamp(t: float) -> str:
    whole = math.floor(t)
    ns = round((t - whole) * 1e9)
    clock = np.datetime64(int(whole), "s").astype(str).replace("T", " ")
    return f"{clock}.{ns:09d}"


def write_calibration(root: Path, size: int = SIZE) -> None:
    calib = root / "calibration"
    calib.mkdir(parents=True, exist_ok=True)
    for name in ("image_02", "image_03"):
        p = intrinsics(name, size)
        (calib / f"{name}.yaml").write_text(
            "%YAML:1.0\n---\nmodel_type: MEI\n"
            f"camera_name: {name}\nimage_width: {size}\nimage_height: {size}\n"
            f"mirror_parameters:\n   xi: {p['xi']:.16e}\n"
            "distortion_parameters:\n"
            + "".join(f"   {k}: {p[k]:.16e}\n" for k in ("k1", "k2", "p1", "p2"))
            + "projection_parameters:\n"
            + "".join(f"   {k}: {p[k]:.16e}\n" for k in ("gamma1", "gamma2", "u0", "v0"))
        )
    (calib / "calib_cam_to_pose.txt").write_text(
        "".join(f"{name}: {_row(T)}\n" for name, T in cam_to_pose().items())
    )
    (calib / "calib_cam_to_velo.txt").write_text(_row(cam0_to_velo()) + "\n")


def write_kitti360(
    root: Path,
    sequences: tuple[str, ...] = SEQUENCES,
    frames: int = 4,
    unposed: tuple[int, ...] = (2,),
    camera_delay_s: float = 0.0,
    size: int = SIZE,
) -> Path:
    """Write the root: ``frames`` frames per sequence (images, scans, time stamps), poses for all but ``unposed``
    (as poses.txt skips the frames where the vehicle stood), the camera ``camera_delay_s`` after each scan."""
    write_calibration(root, size)
    spec = LidarSpec.from_preset("hdl64e")
    for k, seq in enumerate(sequences):
        times = T0 + 3600.0 * k + 0.1 * np.arange(frames)
        velo = root / "data_3d_raw" / seq / "velodyne_points"
        (velo / "data").mkdir(parents=True, exist_ok=True)
        (velo / "timestamps.txt").write_text("".join(_stamp(t) + "\n" for t in times))
        for frame in range(frames):
            points, ring = simulate(spec, seed=100 * k + frame, order="kitti")
            reflectance = (0.1 + 0.8 * (ring % 7) / 6.0)[:, None]
            np.hstack([points, reflectance]).astype(np.float32).tofile(velo / "data" / f"{frame:010d}.bin")
        for name in ("image_02", "image_03"):
            cam = root / "data_2d_raw" / seq / name
            (cam / "data_rgb").mkdir(parents=True, exist_ok=True)
            (cam / "timestamps.txt").write_text("".join(_stamp(t + camera_delay_s) + "\n" for t in times))
            for frame in range(frames):
                Image.fromarray(image(frame + 10 * k, size)).save(cam / "data_rgb" / f"{frame:010d}.png")
        poses = root / "data_poses" / seq
        poses.mkdir(parents=True, exist_ok=True)
        (poses / "poses.txt").write_text(
            "".join(f"{f} {_row(vehicle_pose(f))}\n" for f in range(frames) if f not in unposed)
        )
    return root


def image(seed: int, size: int = SIZE) -> np.ndarray:
    """``uint8 [size, size, 3]``: a smooth pattern, different per frame."""
    v, u = np.mgrid[0:size, 0:size]
    r = (u * 255 // max(size - 1, 1) + seed * 13) % 256
    g = (v * 255 // max(size - 1, 1) + seed * 29) % 256
    b = ((u + v) * 127 // max(size - 1, 1) + seed * 7) % 256
    return np.stack([r, g, b], axis=-1).astype(np.uint8)
