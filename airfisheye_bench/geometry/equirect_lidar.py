"""A LiDAR scan cast into an equirectangular range panorama (docs/design.md, "AirSim360 / Omni360-X").

A dataset of panoramas with range depth (AirSim360) has no LiDAR; a scan of any
:class:`~airfisheye_bench.geometry.lidar.LidarSpec` is simulated from the depth instead, from the panorama's centre:
every nominal beam direction is turned into the panorama's frame and takes the range of the texel it falls in, the
one :class:`~airfisheye_bench.geometry.equirect.EquirectToFisheye` takes in ``nearest`` mode (no interpolation:
across a depth edge a blend of two ranges is a point on neither surface). Per-laser beam origins are not modelled
(the panorama sees from one centre). A sensor at the camera's centre sees every point it returns from the camera's
viewpoint: there is no parallax, so none of them is hidden from the camera.

Example:
    >>> spec = LidarSpec(channels=2, points_per_channel=8, hfov_deg=360.0, vfov_deg=(-10.0, 10.0))
    >>> pts, rings = lidar_from_equirect(np.full((16, 32), 5.0, np.float32), spec, CAM_FROM_FLU)
    >>> pts.shape, sorted(set(rings.tolist())), np.allclose(np.linalg.norm(pts, axis=1), 5.0)
    ((16, 3), [0, 1], True)
"""

from __future__ import annotations

import numpy as np
import torch

from airfisheye_bench.geometry.equirect import direction_to_erp
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.transforms import CAM_FROM_FLU  # noqa: F401  (the example's)

__all__ = ["erp_texel", "lidar_from_equirect"]


def erp_texel(directions: np.ndarray, height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """``(row [N], col [N])`` int64: the texel of an ``height x width`` panorama that each panorama-frame direction
    ``[N, 3]`` falls in (columns wrap at +-180 deg, rows clamp at the poles), as the remap's ``nearest`` mode.

    Example:
        >>> erp_texel(np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]), 4, 8)
        (array([2, 0, 2]), array([4, 4, 0]))
    """
    u, v = direction_to_erp(torch.from_numpy(np.asarray(directions, np.float64)), height, width)
    col = torch.remainder((u + 0.5).floor().to(torch.int64), width)
    row = (v + 0.5).floor().clamp(0, height - 1).to(torch.int64)
    return row.numpy(), col.numpy()


def lidar_from_equirect(
    range_erp: np.ndarray, spec: LidarSpec, R_pano_lidar: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A scan of ``spec`` cast from the centre of a range panorama ``[H, W]`` (metres, 0 = no depth).

    Args:
        range_erp: The depth panorama.
        spec: The LiDAR (its nominal beam directions).
        R_pano_lidar: ``3x3``: the LiDAR's FLU directions -> the panorama's frame (``R_pano_cam @ CAM_FROM_FLU`` for
            a LiDAR on the camera's axes).

    Returns:
        ``(points float64 [M, 3] in the LiDAR's FLU frame, rings int64 [M])``: the beams that meet a depth within
        ``spec.max_range``, ring by ring, in azimuth order within a ring.
    """
    depth = np.asarray(range_erp)
    if depth.ndim != 2:
        raise ValueError(f"range_erp must be one panorama [H, W], got shape {depth.shape}")
    R = np.asarray(R_pano_lidar, np.float64)
    if R.shape != (3, 3):
        raise ValueError(f"R_pano_lidar must be 3x3, got shape {R.shape}")
    dirs = spec.beam_directions(dtype=torch.float64).numpy()  # [C, N, 3] unit, FLU
    rings = np.broadcast_to(np.arange(spec.channels)[:, None], dirs.shape[:2]).reshape(-1)
    dirs = dirs.reshape(-1, 3)
    row, col = erp_texel(dirs @ R.T, *depth.shape)
    rng = depth[row, col].astype(np.float64)
    keep = (rng > 0) & (rng <= spec.max_range)
    return dirs[keep] * rng[keep, None], rings[keep].astype(np.int64)
