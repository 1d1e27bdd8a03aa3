"""Depth on a full six-face cube: planar depth to range, and a LiDAR scan cast into the depth faces.

A renderer that writes six 90-degree pinhole faces (TartanAir V2's ``lcam_front|left|right|top|bottom|back``)
stores *planar* depth (the face's z) per texel; the project's depth is *range* along the pixel's ray
(``docs/design.md``). The five faces the remap uses keep :mod:`~airfisheye_bench.geometry.cubemap`'s axes; the
sixth, :data:`BACK_FACE`, looks along camera ``-z`` with face x = camera ``-x`` and face y = camera ``+y`` (the
cube read as a whole, as a 360-degree LiDAR needs). Faces are stacked in :data:`SIX_FACE_NAMES` order.

A LiDAR is simulated from the faces by casting every beam of a :class:`~airfisheye_bench.geometry.lidar.LidarSpec`
(from the cube's centre) into the face it crosses and intersecting it with the plane of the nearest texel's planar
depth: the point lies on the beam, at the texel's depth (a surface locally flat at the texel's scale).

Example:
    >>> z = np.full((6, 4, 4), 2.0, np.float32)
    >>> r = planar_to_range(z)
    >>> float(r[0, 0, 0]) > 2.0 and float(r[0, 1, 1]) > 2.0 and r.shape == (6, 4, 4)
    True
"""

from __future__ import annotations

import numpy as np
import torch

from airfisheye_bench.geometry.cubemap import FACE_NAMES, face_rotation
from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.transforms import CAM_FROM_FLU

BACK_FACE = "back"
#: The five remap faces, then the back face.
SIX_FACE_NAMES: tuple[str, ...] = (*FACE_NAMES, BACK_FACE)
# Columns: the back face's x, y, z axes in the camera frame.
_R_CAM_BACK = np.array(((-1, 0, 0), (0, 1, 0), (0, 0, -1)), dtype=np.float64).T
_R_CAM_FACES = np.stack([*(face_rotation(n) for n in FACE_NAMES), _R_CAM_BACK])


def six_face_rotation(name: str) -> np.ndarray:
    """``R_cam_face`` of any of the six faces (:func:`~airfisheye_bench.geometry.cubemap.face_rotation` and back).

    Example:
        >>> six_face_rotation("back") @ np.array([0.0, 0.0, 1.0])  # the back face looks along camera -z
        array([ 0.,  0., -1.])
    """
    if name not in SIX_FACE_NAMES:
        raise ValueError(f"name must be one of {SIX_FACE_NAMES}, got {name!r}")
    return _R_CAM_FACES[SIX_FACE_NAMES.index(name)].copy()


def range_factor(face_size: int) -> np.ndarray:
    """``float32 [S, S]``: range / planar depth of each texel of a 90-degree face (``|ray| / ray_z``).

    Texel ``(i, j)`` has its centre at ``((j - (S-1)/2) / (S/2), (i - (S-1)/2) / (S/2), 1)`` (focal ``S/2``).

    Example:
        >>> f = range_factor(2)  # every texel centre is at (+-0.5, +-0.5, 1)
        >>> bool(np.allclose(f, np.sqrt(1.5)))
        True
    """
    s = int(face_size)
    if s < 1:
        raise ValueError(f"face_size must be a positive integer, got {face_size}")
    c = (np.arange(s, dtype=np.float64) - (s - 1) / 2.0) / (s / 2.0)
    return np.sqrt(1.0 + c[None, :] ** 2 + c[:, None] ** 2).astype(np.float32)


def planar_to_range(depth: np.ndarray) -> np.ndarray:
    """Planar depth of square faces ``[..., S, S]`` -> range along each texel's ray (float32; 0 stays 0)."""
    depth = np.asarray(depth)
    if depth.ndim < 2 or depth.shape[-1] != depth.shape[-2]:
        raise ValueError(f"depth must be square faces [..., S, S], got shape {depth.shape}")
    return (depth.astype(np.float32) * range_factor(depth.shape[-1])).astype(np.float32)


def locate_six(
    directions: np.ndarray, face_size: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Camera-frame directions ``[N, 3]`` on the six-face cube.

    Returns:
        ``(face [N] int64 in SIX_FACE_NAMES order, col [N], row [N] int64 nearest texel, cos [N])`` where ``cos`` is
        the direction's component along its face's axis divided by its norm (``planar = range * cos``).

    Example:
        >>> face, col, row, cos = locate_six(np.array([[0.0, 0.0, -1.0], [0.0, -1.0, 0.0]]), 4)
        >>> [SIX_FACE_NAMES[f] for f in face], col.tolist(), row.tolist()
        (['back', 'up'], [2, 2], [2, 2])
    """
    d = np.asarray(directions, dtype=np.float64)
    local = np.einsum("kji,nj->nki", _R_CAM_FACES, d)  # [N, 6, 3]: the direction in every face's frame
    face = np.argmax(local[..., 2], axis=1)
    own = local[np.arange(len(d)), face]
    s = int(face_size)
    half, centre = s / 2.0, (s - 1) / 2.0
    col = np.clip(np.rint(own[:, 0] / own[:, 2] * half + centre), 0, s - 1).astype(np.int64)
    row = np.clip(np.rint(own[:, 1] / own[:, 2] * half + centre), 0, s - 1).astype(np.int64)
    return face, col, row, own[:, 2] / np.linalg.norm(d, axis=1)


def sample_range(directions: np.ndarray, planar_faces: np.ndarray) -> np.ndarray:
    """Distance along each direction ``[N, 3]`` (camera frame, from the cube's centre) to the surface in the six
    planar-depth faces ``[6, S, S]`` (nearest texel, its plane); 0 where that texel is 0 (no depth).

    Example:
        >>> faces = np.full((6, 8, 8), 4.0, np.float32)  # a cube-shaped room, walls 4 m away
        >>> sample_range(np.array([[1.0, 0.0, 1.0], [0.0, 0.0, -2.0]]), faces).round(4).tolist()
        [5.6569, 4.0]
    """
    faces = np.asarray(planar_faces)
    if faces.ndim != 3 or faces.shape[0] != 6 or faces.shape[1] != faces.shape[2]:
        raise ValueError(f"planar_faces must be [6, S, S] in SIX_FACE_NAMES order, got shape {faces.shape}")
    face, col, row, cos = locate_six(directions, faces.shape[1])
    planar = faces[face, row, col].astype(np.float64)
    return np.where(planar > 0, planar / cos, 0.0)


def lidar_from_faces(planar_faces: np.ndarray, spec: LidarSpec) -> tuple[np.ndarray, np.ndarray]:
    """A scan of ``spec`` cast from the cube's centre into six planar-depth faces ``[6, S, S]`` (camera frame
    at the cube's centre; the LiDAR's FLU axes aligned with it, ``CAM_FROM_FLU``).

    Returns:
        ``(points float64 [M, 3] in the LiDAR's FLU frame, rings int64 [M])``: beams with a depth and a range up
        to ``spec.max_range``. Per-laser beam origins are not modelled (the faces see from one centre).

    Example:
        >>> spec = LidarSpec(channels=2, points_per_channel=8, hfov_deg=360.0, vfov_deg=(-10.0, 10.0))
        >>> pts, rings = lidar_from_faces(np.full((6, 16, 16), 3.0, np.float32), spec)
        >>> pts.shape, sorted(set(rings.tolist())), bool((np.abs(pts).max(axis=1) <= 3.0 + 1e-9).all())
        ((16, 3), [0, 1], True)
    """
    dirs_flu = spec.beam_directions(dtype=torch.float64).numpy()
    rings = np.broadcast_to(np.arange(spec.channels)[:, None], dirs_flu.shape[:2]).reshape(-1)
    dirs_flu = dirs_flu.reshape(-1, 3)
    rng = sample_range(dirs_flu @ CAM_FROM_FLU.T, planar_faces)
    keep = (rng > 0) & (rng <= spec.max_range)
    return dirs_flu[keep] * rng[keep, None], rings[keep].astype(np.int64)


__all__ = [
    "BACK_FACE",
    "SIX_FACE_NAMES",
    "lidar_from_faces",
    "locate_six",
    "planar_to_range",
    "range_factor",
    "sample_range",
    "six_face_rotation",
]
