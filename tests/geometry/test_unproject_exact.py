"""Back-projection is exact wherever it gives a ray and NaN wherever it does not, for every camera model (issue #35:
"no silent wrong geometry, anywhere").

Every family of ``CAMERA_MODELS`` is drawn at random (seeded) over its realistic range, not only the published
calibrations: polynomials that turn back or blow up inside or beyond the image, mirrors past the sphere's rim,
distortions that fold. On a dense grid over each image (pixel centres and the half-pixel points between them):

- a pixel has a whole unit ray or none (NaN in all three coordinates), and ``valid_mask`` only where it has one;
- a ray projects validly (its region; only ``fov_deg`` may exclude it) and back onto its pixel within 1e-6 px;
- for the radial models, the ray's incidence lies where the forward radius ``r(theta)`` is increasing, found here
  independently on a fine grid: the ray is the pixel's only one, not a second root of a polynomial;
- for COLMAP's thin-prism models, on the disc of ``theta`` where the distortion is one-to-one: its Jacobian
  determinant, by central differences of COLMAP's ``Distortion`` written out independently, is positive there.

And from the other side, directions over the sphere that project validly into the image come back within 1e-9 rad.
Finally the OCamCalib file of the issue's kind (``OCAM_LONG_INVPOL``) through the file reader.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry.cameras import CAMERA_MODELS, CameraModel, camera_from_dict
from airfisheye_bench.io.calibration_files import read_calibration
from tests.helpers import calibration_fixtures as fx
from tests.helpers import colmap_models as colmap
from tests.helpers.camera_tester import angle_between, sphere_directions
from tests.helpers.random_cameras import FAMILIES, random_cameras

MAX_PX = 1e-6
MAX_RAD = 1e-9


def ocam_fit(cam: CameraModel) -> Callable[[np.ndarray], np.ndarray]:
    """OCam's world2cam radius at ``theta`` (numpy), without the model's chord near the axis."""
    coeffs = np.asarray(cam.world2cam)
    return lambda t: np.polynomial.polynomial.polyval(np.asarray(t) - np.pi / 2, coeffs)


def ocam_head(cam: CameraModel, samples: int = 100_001) -> float:
    """Where OCam's chord from the principal point should meet world2cam, found here on a fine grid: where the fit,
    increasing from its first minimum on, reaches twice the largest ``|radius|`` it has before it increases."""
    fit = ocam_fit(cam)
    t = np.linspace(0.0, np.pi, samples)
    r = fit(t)
    first_up = int(np.argmax(np.diff(r) > 0))  # the fit's first minimum (0 where it increases from the axis)
    d = max(abs(r[0]), abs(r[first_up]))
    if d == 0:
        return 0.0
    return float(t[first_up + int(np.argmax(r[first_up:] >= 2 * d))])


def forward_radius(cam: CameraModel) -> Callable[[np.ndarray], np.ndarray] | None:
    """The radial models' ``r(theta)`` (any positive scale), evaluated here with numpy, not by the model's code."""
    if cam.model == "ocam":
        fit = ocam_fit(cam)
        head = cam.theta_head
        if head == 0:
            return fit
        slope = fit(head) / head  # the chord from the principal point, below theta_head
        return lambda t: np.where(np.asarray(t) < head, slope * np.asarray(t), fit(t))
    if cam.model == "radial_poly":
        coeffs = np.array([0.0, cam.k1, cam.k2, cam.k3, cam.k4])
        return lambda t: np.polynomial.polynomial.polyval(t, coeffs)
    if cam.model == "kannala_brandt":
        coeffs = np.array([0.0, 1.0, 0.0, cam.k1, 0.0, cam.k2, 0.0, cam.k3, 0.0, cam.k4])
        return lambda t: np.polynomial.polynomial.polyval(t, coeffs)
    return None


def increasing_until(r: Callable[[np.ndarray], np.ndarray], samples: int = 100_001) -> float:
    """First incidence angle (on a fine grid over [0, pi]) where ``r`` stops increasing, else pi."""
    t = np.linspace(0.0, np.pi, samples)
    flat = np.nonzero(np.diff(r(t)) <= 0)[0]
    return float(t[flat[0]]) if len(flat) else np.pi


def dense_grid(cam: CameraModel) -> torch.Tensor:
    """Pixel centres and the half-pixel points between them, over the whole image, ``[N, 2]`` float64."""
    u = torch.arange(-0.5, cam.width - 0.49, 0.5, dtype=torch.float64)
    v = torch.arange(-0.5, cam.height - 0.49, 0.5, dtype=torch.float64)
    vv, uu = torch.meshgrid(v, u, indexing="ij")
    return torch.stack([uu, vv], -1).reshape(-1, 2)


def check_exact(cam: CameraModel) -> dict[str, float]:
    """Assert the contract of the module docstring on one camera; returns its numbers."""
    uv = dense_grid(cam)
    rays = cam.unproject(uv)
    has = torch.isfinite(rays).all(-1)
    assert (has | torch.isnan(rays).all(-1)).all(), f"{cam}: a ray that is partly NaN"
    assert not (cam.valid_mask() & ~torch.isfinite(cam.ray_grid(torch.float64)).all(-1)).any()
    rays, uv = rays[has], uv[has]
    assert ((rays.norm(dim=-1) - 1).abs() <= 1e-12).all(), f"{cam}: a ray is not unit-length"
    uv2, valid = cam.project(rays)
    theta = torch.atan2(torch.hypot(rays[:, 0], rays[:, 1]), rays[:, 2])
    # Only the field of view may exclude a back-projected ray: it is in the model's region.
    assert (valid | (theta > cam.max_theta)).all(), f"{cam}: unproject gave a ray outside the model's region"
    err = (uv2 - uv).norm(dim=-1)
    worst = float(err.max()) if len(err) else 0.0
    assert worst <= MAX_PX, f"{cam}: pixel -> ray -> pixel off by {worst:.3g} px"
    r = forward_radius(cam)
    if r is not None:
        # The ray's incidence is where r(theta) increases: the pixel's only ray (no second root past a turn).
        limit = increasing_until(r)
        step = np.pi / 100_000
        assert cam.theta_limit <= limit + step, (
            f"{cam}: valid to {cam.theta_limit}, r(theta) turns at {limit}"
        )
        assert not len(theta) or float(theta.max()) <= limit + step
        if cam.model == "ocam":
            # The chord meets the fit where this grid says it should; below, the radius rises from 0 on the axis.
            assert abs(cam.theta_head - ocam_head(cam)) <= step
            assert np.all(r(theta.numpy()) >= 0) and r(np.array([0.0]))[0] == 0
    if cam.model in COLMAP_NAMES or (cam.model == "pinhole_radtan" and cam.theta_limit < math.pi / 2):
        # The disc of theta the model solves on is one-to-one: COLMAP's distortion (written out independently)
        # keeps a positive Jacobian determinant on it, by central differences.
        assert min_jacobian_det(cam) > 0, f"{cam}: the distortion folds inside theta_limit={cam.theta_limit}"
        assert not len(theta) or float(theta.max()) <= cam.theta_limit + 1e-12
    # From the sphere: every direction that projects validly into the image comes back (no missing ray), to
    # 1e-9 rad, or to what 1e-9 px is worth where the lens is nearly flat (a polynomial about to turn: there one
    # pixel spans a wide angle, whatever the solver).
    dirs = sphere_directions(3000, seed=cam.width)
    puv, pvalid = cam.project(dirs)
    pvalid &= cam.in_image(puv)
    back = cam.unproject(puv[pvalid])
    assert torch.isfinite(back).all(), f"{cam}: a pixel the lens sees has no ray"
    angle = angle_between(back, dirs[pvalid])
    bar = MAX_RAD + 1e-9 / smallest_scale(cam, dirs[pvalid])
    assert (angle <= bar).all(), f"{cam}: direction -> pixel -> ray off by {float(angle.max()):.3g} rad"
    return {"px": worst, "rad": float(angle.max()) if len(angle) else 0.0, "rays": int(has.sum())}


#: The thin-prism models by their COLMAP names, for COLMAP's Distortion (tests/helpers/colmap_models.py).
COLMAP_NAMES = {
    "thin_prism_fisheye": "THIN_PRISM_FISHEYE",
    "rad_tan_thin_prism_fisheye": "RAD_TAN_THIN_PRISM_FISHEYE",
}
#: The pinhole's coefficients in FULL_OPENCV's order.
FULL_OPENCV = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")


def min_jacobian_det(cam: CameraModel, h: float = 1e-6) -> float:
    """Smallest Jacobian determinant of COLMAP's ``m -> m + Distortion(m)`` over the disc where the model is valid,
    ``|m| <= theta_limit`` (the pinhole: ``|m| <= tan(theta_limit)``; 200 radii up to 0.999 of it, 256 azimuths), by
    central differences."""
    if cam.model == "pinhole_radtan":
        model, extra, limit = "FULL_OPENCV", [getattr(cam, n) for n in FULL_OPENCV], math.tan(cam.theta_limit)
    else:
        names = cam.coefficients
        model, extra, limit = COLMAP_NAMES[cam.model], [getattr(cam, n) for n in names], cam.theta_limit
    r = np.linspace(0.0, 0.999 * limit, 201)[1:, None]
    a = np.linspace(0.0, 2 * np.pi, 257)[None, :-1]
    x, y = r * np.cos(a), r * np.sin(a)

    def f(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dx, dy = colmap.distortion(model, extra, x, y)
        return x + dx, y + dy

    (xa, ya), (xb, yb) = f(x + h, y), f(x - h, y)
    (xc, yc), (xd, yd) = f(x, y + h), f(x, y - h)
    det = (xa - xb) * (yc - yd) - (xc - xd) * (ya - yb)
    return float(det.min()) / (4 * h * h)


def smallest_scale(cam: CameraModel, d: torch.Tensor, h: float = 1e-7) -> torch.Tensor:
    """Smaller singular value of the projection's Jacobian with respect to the unit direction ``d`` (pixels per
    radian along the direction the image changes least), by central differences."""
    helper = torch.tensor([0.3, 0.5, 0.81], dtype=torch.float64).expand_as(d)
    e1 = torch.linalg.cross(d, helper)
    e1 = e1 / e1.norm(dim=-1, keepdim=True)
    e2 = torch.linalg.cross(d, e1)
    cols = [(cam.project(d + h * e)[0] - cam.project(d - h * e)[0]) / (2 * h) for e in (e1, e2)]
    a, b, c = (cols[0] ** 2).sum(-1), (cols[0] * cols[1]).sum(-1), (cols[1] ** 2).sum(-1)
    return torch.sqrt((0.5 * (a + c) - torch.sqrt(0.25 * (a - c) ** 2 + b * b)).clamp_min(1e-300))


# ---------------------------------------------------------------------------------------------- tests
def test_every_family_of_the_registry_is_drawn() -> None:
    assert set(CAMERA_MODELS) <= set(FAMILIES)
    # The rest are variants of a model (its name a family's, not a registry key).
    assert {FAMILIES[f](np.random.default_rng(0))["model"] for f in FAMILIES} == set(CAMERA_MODELS)


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_unproject_is_exact_on_random_calibrations(family: str) -> None:
    cams = random_cameras(family)
    stats = [check_exact(cam) for cam in cams]
    assert sum(s["rays"] for s in stats) > 0
    if family in ("kannala_brandt", "ocam", "radial_poly"):
        # The draws reach polynomials that turn back inside 180 deg (the case the valid region must follow).
        assert any(cam.theta_limit < math.pi for cam in cams)


def _theta_of_radius(radius: Callable[[np.ndarray], np.ndarray], r: np.ndarray, hi: float) -> np.ndarray:
    """Incidence angle where ``radius`` is ``r`` (bisection in numpy; ``radius`` increases on [0, hi])."""
    lo_t, hi_t = np.zeros_like(r), np.full_like(r, hi)
    for _ in range(80):
        mid = 0.5 * (lo_t + hi_t)
        above = radius(mid) > r
        lo_t, hi_t = np.where(above, lo_t, mid), np.where(above, mid, hi_t)
    return 0.5 * (lo_t + hi_t)


def test_ocamcalib_long_invpol_file(tmp_path: Path) -> None:
    """The issue's kind of file: 33 terms, 1024 x 768, exact to the image's corners at 123 deg; valid only where
    world2cam increases and stays within reach of the image, not to 180 deg; negative on the axis, where the chord
    from the principal point takes over (every pixel about the centre has its ray, the axis the centre's)."""
    path = tmp_path / "calib_results.txt"
    path.write_text(fx.OCAM_LONG_INVPOL)
    cam = camera_from_dict(read_calibration(path).camera)
    assert (cam.width, cam.height, len(cam.world2cam)) == (1024, 768, 33)
    r = forward_radius(cam)
    assert ocam_fit(cam)(0.0) < -0.6 and r(np.array([np.pi]))[0] > 1e7  # what the fit does off its data

    # Every pixel of the image (a 4-px grid, and the frame's edge at every half pixel) has its ray, exact both ways.
    edge = dense_grid(cam)
    edge = edge[(edge[:, 0] == -0.5) | (edge[:, 0] == 1023.5) | (edge[:, 1] == -0.5) | (edge[:, 1] == 767.5)]
    uv = torch.cat([cam.pixel_grid()[::4, ::4].reshape(-1, 2), edge])
    rays = cam.unproject(uv)
    assert torch.isfinite(rays).all()
    uv2, valid = cam.project(rays)
    assert valid.all() and (uv2 - uv).norm(dim=-1).max() <= MAX_PX
    theta = torch.atan2(torch.hypot(rays[:, 0], rays[:, 1]), rays[:, 2]).numpy()
    gx, gy = cam._sensor(uv[:, 0], uv[:, 1])
    expected = _theta_of_radius(r, torch.hypot(gx, gy).numpy(), math.radians(130.0))
    assert np.abs(theta - expected).max() <= MAX_RAD
    # The image reaches 123 deg at its corners; the field of view it reports is that (on a 256 x 192 copy of the
    # lens, whose corner pixels' centres lie a little further in), not 360 deg.
    assert 123.0 < math.degrees(theta.max()) < 123.5
    assert 245.0 < cam.resized(256, 192).coverage_deg < 246.5

    # The valid region: from the axis (the chord up to twice the fit's -0.67 px, 0.26 deg), to where the radius
    # leaves the frame 50 images around.
    fit = ocam_fit(cam)
    assert 0.0 < cam.theta_head < 0.01 and math.radians(120.0) < cam.theta_limit < math.radians(170.0)
    assert fit(cam.theta_head) == pytest.approx(-2 * fit(0.0), abs=1e-7)  # to the fit's rounding there
    assert r(np.array([cam.theta_limit]))[0] == pytest.approx(cam._inverse.y_range[1], rel=1e-9)
    t = torch.tensor(
        [0.0, 1e-9, 0.5 * cam.theta_head, cam.theta_limit - 1e-6, cam.theta_limit + 1e-6, math.pi - 1e-3]
    )
    dirs = torch.stack([torch.sin(t), torch.zeros_like(t), torch.cos(t)], -1).double()
    puv, pvalid = cam.project(dirs)
    assert pvalid.tolist() == [True, True, True, True, False, False]
    back = cam.unproject(puv)
    assert torch.isfinite(back[:4]).all() and torch.isnan(back[4:]).all()
    assert angle_between(back[:4], dirs[:4]).max() <= MAX_RAD
    # Near the centre, the radius of a ray is the chord's, from 0 on the axis: no pixel there is left without one.
    assert (puv[1:3] - puv[0]).norm(dim=-1).tolist() == pytest.approx(
        (-2 * fit(0.0) / cam.theta_head * t[1:3].numpy()).tolist(), rel=1e-6
    )
