"""Rigid transforms and rotation conventions."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry import (
    CAM_FROM_FLU,
    check_rigid,
    euler_to_matrix,
    invert_rigid,
    make_transform,
    matrix_to_quaternion,
    quaternion_to_matrix,
    relative_transform,
    transform_points,
)


def random_transforms(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    R = euler_to_matrix(rng.uniform(-3, 3, n), rng.uniform(-1.5, 1.5, n), rng.uniform(-3, 3, n))
    return make_transform(R, rng.normal(size=(n, 3)) * 10)


def test_euler_convention_flu() -> None:
    fwd, left, up = np.eye(3)
    np.testing.assert_allclose(euler_to_matrix(0.0, 0.0, np.pi / 2) @ fwd, left, atol=1e-12)  # yaw left
    np.testing.assert_allclose(euler_to_matrix(0.0, np.pi / 2, 0.0) @ fwd, -up, atol=1e-12)  # pitch down
    np.testing.assert_allclose(
        euler_to_matrix(np.pi / 2, 0.0, 0.0) @ left, up, atol=1e-12
    )  # roll right-wing-down
    assert np.allclose(
        euler_to_matrix(0.1, 0.2, 0.3),
        euler_to_matrix(0, 0, 0.3) @ euler_to_matrix(0, 0.2, 0) @ euler_to_matrix(0.1, 0, 0),
    )


def test_cam_from_flu_axes() -> None:
    fwd, left, up = np.eye(3)
    np.testing.assert_array_equal(CAM_FROM_FLU @ fwd, [0, 0, 1])  # forward is the optical axis
    np.testing.assert_array_equal(CAM_FROM_FLU @ left, [-1, 0, 0])  # left is -x (x points right)
    np.testing.assert_array_equal(CAM_FROM_FLU @ up, [0, -1, 0])  # up is -y (y points down)
    assert np.isclose(np.linalg.det(CAM_FROM_FLU), 1.0)


def test_inverse_and_composition() -> None:
    T = random_transforms(16)
    np.testing.assert_allclose(invert_rigid(T) @ T, np.broadcast_to(np.eye(4), T.shape), atol=1e-12)
    np.testing.assert_allclose(invert_rigid(T), np.linalg.inv(T), atol=1e-10)
    Ta, Tb = T[:8], T[8:]
    np.testing.assert_allclose(relative_transform(Ta, Tb), np.linalg.inv(Ta) @ Tb, atol=1e-10)


def test_transform_points_broadcasts() -> None:
    T = random_transforms(3)
    pts = np.random.default_rng(1).normal(size=(3, 7, 3))
    out = transform_points(T, pts)
    ref = np.einsum("bij,bnj->bni", T[:, :3, :3], pts) + T[:, None, :3, 3]
    np.testing.assert_allclose(out, ref, atol=1e-12)
    single = transform_points(torch.from_numpy(T[0]), torch.from_numpy(pts[0]))
    assert isinstance(single, torch.Tensor)
    np.testing.assert_allclose(single.numpy(), ref[0], atol=1e-12)


def test_quaternion_round_trip_and_sign() -> None:
    R = random_transforms(64, seed=3)[:, :3, :3]
    q = matrix_to_quaternion(R)
    assert (q[:, 0] >= 0).all()
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(quaternion_to_matrix(q), R, atol=1e-12)
    # 180-degree rotations (w = 0) are the numerically delicate case.
    flips = np.stack([np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])])
    np.testing.assert_allclose(quaternion_to_matrix(matrix_to_quaternion(flips)), flips, atol=1e-12)


def test_check_rigid_rejects_bad_transforms() -> None:
    check_rigid(random_transforms(4), "T_ok")
    with pytest.raises(ValueError, match="T_cam_lidar"):
        check_rigid(np.zeros((4, 4)), "T_cam_lidar")
    reflection = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match="det"):
        check_rigid(reflection, "T")
    scaled = np.diag([2.0, 2.0, 2.0, 1.0])
    with pytest.raises(ValueError, match="orthonormal"):
        check_rigid(scaled, "T")
    bad = np.eye(4)
    bad[0, 3] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        check_rigid(bad, "T")
    with pytest.raises(ValueError, match=r"\[\.\.\., 4, 4\]"):
        check_rigid(np.eye(3), "T")
