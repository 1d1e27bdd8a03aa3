"""Rigid transforms, rotations and the fixed axis conventions of the project.

Conventions (docs/design.md): ``T_a_b`` is a 4x4 rigid transform mapping points in frame b to frame a. Camera frames are
OpenCV (x right, y down, z forward); body and LiDAR frames are FLU (x forward, y left, z up); the world is z up.
Every function accepts numpy arrays or torch tensors, any leading batch shape, and answers in kind.
"""

from __future__ import annotations

import numpy as np
import torch

from airfisheye_bench.geometry import portable
from airfisheye_bench.geometry._arrays import ArrayLike, as_tensor, back, check_last_dim

#: Rotation taking FLU (x forward, y left, z up) direction coordinates to OpenCV camera coordinates
#: (x right = -y_flu, y down = -z_flu, z forward = x_flu).
CAM_FROM_FLU = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])


def make_transform(R: ArrayLike, t: ArrayLike) -> ArrayLike:
    """Stack a rotation ``[..., 3, 3]`` and translation ``[..., 3]`` into ``[..., 4, 4]``.

    Example:
        >>> make_transform(np.eye(3), np.array([1.0, 2.0, 3.0]))[:3, 3]
        array([1., 2., 3.])
    """
    Rt, was_numpy = as_tensor(R, "R")
    tt, _ = as_tensor(t, "t", dtype=Rt.dtype)
    if Rt.shape[-2:] != (3, 3):
        raise ValueError(f"R must have shape [..., 3, 3], got {tuple(Rt.shape)}")
    check_last_dim(tt, 3, "t")
    batch = torch.broadcast_shapes(Rt.shape[:-2], tt.shape[:-1])
    T = torch.zeros(*batch, 4, 4, dtype=Rt.dtype, device=Rt.device)
    T[..., :3, :3] = Rt
    T[..., :3, 3] = tt
    T[..., 3, 3] = 1.0
    return back(T, was_numpy)


def invert_rigid(T: ArrayLike) -> ArrayLike:
    """Inverse of a rigid transform, using ``R^T`` rather than a general matrix inverse."""
    Tt, was_numpy = as_tensor(T, "T")
    _check_4x4(Tt, "T")
    R = Tt[..., :3, :3]
    t = Tt[..., :3, 3]
    Rinv = R.transpose(-1, -2)
    out = torch.zeros_like(Tt)
    out[..., :3, :3] = Rinv
    out[..., :3, 3] = -(Rinv @ t.unsqueeze(-1)).squeeze(-1)
    out[..., 3, 3] = 1.0
    return back(out, was_numpy)


def transform_points(T: ArrayLike, points: ArrayLike) -> ArrayLike:
    """Apply ``T [..., 4, 4]`` to ``points [..., N, 3]`` (or ``[..., 3]``); the batch dims broadcast.

    Example:
        >>> T = make_transform(np.eye(3), np.array([0.0, 0.0, 1.0]))
        >>> transform_points(T, np.zeros((2, 3)))[:, 2]
        array([1., 1.])
    """
    Tt, was_numpy = as_tensor(T, "T")
    p, _ = as_tensor(points, "points", dtype=Tt.dtype)
    _check_4x4(Tt, "T")
    check_last_dim(p, 3, "points")
    R = Tt[..., :3, :3]
    t = Tt[..., :3, 3]
    if p.ndim >= 2 and Tt.ndim >= 3:
        # points [..., N, 3] with a batched T [..., 4, 4]: broadcast over N.
        out = p @ R.transpose(-1, -2) + t.unsqueeze(-2)
    else:
        out = p @ R.transpose(-1, -2) + t
    return back(out, was_numpy)


def relative_transform(T_world_a: ArrayLike, T_world_b: ArrayLike) -> ArrayLike:
    """``T_a_b = T_world_a^-1 @ T_world_b``: maps points in frame b to frame a."""
    A, was_numpy = as_tensor(T_world_a, "T_world_a")
    B, _ = as_tensor(T_world_b, "T_world_b", dtype=A.dtype)
    return back(as_tensor(invert_rigid(A), "T")[0] @ B, was_numpy)


def check_rigid(T: ArrayLike, name: str = "T", atol: float = 1e-4) -> None:
    """Raise ``ValueError`` naming ``name`` unless ``T`` is a finite proper rigid transform ``[..., 4, 4]``."""
    Tt, _ = as_tensor(T, name, dtype=torch.float64)
    _check_4x4(Tt, name)
    if not torch.isfinite(Tt).all():
        raise ValueError(f"{name} contains non-finite values")
    R = Tt[..., :3, :3]
    eye = torch.eye(3, dtype=Tt.dtype, device=Tt.device)
    if not torch.allclose(R.transpose(-1, -2) @ R, eye.expand_as(R), atol=atol):
        raise ValueError(f"{name} is not rigid: its rotation block is not orthonormal (R^T R != I)")
    if not torch.allclose(torch.linalg.det(R), torch.ones((), dtype=Tt.dtype), atol=atol):
        raise ValueError(f"{name} is not a proper rotation: det(R) != +1 (singular or a reflection)")
    bottom = torch.tensor([0.0, 0.0, 0.0, 1.0], dtype=Tt.dtype, device=Tt.device)
    if not torch.allclose(Tt[..., 3, :], bottom.expand_as(Tt[..., 3, :]), atol=atol):
        raise ValueError(f"{name} must have a last row of [0, 0, 0, 1]")


def euler_to_matrix(roll: ArrayLike | float, pitch: ArrayLike | float, yaw: ArrayLike | float) -> ArrayLike:
    """Rotation ``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (intrinsic Z-Y-X, FLU body convention), angles in radians.

    With FLU axes a positive pitch about the left (y) axis tilts the forward axis *down*.

    Example:
        >>> R = euler_to_matrix(0.0, np.pi / 2, 0.0)
        >>> np.round(R @ np.array([1.0, 0.0, 0.0]), 6)  # forward now points down
        array([ 0.,  0., -1.])
    """
    was_numpy = not any(isinstance(a, torch.Tensor) for a in (roll, pitch, yaw))
    r, _ = as_tensor(roll, "roll")
    dtype = r.dtype if r.dtype == torch.float64 else torch.float64 if was_numpy else r.dtype
    r = r.to(dtype)
    p, _ = as_tensor(pitch, "pitch", dtype=dtype)
    y, _ = as_tensor(yaw, "yaw", dtype=dtype)
    r, p, y = torch.broadcast_tensors(r, p, y)
    if r.device.type == "cpu" and not (r.requires_grad or p.requires_grad or y.requires_grad):
        # Poses of generated data: the C library's sin/cos, the same bits on every CPU (see portable).
        cr, sr, cp, sp, cy, sy = (f(a) for a in (r, p, y) for f in (portable.cos, portable.sin))
    else:
        cr, sr, cp, sp, cy, sy = r.cos(), r.sin(), p.cos(), p.sin(), y.cos(), y.sin()
    R = torch.stack(
        [
            torch.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
            torch.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
            torch.stack([-sp, cp * sr, cp * cr], -1),
        ],
        -2,
    )
    return back(R, was_numpy)


def gimbal_rotation(yaw_deg: float = 0.0, pitch_deg: float = 0.0, roll_deg: float = 0.0) -> np.ndarray:
    """``R_src_cam`` (float64 3x3) of a virtual camera on a gimbal, both frames in OpenCV camera axes.

    The angles are in degrees, in the FLU convention of :func:`euler_to_matrix` (``Rz(yaw) Ry(pitch) Rx(roll)``
    about the source's forward, left and up axes): a positive yaw turns the view to the left (counter-clockwise seen
    from above), a positive pitch tilts it down (the synthetic rig's ``gimbal_pitch_deg``), a positive roll turns
    the camera about its optical axis so that its left side rises (clockwise seen from behind). The result maps the virtual camera's
    directions into the source's camera frame (the cube's, or a panorama's, docs/design.md "Equirectangular
    panoramas"): it is the ``rotation`` of ``CubemapToFisheye`` and ``EquirectToFisheye``.

    Example:
        >>> R = gimbal_rotation(pitch_deg=90.0)
        >>> np.round(R @ np.array([0.0, 0.0, 1.0]), 6) + 0.0  # the optical axis now points down (camera +y)
        array([0., 1., 0.])
        >>> np.round(gimbal_rotation(yaw_deg=90.0) @ np.array([0.0, 0.0, 1.0]), 6) + 0.0  # to the left (-x)
        array([-1.,  0.,  0.])
    """
    angles = np.radians(np.array([roll_deg, pitch_deg, yaw_deg], dtype=np.float64))
    R_flu = euler_to_matrix(*(float(a) for a in angles))
    return CAM_FROM_FLU @ R_flu @ CAM_FROM_FLU.T


def quaternion_to_matrix(q: ArrayLike) -> ArrayLike:
    """Rotation matrix from unit quaternions ``[..., 4]`` ordered ``w, x, y, z`` (normalised first)."""
    qt, was_numpy = as_tensor(q, "q")
    check_last_dim(qt, 4, "q")
    norm = qt.norm(dim=-1, keepdim=True)
    if not torch.isfinite(qt).all() or (norm < 1e-12).any():
        raise ValueError("q must be finite, non-zero quaternions (w, x, y, z)")
    w, x, y, z = (qt / norm).unbind(-1)
    R = torch.stack(
        [
            torch.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            torch.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            torch.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )
    return back(R, was_numpy)


def matrix_to_quaternion(R: ArrayLike) -> ArrayLike:
    """Unit quaternions ``w, x, y, z`` with ``w >= 0`` from rotation matrices ``[..., 3, 3]``.

    Uses the numerically stable branch on the largest of ``w, x, y, z`` (Shepperd's method).
    """
    Rt, was_numpy = as_tensor(R, "R")
    if Rt.shape[-2:] != (3, 3):
        raise ValueError(f"R must have shape [..., 3, 3], got {tuple(Rt.shape)}")
    m = Rt
    tr = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    # Four candidate (unnormalised) quaternions; pick the one with the largest pivot per matrix.
    cands = torch.stack(
        [
            torch.stack(
                [
                    1 + tr,
                    m[..., 2, 1] - m[..., 1, 2],
                    m[..., 0, 2] - m[..., 2, 0],
                    m[..., 1, 0] - m[..., 0, 1],
                ],
                -1,
            ),
            torch.stack(
                [
                    m[..., 2, 1] - m[..., 1, 2],
                    1 + 2 * m[..., 0, 0] - tr,
                    m[..., 0, 1] + m[..., 1, 0],
                    m[..., 0, 2] + m[..., 2, 0],
                ],
                -1,
            ),
            torch.stack(
                [
                    m[..., 0, 2] - m[..., 2, 0],
                    m[..., 0, 1] + m[..., 1, 0],
                    1 + 2 * m[..., 1, 1] - tr,
                    m[..., 1, 2] + m[..., 2, 1],
                ],
                -1,
            ),
            torch.stack(
                [
                    m[..., 1, 0] - m[..., 0, 1],
                    m[..., 0, 2] + m[..., 2, 0],
                    m[..., 1, 2] + m[..., 2, 1],
                    1 + 2 * m[..., 2, 2] - tr,
                ],
                -1,
            ),
        ],
        -2,
    )
    pivots = torch.stack(
        [1 + tr, 1 + 2 * m[..., 0, 0] - tr, 1 + 2 * m[..., 1, 1] - tr, 1 + 2 * m[..., 2, 2] - tr], -1
    )
    best = pivots.argmax(-1)
    q = torch.gather(cands, -2, best[..., None, None].expand(*best.shape, 1, 4)).squeeze(-2)
    q = q / q.norm(dim=-1, keepdim=True)
    q = torch.where(q[..., :1] < 0, -q, q)
    return back(q, was_numpy)


def _check_4x4(T: torch.Tensor, name: str) -> None:
    if T.shape[-2:] != (4, 4):
        raise ValueError(f"{name} must have shape [..., 4, 4], got {tuple(T.shape)}")
