"""The ray map (docs/design.md, "Ray map"): each valid pixel's unit ray in the camera frame, which projects back onto
the pixel, and a valid channel; nothing where the pixel has no data."""

from __future__ import annotations

import pytest
import torch

from airfisheye_bench.geometry.cameras import CameraModel, ideal_camera
from airfisheye_bench.geometry.ray_maps import RAY_MAP_CHANNELS, ray_map
from tests.helpers.random_cameras import random_cameras

CAMERAS = [
    ideal_camera(40, 32, fov_deg=190.0),
    ideal_camera(32, 32, fov_deg=180.0, model="equisolid"),
    ideal_camera(36, 36, fov_deg=120.0, model="stereographic"),
    *random_cameras("kannala_brandt", 1),
    *random_cameras("double_sphere", 1),
    *random_cameras("pinhole_radtan", 1),
]


@pytest.mark.parametrize("camera", CAMERAS, ids=lambda c: c.to_dict()["model"])
def test_each_valid_pixel_holds_its_unit_ray_and_the_rest_nothing(camera: CameraModel) -> None:
    rays = ray_map(camera)
    assert rays.shape == (RAY_MAP_CHANNELS, camera.height, camera.width) and rays.dtype == torch.float32
    valid = camera.valid_mask()
    assert valid.any() and torch.equal(rays[3].bool(), valid)
    assert torch.equal(rays[3], valid.float())
    assert torch.isfinite(rays).all()
    assert not rays[:3, ~valid].any()
    direction = rays[:3, valid].T.double()  # [N, 3]
    torch.testing.assert_close(direction.norm(dim=1), torch.ones(len(direction), dtype=torch.float64))
    # The ray of a pixel projects back onto the pixel's centre (within float32's rounding of the ray).
    uv, ok = camera.project(direction)
    assert ok.all()
    torch.testing.assert_close(uv, camera.pixel_grid()[valid], atol=1e-2, rtol=0)
    # z is the cosine of the incidence angle.
    torch.testing.assert_close(rays[2, valid], torch.cos(camera.theta_grid()[valid]), atol=1e-6, rtol=0)


def test_a_given_valid_mask_bounds_the_map() -> None:
    camera = ideal_camera(32, 32, fov_deg=190.0)
    valid = camera.valid_mask().clone()
    valid[:, :16] = False  # e.g. a padded calibration's band: no data there
    rays = ray_map(camera, valid)
    assert torch.equal(rays[3], valid.float())
    assert not rays[:3, :, :16].any()
    torch.testing.assert_close(rays[:3, valid], ray_map(camera)[:3, valid])
    with pytest.raises(ValueError, match=r"valid must be \[32, 32\]"):
        ray_map(camera, valid[:8])
