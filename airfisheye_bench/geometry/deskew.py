"""Ego-motion compensation of one spinning-LiDAR scan ("curling"), as the KITTI-360 devkit does it.

A scan is recorded over one revolution while the vehicle moves, so its raw points mix the sensor's poses of the
whole revolution. The KITTI-360 devkit (github:autonomousvision/kitti360Scripts, commit 40ee015,
``kitti360scripts/helpers/curlVelodyneData_impl.c`` ``curl_velodyne_data``, called with the parameters of
``kitti360scripts/devkits/accumuLaser/src/accumulation.cpp`` ``CurlParametersFromPoses`` and of
``kitti360scripts/viewer/kitti360Viewer3DRaw.py`` ``curlParameterFromPoses``) moves every point ``p`` by a fraction
``s`` of the motion ``D`` between two scans, expressed in the LiDAR frame::

    r, t = Rodrigues(R_D), t_D
    p' = Rot(s r) p + s t,          s = atan2(p_y, p_x) / (2 pi)       (in [-1/2, 1/2])

``D = T_velo(f)^-1 T_velo(f-1)`` maps the previous scan's frame into the current one, so a point of azimuth
``a`` is treated as recorded ``a / (2 pi)`` of a revolution *before* the sensor faced forward (``a = 0``): the
HDL-64E turns clockwise seen from above, and the camera is triggered when it faces forward. After curling, the
scan is in the LiDAR frame at that forward-facing instant. :func:`curl_points` is that formula with a per-point
``s`` (the caller may derive it from time stamps instead of azimuth alone); :func:`scan_fraction` is the devkit's
``s``.

Example:
    >>> import numpy as np
    >>> D = np.eye(4); D[0, 3] = 1.0                     # the sensor moved 1 m along x since the last scan
    >>> pts = np.array([[0.0, 10.0, 0.0], [0.0, -10.0, 0.0], [10.0, 0.0, 0.0]])  # left, right, ahead
    >>> curl_points(pts, D, scan_fraction(pts)).round(6).tolist()
    [[0.25, 10.0, 0.0], [-0.25, -10.0, 0.0], [10.0, 0.0, 0.0]]
"""

from __future__ import annotations

import math

import numpy as np

from airfisheye_bench.geometry.transforms import make_transform, matrix_to_quaternion


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """Axis times angle (radians) of a rotation matrix ``[3, 3]`` (OpenCV's ``Rodrigues`` of a matrix).

    Example:
        >>> c, s = math.cos(0.3), math.sin(0.3)
        >>> rotation_vector(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])).round(9).tolist()
        [0.0, 0.0, 0.3]
    """
    q = matrix_to_quaternion(np.asarray(R, np.float64))  # w >= 0: the angle is in [0, pi]
    v = q[1:]
    norm = float(np.linalg.norm(v))
    if norm < 1e-15:
        return np.zeros(3)
    return v * (2.0 * math.atan2(norm, float(q[0])) / norm)


def rotation_from_vector(r: np.ndarray) -> np.ndarray:
    """The rotation matrix of an axis-angle vector (inverse of :func:`rotation_vector`).

    Example:
        >>> rotation_from_vector(np.array([0.0, 0.0, math.pi / 2])).round(9).tolist()[0]
        [0.0, -1.0, 0.0]
    """
    r = np.asarray(r, np.float64)
    theta = float(np.linalg.norm(r))
    if theta < 1e-15:
        return np.eye(3)
    k = r / theta
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(theta) * K + (1.0 - math.cos(theta)) * (K @ K)


def scan_fraction(points: np.ndarray) -> np.ndarray:
    """The devkit's ``s = atan2(y, x) / (2 pi)`` of every point ``[N, 3]`` (LiDAR frame, FLU): ``float64 [N]``."""
    p = np.asarray(points, np.float64)
    return np.arctan2(p[:, 1], p[:, 0]) / (2.0 * math.pi)


def fraction_transform(D: np.ndarray, s: float) -> np.ndarray:
    """``[4, 4]`` the devkit's fraction ``s`` of the motion ``D``: ``[Rot(s r) | s t]`` (what one point moves by)."""
    D = np.asarray(D, np.float64)
    return make_transform(rotation_from_vector(s * rotation_vector(D[:3, :3])), s * D[:3, 3])


def curl_points(points: np.ndarray, D: np.ndarray, fraction: np.ndarray) -> np.ndarray:
    """Move each point ``[N, 3]`` by its ``fraction [N]`` of the motion ``D [4, 4]`` (see the module docstring).

    The vectorised form of the devkit's ``curl_velodyne_data``: Rodrigues' formula with the common axis of
    ``D``'s rotation and the per-point angle ``s |r|``, plus ``s t``. Returns ``float64 [N, 3]``.
    """
    p = np.asarray(points, np.float64)
    s = np.asarray(fraction, np.float64)[:, None]
    D = np.asarray(D, np.float64)
    r, t = rotation_vector(D[:3, :3]), D[:3, 3]
    angle = float(np.linalg.norm(r))
    out = p + s * t
    if angle <= 1e-10:  # the devkit's threshold: a translation only
        return out
    k = r / angle
    theta = s * angle
    cos, sin = np.cos(theta), np.sin(theta)
    kv = p @ k
    return out + p * (cos - 1.0) + np.cross(k, p) * sin + k[None, :] * (kv[:, None] * (1.0 - cos))


__all__ = ["curl_points", "fraction_transform", "rotation_from_vector", "rotation_vector", "scan_fraction"]
