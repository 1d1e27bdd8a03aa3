"""Scans with the structure of real spinning LiDARs' files, for the tests and the KITTI-360 benchmark (no real
data: they are simulated).

A street-like scene (ground 1.73 m below the sensor as on KITTI's car, walls, cars, poles, a near obstacle) is
scanned by the beams of a :class:`LidarSpec` from their own origins (``beam_origins_m``), with the channel table's
azimuth offsets, a random phase per laser and small angular jitter; returns beyond ``max_range`` are lost. Then:

* ``order="kitti"``: each laser's revolution stored contiguously, top laser first, starting near azimuth 0 and
  wrapping once at +-180 deg (KITTI ``.bin``);
* ``order="firing"``: column by column, every laser of a column in turn (a driver's packet order);
* ``order="nuscenes"``: column by column with every firing stored, a lost return as a zero (nuScenes
  ``.pcd.bin``: 32 x 1084 points), the lasers of a column in ring order or in ``sequence`` (the rings in a
  packet's firing order);
* self-hits within 1 m can be added (nuScenes holds thousands);
* ``motion_m``: the sweep compensated for the vehicle's motion, as nuScenes' are: the vehicle drives that far
  ahead (+x) during the revolution and every point is moved into the sensor's frame at the last firing.

The true ring of every return comes with it.
"""

from __future__ import annotations

import math

import numpy as np

from airfisheye_bench.geometry.lidar import LidarSpec

#: Axis-aligned boxes (min, max corners) in the LiDAR frame.
BOXES = np.array(
    [
        [(-60.0, -60.0, -2.73), (60.0, 60.0, -1.73)],  # ground
        [(8.0, 6.0, -1.73), (40.0, 9.0, 6.0)],  # buildings along the street
        [(-30.0, -12.0, -1.73), (25.0, -8.0, 10.0)],
        [(-40.0, 5.0, -1.73), (-10.0, 12.0, 8.0)],
        [(5.0, -3.5, -1.73), (9.5, -1.7, -0.3)],  # parked cars
        [(12.0, 1.8, -1.73), (16.5, 3.6, -0.2)],
        [(-9.0, -3.0, -1.73), (-4.5, -1.2, -0.3)],
        [(3.0, 2.0, -1.73), (3.3, 2.3, 3.0)],  # poles
        [(-2.5, -2.6, -1.73), (-2.2, -2.3, 3.0)],
        [(1.8, -0.6, -1.2), (2.3, 0.4, -0.4)],  # a near obstacle 2 m ahead
    ]
)


def _hit(origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Distance along each ray to the first box (inf: none); rays start outside every box."""
    t = np.full(len(dirs), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
        for lo, hi in BOXES:
            t1, t2 = (lo - origins) * inv, (hi - origins) * inv
            near = np.nan_to_num(np.minimum(t1, t2), nan=-np.inf).max(axis=1)
            far = np.nan_to_num(np.maximum(t1, t2), nan=np.inf).min(axis=1)
            hit = (near <= far) & (near > 0)
            t = np.where(hit, np.minimum(t, near), t)
    return t


def simulate(
    spec: LidarSpec,
    seed: int = 0,
    order: str = "kitti",
    jitter_cells: float = 0.05,
    self_hits: int = 0,
    motion_m: float = 0.0,
    sequence: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(points float64 [N, 3], true ring int64 [N])`` in the file order ``order`` (see the module docstring).

    Self-hits get ring -1 in the truth (no laser of the table measured them in the scene); in the ``nuscenes`` order
    they replace the returns of their firings, so that every column keeps one point per laser.
    """
    rng = np.random.default_rng(seed)
    n_c, n_pc = spec.channels, spec.points_per_channel
    h = spec.horizontal_resolution
    channel = np.repeat(np.arange(n_c), n_pc)
    column = np.tile(np.arange(n_pc), n_c)
    start = rng.uniform(-0.5, 0.5, n_c)[channel] * h  # each laser's first firing, near azimuth 0
    az = (column + 0.5) * h + start + rng.normal(0.0, jitter_cells * h, channel.size)
    az = np.remainder(az + math.pi, 2.0 * math.pi) - math.pi  # from 0 round to 0, wrapping once at +-180
    az = (
        az + spec.channel_azimuth_offsets()[channel] * 0.0
    )  # the offsets move the beams, not the stored order
    beam_az = az + spec.channel_azimuth_offsets()[channel]
    el = spec.channel_elevations()[channel] + rng.normal(
        0.0, jitter_cells * spec.vertical_resolution / 4, channel.size
    )
    dirs = np.stack([np.cos(el) * np.cos(beam_az), np.cos(el) * np.sin(beam_az), np.sin(el)], axis=1)
    origins = spec.beam_origins(beam_az, channel)
    t = _hit(origins, dirs)
    keep = (t <= spec.max_range) | (order == "nuscenes")  # nuScenes keeps every firing
    points = np.where(
        (t <= spec.max_range)[:, None], origins + dirs * np.where(np.isfinite(t), t, 0.0)[:, None], 0.0
    )
    if motion_m:  # where the sensor was at each firing, seen from where it is at the last one
        points[:, 0] -= motion_m * (1.0 - (column + 0.5) / n_pc)
    points = points[keep]
    ring, az_kept, col_kept, lost = channel[keep], az[keep], column[keep], (t > spec.max_range)[keep]
    if order == "kitti":  # laser by laser, top first; inside a laser by firing time (column)
        idx = np.lexsort((col_kept, -ring))
    elif order == "firing":
        idx = np.lexsort((ring, col_kept))
    elif order == "nuscenes":
        slot = np.empty(n_c, dtype=np.int64)
        slot[np.arange(n_c) if sequence is None else np.asarray(sequence)] = np.arange(n_c)
        idx = np.lexsort((slot[ring], col_kept))
    else:
        raise ValueError(order)
    points, ring, lost = points[idx], ring[idx], lost[idx]
    if self_hits and order == "nuscenes":  # the body instead of the scene, 0.2-1.2 m along the beam
        where = rng.choice(np.flatnonzero(~lost), self_hits, replace=False)
        beam = points[where] / np.linalg.norm(points[where], axis=1, keepdims=True)
        points[where] = beam * rng.uniform(0.2, 1.2, (self_hits, 1))
        ring[where] = -1
    elif (
        self_hits
    ):  # returns 0.2-1.2 m along a beam (the vehicle's own body), a tenth of them zeros (no return)
        where = np.sort(rng.integers(0, len(points), self_hits))  # fired between two stored returns
        beam = points[where] / np.linalg.norm(points[where], axis=1, keepdims=True)
        start = spec.beam_origins(np.arctan2(beam[:, 1], beam[:, 0]), ring[where])
        junk = start + beam * rng.uniform(0.2, 1.2, (self_hits, 1))
        junk[rng.random(self_hits) < 0.1] = 0.0
        points = np.insert(points, where, junk, axis=0)
        ring = np.insert(ring, where, -1)
    del az_kept
    return points, ring.astype(np.int64)
