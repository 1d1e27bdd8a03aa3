"""The ideal lenses (``ideal_camera``): lens models, round trips, validity, numpy/torch parity and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry import CameraModel, camera_from_dict, ideal_camera, incidence_angle

KB = (0.05, -0.01, 0.002, -0.0003)
CAMERAS = {
    "equidistant": dict(model="equidistant"),
    "equisolid": dict(model="equisolid"),
    "stereographic": dict(model="stereographic"),
    "orthographic": dict(model="orthographic", fov_deg=180.0),
    "kannala_brandt": dict(model="kannala_brandt", k=KB),
    "kb_offcentre": dict(model="kannala_brandt", k=(-0.03, 0.001, 0.0, 0.0), cx=250.0, cy=270.3, focal=150.0),
}


@pytest.fixture(params=list(CAMERAS), ids=list(CAMERAS))
def camera(request) -> CameraModel:
    return ideal_camera(512, 544, **CAMERAS[request.param])


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_round_trip_over_the_whole_valid_image(camera: CameraModel, dtype: torch.dtype) -> None:
    mask = camera.valid_mask()
    assert mask.any()
    uv = camera.pixel_grid(dtype)[mask]
    rays = camera.unproject(uv)
    assert rays.dtype == dtype
    torch.testing.assert_close(rays.norm(dim=-1), torch.ones(len(rays), dtype=dtype))
    uv2, valid = camera.project(rays)
    assert valid.all()
    assert (uv2 - uv).abs().max() < 1e-3


def test_radial_model_formulas() -> None:
    """The image radius follows each model's textbook formula r(theta)."""
    theta = torch.linspace(0.01, math.radians(85), 50, dtype=torch.float64)
    points = torch.stack([torch.sin(theta), torch.zeros_like(theta), torch.cos(theta)], -1)
    f = 200.0
    expected = {
        "equidistant": f * theta,
        "equisolid": 2 * f * torch.sin(theta / 2),
        "stereographic": 2 * f * torch.tan(theta / 2),
        "orthographic": f * torch.sin(theta),
        "kannala_brandt": f
        * theta
        * (1 + KB[0] * theta**2 + KB[1] * theta**4 + KB[2] * theta**6 + KB[3] * theta**8),
    }
    for model, r in expected.items():
        cam = ideal_camera(
            1001, 1001, fov_deg=180.0, model=model, focal=f, k=KB if model == "kannala_brandt" else None
        )
        uv, _ = cam.project(points)
        torch.testing.assert_close(uv[:, 0] - cam.cx, r)
        torch.testing.assert_close(uv[:, 1] - cam.cy, torch.zeros_like(r), atol=1e-9, rtol=0)


def test_default_focal_inscribes_the_image_circle() -> None:
    cam = ideal_camera(640, 480, fov_deg=190.0)
    edge = math.radians(95.0)
    uv, valid = cam.project(
        np.array([[math.sin(edge), 0.0, math.cos(edge)], [0.0, math.sin(edge), math.cos(edge)]])
    )
    assert cam.cx == 319.5 and cam.cy == 239.5
    np.testing.assert_allclose(uv[0, 0] - cam.cx, 240.0)  # r_max = min(W, H) / 2
    np.testing.assert_allclose(uv[1, 1] - cam.cy, 240.0)
    assert valid.all()
    assert math.isclose(cam.focal, 240.0 / edge)


def test_points_beyond_half_fov_are_invalid_not_wrapped() -> None:
    cam = ideal_camera(256, 256, fov_deg=190.0)
    theta = np.radians([94.0, 95.5, 120.0, 179.0, 180.0])
    pts = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], -1)
    _, valid = cam.project(pts)
    assert valid.tolist() == [True, False, False, False, False]
    # A point straight behind the camera is invalid too, and so is the origin and any non-finite point.
    _, valid = cam.project(
        np.array([[0, 0, -1.0], [0, 0, 0.0], [np.nan, 0, 1.0], [np.inf, 0, 1.0], [0, 1.0, np.inf]])
    )
    assert not valid.any()
    # An infinite z would pass the angle test (theta 0, or pi for a full-sphere lens) if nothing caught it.
    full_sphere = ideal_camera(256, 256, fov_deg=360.0)
    _, valid = full_sphere.project(
        np.array([[0.5, 0, np.inf], [0.5, 0, -np.inf], [0, 0, 0.0], [0.5, 0, -1.0]])
    )
    assert valid.tolist() == [False, False, False, True]


def test_orthographic_rays_beyond_the_model_are_nan() -> None:
    cam = ideal_camera(100, 100, fov_deg=180.0, model="orthographic")
    ray = cam.unproject(torch.tensor([[cam.cx + cam.focal * 1.2, cam.cy]], dtype=torch.float64))
    assert torch.isnan(ray).all()
    assert not cam.valid_mask()[0, 0]  # the corner is outside the image circle


def test_numpy_and_torch_inputs_any_batch_shape() -> None:
    cam = ideal_camera(320, 320)
    pts = np.random.default_rng(0).normal(size=(2, 3, 4, 3))
    uv_np, valid_np = cam.project(pts)
    uv_t, valid_t = cam.project(torch.from_numpy(pts))
    assert isinstance(uv_np, np.ndarray) and isinstance(uv_t, torch.Tensor)
    assert uv_np.shape == (2, 3, 4, 2) and valid_np.shape == (2, 3, 4)
    np.testing.assert_allclose(uv_np, uv_t.numpy())
    np.testing.assert_array_equal(valid_np, valid_t.numpy())
    rays = cam.unproject(np.float32([[10, 20], [160, 160]]))
    assert rays.dtype == np.float32 and rays.shape == (2, 3)


def test_grids_are_consistent() -> None:
    cam = ideal_camera(96, 80, fov_deg=200.0)
    rays = cam.ray_grid()
    assert rays.shape == (80, 96, 3) and rays.dtype == torch.float32
    assert cam.ray_grid() is rays  # cached
    theta = cam.theta_grid()
    torch.testing.assert_close(theta, incidence_angle(rays), atol=1e-5, rtol=0)
    torch.testing.assert_close(cam.valid_mask(), theta <= math.radians(100.0) + 1e-6)


def test_resized_camera_keeps_the_lens() -> None:
    cam = ideal_camera(1536, 1536, model="kannala_brandt", k=KB)
    small = cam.resized(512, 512)
    assert small == ideal_camera(512, 512, model="kannala_brandt", k=KB)
    # The same ray lands on the same relative image position.
    ray = torch.tensor([[0.3, -0.2, 0.5]], dtype=torch.float64)
    uv_big, _ = cam.project(ray)
    uv_small, _ = small.project(ray)
    torch.testing.assert_close((uv_small + 0.5) * 3, uv_big + 0.5)


def test_serialisation_round_trip(camera: CameraModel) -> None:
    again = camera_from_dict(camera.to_dict())
    assert again == camera and hash(again) == hash(camera)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(model="orthographic", fov_deg=190.0), "orthographic"),
        (dict(model="stereographic", fov_deg=360.0), "stereographic"),
        (dict(model="fisheye624"), "model must be one of"),
        (dict(fov_deg=0.0), "fov_deg"),
        (dict(fov_deg=float("nan")), "fov_deg"),
        (dict(model="kannala_brandt", k=(0.0, 0.0)), "four"),
        (dict(model="kannala_brandt", k=(-0.5, 0.0, 0.0, 0.0)), "not increasing"),
        (dict(model="equidistant", k=(0.1, 0, 0, 0)), "only used by the kannala_brandt"),
        (dict(focal=-3.0), "focal"),
    ],
)
def test_bad_parameters_raise(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        ideal_camera(100, 100, **kwargs)


def test_bad_inputs_raise() -> None:
    cam = ideal_camera(64, 64)
    with pytest.raises(ValueError, match=r"points must have shape \[\.\.\., 3\]"):
        cam.project(np.zeros((4, 2)))
    with pytest.raises(ValueError, match=r"uv must have shape \[\.\.\., 2\]"):
        cam.unproject(np.zeros((4, 3)))
    with pytest.raises(ValueError, match="width and height"):
        ideal_camera(0, 64)
    with pytest.raises(ValueError, match="unknown camera keys"):
        camera_from_dict({"width": 4, "height": 4, "fov": 190})
