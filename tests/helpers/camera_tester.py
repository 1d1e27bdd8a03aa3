"""Shared tests for every camera model (in the style of ``tests/helpers/model_tester.py``).

A model's test class subclasses :class:`CameraModelTester` and sets ``camera_dict`` (a ``to_dict``-style
description, usually a published calibration)::

    class TestKitti360Image02(CameraModelTester):
        camera_dict = CALIBRATIONS["kitti360_image_02"]["camera"]

or ``calibration_file`` (a calibration file's name and text, read through ``read_calibration`` as a user's is).

Every test builds the camera through ``camera_from_dict`` and checks the contract of ``geometry/cameras/base.py``:
round trips over the whole valid image and field of view (<= 1e-9 rad, <= 1e-6 px), numpy/torch and dtype
parity, NaN rays and invalid points outside the model's region, ``valid_mask`` against the projection,
``resized``, ``to_dict`` / ``camera_from_dict``, clear errors for bad keys, and ``pixels_per_radian``. The valid
region has no hole: found from the projection, not from ``unproject`` (whose NaN ``valid_mask`` would follow), every
point of a disc about the optical axis's pixel, the axis's pixel itself and points 1e-12 px from it included, and the
pixels of directions at every incidence from the axis out to the region's edge, have rays that project back onto
them, the centre's ray being the axis.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry.cameras import CameraModel, camera_from_dict
from airfisheye_bench.io.calibration_files import read_calibration

GOLDEN = Path(__file__).resolve().parents[1] / "geometry" / "golden"
CALIBRATIONS: dict[str, dict] = json.loads((GOLDEN / "calibrations.json").read_text())["cameras"]


def angle_between(a: torch.Tensor | np.ndarray, b: torch.Tensor | np.ndarray) -> torch.Tensor:
    """Angle (radians) between rays, accurate near 0 (``atan2(|a x b|, a . b)``)."""
    a, b = torch.as_tensor(a, dtype=torch.float64), torch.as_tensor(b, dtype=torch.float64)
    return torch.atan2(torch.linalg.cross(a, b).norm(dim=-1), (a * b).sum(-1))


def sphere_directions(n: int = 4000, seed: int = 0) -> torch.Tensor:
    """Unit directions spread over the whole sphere (float64), with the optical axis and its opposite."""
    g = torch.Generator().manual_seed(seed)
    d = torch.randn(n, 3, generator=g, dtype=torch.float64)
    d = torch.cat([d, torch.tensor([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]], dtype=torch.float64)])
    return d / d.norm(dim=-1, keepdim=True)


def cone(theta: torch.Tensor, azimuths: int) -> torch.Tensor:
    """Unit directions ``[len(theta) * azimuths, 3]`` at each incidence angle ``theta``, all azimuths."""
    phi = torch.linspace(0.0, 2.0 * math.pi, azimuths + 1, dtype=torch.float64)[:-1]
    t, p = (a.reshape(-1) for a in torch.meshgrid(theta.double(), phi, indexing="ij"))
    return torch.stack([torch.sin(t) * torch.cos(p), torch.sin(t) * torch.sin(p), torch.cos(t)], -1)


def largest_valid_incidence(camera: CameraModel) -> float:
    """Largest incidence angle (radians) of the model's valid region, from the projection of directions over the
    sphere refined near its edge; short of the back axis (where a full-sphere lens's pixels are ill-conditioned)."""
    theta = torch.linspace(0.0, math.pi - 1e-3, 2000, dtype=torch.float64)
    valid = camera.project(cone(theta, 8))[1].reshape(len(theta), 8).all(-1)
    first_invalid = (~valid).nonzero()
    return float(theta[int(first_invalid[0, 0]) - 1]) if len(first_invalid) else float(theta[-1])


class CameraModelTester:
    """Mixin of camera-model tests; subclasses set ``camera_dict`` (and, where needed, the attributes below)."""

    #: ``to_dict``-style description of the camera under test.
    camera_dict: ClassVar[dict] = {}
    #: Or the ``(file name, text)`` of a calibration file of it, read through ``read_calibration``.
    calibration_file: ClassVar[tuple[str, str] | None] = None
    #: Whether the model's valid region reaches behind the camera (a 360-deg lens, or a polynomial model without
    #: ``fov_deg`` whose polynomial keeps increasing up to 180 deg).
    full_sphere: ClassVar[bool] = False
    #: The shared tests run on the camera resized to at most this many pixels a side (the lens unchanged:
    #: ``resized`` scales the intrinsics); the golden tests use the full-size calibrations.
    max_side: ClassVar[int] = 256
    #: Round-trip bars (the issue's: 1e-9 rad, 1e-6 px).
    max_angle_rad: ClassVar[float] = 1e-9
    max_pixel_err: ClassVar[float] = 1e-6

    @pytest.fixture(scope="class")
    @classmethod
    def camera(cls, tmp_path_factory: pytest.TempPathFactory) -> CameraModel:
        if cls.calibration_file is not None:
            name, text = cls.calibration_file
            path = tmp_path_factory.mktemp("calibration") / name
            path.write_text(text)
            cam = camera_from_dict(read_calibration(path).camera)
        else:
            cam = camera_from_dict(cls.camera_dict)
        w, h = cam.width, cam.height
        g = math.gcd(w, h)  # integer steps keep the aspect ratio exactly
        steps = [d for d in range(1, g + 1) if g % d == 0]
        step = next((d for d in steps if max(w, h) // d <= cls.max_side), steps[-1])
        return cam.resized(w // step, h // step) if step > 1 else cam

    # ------------------------------------------------------------------ round trips
    def test_round_trip_over_the_whole_valid_image(self, camera: CameraModel) -> None:
        mask = camera.valid_mask()
        assert mask.any(), "the camera has no valid pixel"
        uv = camera.pixel_grid()[mask]
        rays = camera.unproject(uv)
        torch.testing.assert_close(rays.norm(dim=-1), torch.ones(len(rays), dtype=torch.float64))
        uv2, valid = camera.project(rays)
        assert valid.all()
        assert angle_between(camera.unproject(uv2), rays).max() <= self.max_angle_rad
        # In pixels too, except within 0.1 deg of the back axis of a full-sphere lens: there a ray's azimuth rests
        # on x, y of ~1e-16 and the pixel is ill-conditioned (the angle above is not).
        away = rays[:, 2] > math.cos(math.pi - 1e-3)
        assert (uv2 - uv)[away].abs().max() <= self.max_pixel_err

    def test_round_trip_over_the_field_of_view(self, camera: CameraModel) -> None:
        dirs = sphere_directions()
        uv, valid = camera.project(dirs)
        assert valid.any()
        # Up to a frame around the image three times its size: beyond, a polynomial model's pixels are not ones a
        # sensor has (and its inverse is solved only so far).
        w, h = camera.width, camera.height
        valid &= (uv[:, 0] > -w) & (uv[:, 0] < 2 * w) & (uv[:, 1] > -h) & (uv[:, 1] < 2 * h)
        back = camera.unproject(uv[valid])
        assert torch.isfinite(back).all()
        assert angle_between(back, dirs[valid]).max() <= self.max_angle_rad
        # Within the image circle where fov_deg is one (the pinhole's is its width's field of view instead).
        theta = torch.acos(dirs[valid][:, 2].clamp(-1, 1))
        assert theta.max() <= camera.max_theta + 1e-12

    # ------------------------------------------------------------------ no hole in the valid region
    def test_every_pixel_about_the_principal_point_has_its_ray(self, camera: CameraModel) -> None:
        """The disc about the axis's pixel that the cone of incidences up to ``theta_r`` (20 deg, or half the
        region's) covers, found from the projection: every point of it, on a dense polar grid from the centre out
        (1e-12 px to its rim), and every pixel centre in it, has a ray within that cone which projects back onto it;
        the centre's is the axis, and the incidence goes to 0 there (no cone of rays collapsed into it)."""
        centre, ok = camera.project(torch.tensor([[0.0, 0.0, 1.0]], dtype=torch.float64))
        assert ok.all()
        theta_r = min(math.radians(20.0), 0.5 * largest_valid_incidence(camera))
        rim, rim_ok = camera.project(cone(torch.tensor([theta_r]), 720))
        assert rim_ok.all()
        radius = 0.98 * float((rim - centre).norm(dim=-1).min())  # the rim's 720 points bound it to ~0.3 %
        r = torch.cat(
            [
                torch.tensor([0.0, 1e-12, 1e-9, 1e-6, 1e-3], dtype=torch.float64),
                torch.linspace(0, radius, 400)[1:],
            ]
        )
        a = torch.linspace(0.0, 2.0 * math.pi, 33, dtype=torch.float64)[:-1]
        polar = centre + (r[:, None, None] * torch.stack([torch.cos(a), torch.sin(a)], -1)).reshape(-1, 2)
        grid = camera.pixel_grid().reshape(-1, 2)
        uv = torch.cat([polar, grid[(grid - centre).norm(dim=-1) <= radius]])
        rays = camera.unproject(uv)
        assert torch.isfinite(rays).all(), (
            f"{int((~torch.isfinite(rays).all(-1)).sum())} points without a ray"
        )
        uv2, valid = camera.project(rays)
        assert valid.all() and (uv2 - uv).norm(dim=-1).max() <= self.max_pixel_err
        theta = torch.atan2(torch.hypot(rays[:, 0], rays[:, 1]), rays[:, 2])
        assert theta.max() <= theta_r + 1e-6 and theta[0] == 0
        assert theta[: 4 * len(a)].max() <= 1e-5  # within 1e-6 px of the centre: within 1e-5 rad of the axis

    def test_round_trip_from_the_axis_outwards(self, camera: CameraModel) -> None:
        """Directions at every incidence of the valid region, densely from the axis (and 1e-12 rad off it) to the
        region's edge, at 12 azimuths: each pixel they project to in and around the image has a ray, which projects
        back onto it."""
        top = largest_valid_incidence(camera)
        theta = torch.cat(
            [torch.tensor([1e-12, 1e-9, 1e-6, 1e-4], dtype=torch.float64), torch.linspace(0, top, 1500)]
        )
        uv, valid = camera.project(cone(theta, 12))
        w, h = camera.width, camera.height  # a frame around the image (see the field-of-view test)
        valid &= (uv[:, 0] > -w) & (uv[:, 0] < 2 * w) & (uv[:, 1] > -h) & (uv[:, 1] < 2 * h)
        assert valid[: 5 * 12].all()  # the axis and its neighbourhood
        uv = uv[valid]
        rays = camera.unproject(uv)
        assert torch.isfinite(rays).all(), (
            f"{int((~torch.isfinite(rays).all(-1)).sum())} pixels without a ray"
        )
        uv2, again = camera.project(rays)
        assert again.all() and (uv2 - uv).norm(dim=-1).max() <= self.max_pixel_err

    # ------------------------------------------------------------------ kinds and dtypes
    def test_numpy_and_torch_in_the_same_kind_and_dtype(self, camera: CameraModel) -> None:
        dirs = sphere_directions(62, seed=1).reshape(4, 16, 3)
        uv_t, valid_t = camera.project(dirs)
        uv_n, valid_n = camera.project(dirs.numpy())
        assert isinstance(uv_n, np.ndarray) and isinstance(valid_n, np.ndarray) and valid_n.dtype == bool
        assert uv_n.shape == (4, 16, 2) and valid_t.shape == (4, 16)
        np.testing.assert_array_equal(uv_n, uv_t.numpy())
        np.testing.assert_array_equal(valid_n, valid_t.numpy())
        uv32, _ = camera.project(dirs.float())
        assert uv32.dtype == torch.float32
        pix = camera.pixel_grid()[:: max(1, camera.height // 7), :: max(1, camera.width // 7)].reshape(-1, 2)
        for arr in (pix.float(), pix, pix.numpy().astype(np.float32), pix.numpy()):
            rays = camera.unproject(arr)
            assert type(rays) is type(arr) and rays.dtype == arr.dtype and rays.shape == (len(pix), 3)
        np.testing.assert_allclose(
            camera.unproject(pix.numpy()), camera.unproject(pix).numpy(), rtol=0, atol=0, equal_nan=True
        )

    # ------------------------------------------------------------------ valid region
    def test_outside_the_model_no_ray_and_no_valid_point(self, camera: CameraModel) -> None:
        far = torch.tensor(
            [[-50.0 * camera.width, 0.5 * camera.height], [0.5 * camera.width, 60.0 * camera.height]],
            dtype=torch.float64,
        )
        rays = camera.unproject(far)
        finite = torch.isfinite(rays).all(-1)
        # A pixel far outside the image either has no ray (NaN in all three coordinates) or a unit one.
        assert (torch.isnan(rays).all(-1) | finite).all()
        torch.testing.assert_close(
            rays[finite].norm(dim=-1), torch.ones(int(finite.sum()), dtype=torch.float64)
        )
        bad = torch.tensor(
            [[0.0, 0.0, 0.0], [math.nan, 0.0, 1.0], [math.inf, 0.0, 1.0], [0.0, 1.0, math.inf]],
            dtype=torch.float64,
        )
        assert not camera.project(bad)[1].any()
        behind = camera.project(torch.tensor([[0.0, 0.0, -1.0], [1e-3, 0.0, -1.0]], dtype=torch.float64))[1]
        assert behind.tolist() == [False, self.full_sphere]  # the back axis itself has no azimuth

    def test_valid_mask_is_the_projection_valid_region(self, camera: CameraModel) -> None:
        rays = camera.ray_grid(torch.float64)
        _, valid = camera.project(rays)
        expected = valid & torch.isfinite(rays).all(-1)
        assert torch.equal(camera.valid_mask(), expected)
        theta = camera.theta_grid()
        assert torch.isfinite(theta[camera.valid_mask()]).all()
        assert torch.isnan(theta[~torch.isfinite(rays).all(-1)]).all()

    # ------------------------------------------------------------------ identity
    def test_resized_keeps_the_lens(self, camera: CameraModel) -> None:
        w, h = camera.width, camera.height
        g = math.gcd(w, h)
        small = camera.resized(w // g * max(1, g // 4), h // g * max(1, g // 4))
        s = small.width / w
        dirs = sphere_directions(200, seed=2)
        uv, valid = camera.project(dirs)
        uv_s, valid_s = small.project(dirs)
        assert torch.equal(valid, valid_s)
        valid &= (uv.abs() < 3 * max(w, h)).all(-1)  # pixels a sensor has (see the field-of-view test)
        torch.testing.assert_close((uv_s[valid] + 0.5) / s, uv[valid] + 0.5, rtol=0, atol=1e-9)
        assert small.model == camera.model and small.resized(w, h) == small.resized(w, h)

    def test_dict_round_trip(self, camera: CameraModel) -> None:
        d = camera.to_dict()
        assert d["model"] == camera.model and d["width"] == camera.width and d["height"] == camera.height
        again = camera_from_dict(json.loads(json.dumps(d)))  # plain values only
        assert again == camera and hash(again) == hash(camera)
        assert again.to_dict() == d

    def test_bad_keys_are_named(self, camera: CameraModel) -> None:
        d = camera.to_dict()
        with pytest.raises(ValueError, match=r"unknown camera keys \['zoom'\]"):
            camera_from_dict({**d, "zoom": 2})
        with pytest.raises(ValueError, match="missing"):
            camera_from_dict({k: v for k, v in d.items() if k != "width"})

    # ------------------------------------------------------------------ local scale
    def test_pixels_per_radian_is_the_largest_local_scale(self, camera: CameraModel) -> None:
        ppr = camera.pixels_per_radian()
        assert ppr.shape == (camera.height, camera.width) and torch.isfinite(ppr).all() and (ppr > 0).all()
        mask = camera.valid_mask()
        idx = mask.reshape(-1).nonzero().squeeze(1)
        idx = idx[torch.linspace(0, len(idx) - 1, 50).long()]
        rays = camera.ray_grid(torch.float64).reshape(-1, 3)[idx]
        uv0, _ = camera.project(rays)
        h = 1e-5
        largest = torch.zeros(len(idx), dtype=torch.float64)
        for a in torch.linspace(0, math.pi, 13)[:-1].tolist():
            # a direction in the tangent plane of each ray, at angle a
            helper = torch.tensor([0.3, 0.5, 0.81], dtype=torch.float64).expand_as(rays)
            t1 = torch.linalg.cross(rays, helper)
            t1 = t1 / t1.norm(dim=-1, keepdim=True)
            t2 = torch.linalg.cross(rays, t1)
            e = math.cos(a) * t1 + math.sin(a) * t2
            uv1, _ = camera.project(rays * math.cos(h) + e * math.sin(h))
            largest = torch.maximum(largest, (uv1 - uv0).norm(dim=-1) / h)
        torch.testing.assert_close(largest, ppr.reshape(-1)[idx], rtol=2e-2, atol=0)
