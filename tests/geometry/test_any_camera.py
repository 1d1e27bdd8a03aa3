"""Downstream geometry takes any camera model: cubemap remap tables, LiDAR projection with the z-buffer window, and
the incidence-angle rings, on published calibrations (KITTI-360 image_02: MEI, corners outside the model; TUM-VI
double sphere; WoodScape radial_poly, a non-square frame)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry import (
    CAM_FROM_FLU,
    CubemapToFisheye,
    LidarSpec,
    camera_from_dict,
    face_rays,
    lidar_depth_map,
    make_transform,
    project_lidar,
)
from airfisheye_bench.metrics.binned import ring_edges_for
from tests.helpers.camera_tester import CALIBRATIONS, angle_between


def _camera(name: str, side: int):
    cam = camera_from_dict(CALIBRATIONS[name]["camera"])
    g = math.gcd(cam.width, cam.height)
    step = next((d for d in range(1, g + 1) if g % d == 0 and max(cam.width, cam.height) // d <= side), g)
    return cam.resized(cam.width // step, cam.height // step)


@pytest.mark.parametrize(
    "name", ["kitti360_image_02", "tumvi512_cam0_ds", "woodscape_front", "ocam_kodak_sp360"]
)
def test_cubemap_remap_samples_along_the_lens_rays(name: str) -> None:
    """Faces that store their own ray directions, remapped through the lens, give back the lens's rays."""
    cam = _camera(name, 160)
    s = 64
    faces = face_rays(s).permute(0, 3, 1, 2).contiguous()  # [5, 3, S, S]: each texel holds its direction
    remap = CubemapToFisheye(cam, s)
    out = remap(faces, "bilinear").permute(1, 2, 0)
    valid = remap.valid_mask
    assert valid.any() and not (valid & ~cam.valid_mask()).any()
    # Away from the missing back face (whose border taps get no weight): the OCam lens sees to 129 deg.
    valid &= cam.theta_grid() <= math.radians(120.0)
    rays = cam.ray_grid(torch.float64)[valid]
    sampled = out[valid].double()
    # Bilinear interpolation of unit vectors: within a fraction of a texel (90 deg / S) of the true ray.
    assert angle_between(sampled, rays).max() < 0.25 * math.radians(90.0 / s)


def test_kitti360_corners_get_no_cubemap_pixels_and_no_lidar_points() -> None:
    cam = _camera("kitti360_image_02", 200)
    remap = CubemapToFisheye(cam, 32)
    assert not remap.valid_mask[0, 0] and not remap.valid_mask[-1, -1]
    # A point straight through the corner pixel's direction does not exist for this lens: the corner has no ray,
    # and a point at 125 deg off-axis (beyond the model's 117 deg) is not projected.
    assert torch.isnan(cam.ray_grid(torch.float64)[0, 0]).all()
    t = math.radians(125.0)
    _, valid = cam.project(np.array([[math.sin(t), 0.0, math.cos(t)]]))
    assert not valid[0]


@pytest.mark.parametrize("name", ["kitti360_image_02", "woodscape_front"])
@pytest.mark.parametrize("method", ["none", "zbuffer", "ordering"])
def test_lidar_projection_and_depth_map_with_a_calibrated_lens(name: str, method: str) -> None:
    cam = _camera(name, 200)
    spec = LidarSpec(channels=16, points_per_channel=512)
    pts = 8.0 * spec.beam_directions(torch.float64).reshape(-1, 3).numpy()  # an 8 m sphere around the LiDAR
    T = make_transform(CAM_FROM_FLU, np.zeros(3))
    uv, rng, mask = project_lidar(pts, T, cam, spec, method=method)
    np.testing.assert_allclose(rng, 8.0)
    cam_pts = pts @ T[:3, :3].T
    expected_uv, expected_valid = cam.project(cam_pts)
    expected_valid &= cam.in_image(expected_uv)
    assert mask.any()
    assert not (mask & ~expected_valid).any()  # only points the lens sees, inside the frame
    np.testing.assert_allclose(uv[mask], expected_uv[mask], atol=1e-6)
    if method == "none":
        np.testing.assert_array_equal(mask, expected_valid)
    depth = lidar_depth_map(pts, T, cam, spec, method=method)
    assert depth.shape == (cam.height, cam.width) and (depth > 0).any()
    np.testing.assert_allclose(depth[depth > 0], 8.0, rtol=1e-5)


def test_zbuffer_window_follows_the_lens_scale() -> None:
    """The z-buffer window comes from ``pixels_per_radian``: for the ideal lens it is the old closed form."""
    ideal = camera_from_dict({"model": "equidistant", "width": 128, "height": 128, "fov_deg": 190.0})
    ppr = ideal.pixels_per_radian()
    theta = ideal.theta_grid().double()
    # equidistant: radial scale f, tangential f theta / sin(theta): the larger is the tangential one off-axis.
    expected = ideal.focal * torch.where(theta > 1e-6, theta / torch.sin(theta), torch.ones_like(theta))
    m = ideal.valid_mask()
    torch.testing.assert_close(ppr[m], expected[m], rtol=1e-6, atol=0)
    kitti = _camera("kitti360_image_02", 200)
    k = kitti.pixels_per_radian()
    assert torch.isfinite(k).all() and k[100, 100] > 0


def test_incidence_rings_reach_the_rim_of_a_calibrated_lens() -> None:
    cam = _camera("kitti360_image_02", 200)
    assert cam.fov_deg is None
    assert cam.coverage_deg == pytest.approx(
        2 * math.degrees(float(cam.theta_grid()[cam.valid_mask()].max()))
    )
    edges = ring_edges_for(cam.coverage_deg)
    assert edges[-1] >= 116.0  # the MEI lens sees to ~117 deg: its outer pixels fall in a ring
    assert (
        ring_edges_for(camera_from_dict({"model": "equidistant", "width": 64, "height": 64}).coverage_deg)[-1]
        == 95.0
    )
