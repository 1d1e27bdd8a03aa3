"""The benchmarks' analytic LiDAR scene: boxes scanned by a ``LidarSpec``'s beams, with exact visibility.

A structured synthetic scene (ground, buildings, poles, near floating obstacles; axis-aligned boxes) or the
issue's boxes-and-wall scene is scanned by casting the beams of a ``LidarSpec`` from the origin; the exact
visibility of every point from a camera centre is a ray-box test. ``scripts/bench_lidar.py``,
``scripts/bench_occlusion_memory.py``, ``scripts/bench_lidar_rings.py`` and the occlusion tests share it.
``scan``'s variants move the beams as a real spinning LiDAR's: ``boundary`` (every beam half a column off),
``ring phase`` (a random azimuth phase per ring), ``jitter`` (ring phase plus 0.1 cell of noise per beam in
azimuth and elevation, 5% of returns dropped) and ``shuffled`` (the nominal beams in a random order).
"""

from __future__ import annotations

import math

import numpy as np
import torch

from airfisheye_bench.geometry import CAM_FROM_FLU, euler_to_matrix, make_transform
from airfisheye_bench.geometry.lidar import LidarSpec

__all__ = ["BOXES_AND_WALL", "SCENES", "camera_rig", "ray_box_entry", "scan", "structured_scene", "visible"]


def ray_box_entry(origin: np.ndarray, dirs: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Distance along unit rays ``dirs [N, 3]`` from ``origin`` into the first box ``[M, 2, 3]`` (inf: none).

    Slab test; a ray starting inside a box enters it at distance 0.
    """
    t = np.full(len(dirs), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
        for lo, hi in boxes:  # a loop over boxes (tens), vectorised over rays
            t1, t2 = (lo - origin) * inv, (hi - origin) * inv
            near = np.nan_to_num(np.minimum(t1, t2), nan=-np.inf).max(axis=1)
            far = np.nan_to_num(np.maximum(t1, t2), nan=np.inf).min(axis=1)
            hit = (near <= far) & (far > 0)
            t = np.where(hit, np.minimum(t, np.maximum(near, 0.0)), t)
    return t


def structured_scene(seed: int = 0) -> np.ndarray:
    """Boxes ``[M, 2, 3]`` (min, max corners) in the LiDAR frame; the LiDAR flies 6 m above the ground."""
    rng = np.random.default_rng(seed)
    boxes = [((-150.0, -150.0, -7.0), (150.0, 150.0, -6.0))]  # ground
    while len(boxes) < 26:  # buildings
        cx, cy = rng.uniform(-60, 60, 2)
        sx, sy = rng.uniform(3, 12, 2)
        if abs(cx) > sx / 2 + 8 or abs(cy) > sy / 2 + 8:
            boxes.append(
                ((cx - sx / 2, cy - sy / 2, -6.0), (cx + sx / 2, cy + sy / 2, -6.0 + rng.uniform(3, 25)))
            )
    while len(boxes) < 56:  # poles and trunks
        cx, cy = rng.uniform(-25, 25, 2)
        w = rng.uniform(0.2, 0.6)
        if max(abs(cx), abs(cy)) > 2:
            boxes.append(
                ((cx - w / 2, cy - w / 2, -6.0), (cx + w / 2, cy + w / 2, -6.0 + rng.uniform(4, 12)))
            )
    for _ in range(6):  # near floating obstacles (branches, signs), 2-7 m ahead
        x, y, z = rng.uniform(2, 6), rng.uniform(-4, 4), rng.uniform(-3, 0)
        boxes.append(
            ((x, y, z), (x + rng.uniform(0.2, 1.0), y + rng.uniform(0.2, 2.0), z + rng.uniform(0.3, 1.5)))
        )
    return np.asarray(boxes, dtype=np.float64)


#: The issue's analytic scene: a wall 20 m ahead, three boxes 5-14 m ahead, the ground 3 m below the LiDAR.
BOXES_AND_WALL = np.array(
    [
        [(20.0, -30.0, -10.0), (21.0, 30.0, 20.0)],
        [(8.0, -2.0, -3.0), (10.0, 2.0, 1.0)],
        [(5.0, 3.0, -3.0), (6.0, 4.5, 2.0)],
        [(12.0, -8.0, -3.0), (14.0, -5.0, 3.0)],
        [(-50.0, -50.0, -4.0), (50.0, 50.0, -3.0)],
    ]
)
#: scene -> (boxes, camera offset from the LiDAR in metres, camera pitch in degrees)
SCENES = {
    "structured": (None, (0.1, 0.3, -0.4), 20.0),
    "boxes": (BOXES_AND_WALL, (0.0, 0.6, 0.4), 0.0),  # camera 0.6 m beside and 0.4 m above the LiDAR
}


def scan(spec: LidarSpec, boxes: np.ndarray, variant: str = "nominal", seed: int = 0) -> np.ndarray:
    """Points hit by the spec's beams (LiDAR at the origin), within its range; ``variant`` moves the beams
    as a real sensor's (see the module docstring: ``nominal``, ``boundary``, ``ring phase``, ``jitter``,
    ``shuffled``)."""
    if variant == "nominal":
        dirs = spec.beam_directions(torch.float64).reshape(-1, 3).numpy()
    else:
        rng = np.random.default_rng(seed)
        shape = (spec.channels, spec.points_per_channel)
        el = np.broadcast_to(spec.channel_elevations()[:, None], shape).copy()
        az = np.broadcast_to(spec.column_azimuths()[None, :], shape).copy()
        h, v = spec.horizontal_resolution, spec.vertical_resolution
        if variant == "boundary":
            az += 0.5 * h
        elif variant in ("ring phase", "jitter"):
            az += rng.uniform(-0.5, 0.5, (spec.channels, 1)) * h
        if variant == "jitter":
            az += rng.normal(0.0, 0.1, shape) * h
            el += rng.normal(0.0, 0.1, shape) * v
        dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1).reshape(-1, 3)
        if variant == "jitter":
            dirs = dirs[rng.random(len(dirs)) >= 0.05]
        if variant == "shuffled":
            dirs = dirs[rng.permutation(len(dirs))]
    t = ray_box_entry(np.zeros(3), dirs, boxes)
    hit = t <= spec.max_range
    return dirs[hit] * t[hit, None]


def camera_rig(offset=(0.1, 0.3, -0.4), pitch_deg: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    """``(centre, T_cam_lidar)``: a forward camera pitched down, centred at ``offset`` in the LiDAR frame."""
    centre = np.asarray(offset, dtype=np.float64)
    R_lidar_cam = euler_to_matrix(0.0, math.radians(pitch_deg), 0.0) @ CAM_FROM_FLU.T
    R = R_lidar_cam.T
    return centre, make_transform(R, -R @ centre)


def visible(points: np.ndarray, centre: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Exact visibility from ``centre``: no box is entered before the point itself is reached."""
    v = points - centre
    dist = np.linalg.norm(v, axis=1)
    return ray_box_entry(centre, v / dist[:, None], boxes) >= dist * (1 - 1e-9) - 1e-9
