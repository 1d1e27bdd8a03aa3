"""Analytic scenes for the occlusion tests: boxes, a scan cast against them, a camera rig, and exact visibility."""

from __future__ import annotations

import math

import numpy as np
import torch

from airfisheye_bench.geometry import CAM_FROM_FLU, euler_to_matrix, make_transform
from airfisheye_bench.geometry.lidar import LidarSpec


def ray_box_entry(origin: np.ndarray, dirs: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Distance along unit rays to the first axis-aligned box they enter (slab test); inf if none."""
    t = np.full(len(dirs), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
        for lo, hi in boxes:
            t1, t2 = (lo - origin) * inv, (hi - origin) * inv
            near = np.nan_to_num(np.minimum(t1, t2), nan=-np.inf).max(axis=1)
            far = np.nan_to_num(np.maximum(t1, t2), nan=np.inf).min(axis=1)
            t = np.where((near <= far) & (far > 0), np.minimum(t, np.maximum(near, 0.0)), t)
    return t


def cast_scan(spec: LidarSpec, boxes: np.ndarray) -> np.ndarray:
    """A realistic scan: the spec's own beams cast from the origin against the boxes."""
    dirs = spec.beam_directions(torch.float64).reshape(-1, 3).numpy()
    t = ray_box_entry(np.zeros(3), dirs, boxes)
    return dirs[t <= spec.max_range] * t[t <= spec.max_range, None]


def rig(offset, pitch_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Camera centre (LiDAR frame) and ``T_cam_lidar`` of a camera looking along LiDAR x, pitched down."""
    centre = np.asarray(offset, dtype=np.float64)
    R = (euler_to_matrix(0.0, math.radians(pitch_deg), 0.0) @ CAM_FROM_FLU.T).T
    return centre, make_transform(R, -R @ centre)


def seen_from(points: np.ndarray, centre: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Exact visibility: the ray from the camera centre enters no box before reaching the point."""
    v = points - centre
    dist = np.linalg.norm(v, axis=1)
    return ray_box_entry(centre, v / dist[:, None], boxes) >= dist * (1 - 1e-9) - 1e-9
