"""Every camera model through the shared tester: real published calibrations, the ideal lenses, and OCamCalib fits
that are off on the optical axis (the end of their data), as files and as synthetic ss / invpol pairs."""

from __future__ import annotations

import math
from typing import ClassVar

import pytest
import torch

from airfisheye_bench.geometry.cameras import CAMERA_MODELS, camera_from_dict, ideal_camera
from tests.helpers import calibration_fixtures as fx
from tests.helpers.camera_tester import CALIBRATIONS, CameraModelTester, angle_between


class TestEquidistant(CameraModelTester):
    camera_dict: ClassVar[dict] = {"model": "equidistant", "width": 320, "height": 256, "fov_deg": 190.0}


class TestEquidistantFullSphere(CameraModelTester):
    camera_dict: ClassVar[dict] = {"model": "equidistant", "width": 128, "height": 128, "fov_deg": 360.0}
    full_sphere = True


class TestEquisolid(CameraModelTester):
    camera_dict: ClassVar[dict] = {
        "model": "equisolid",
        "width": 300,
        "height": 300,
        "fov_deg": 230.0,
        "cx": 140.2,
    }


class TestStereographic(CameraModelTester):
    camera_dict: ClassVar[dict] = {"model": "stereographic", "width": 256, "height": 192, "fov_deg": 200.0}


class TestOrthographic(CameraModelTester):
    camera_dict: ClassVar[dict] = {"model": "orthographic", "width": 256, "height": 256, "fov_deg": 180.0}


class TestKannalaBrandtTumVI(CameraModelTester):
    camera_dict: ClassVar[dict] = CALIBRATIONS["tumvi512_cam0_kb"]["camera"]
    full_sphere = True  # no fov_deg, and the polynomial increases up to 180 deg


class TestKannalaBrandtSkewAndFov(CameraModelTester):
    camera_dict: ClassVar[dict] = {
        **CALIBRATIONS["tumvi512_cam0_kb"]["camera"],
        "skew": 0.002,
        "fov_deg": 195.0,
    }


class TestKannalaBrandtOldForm(CameraModelTester):
    camera_dict: ClassVar[dict] = {
        "model": "kannala_brandt",
        "width": 512,
        "height": 512,
        "fov_deg": 190.0,
        "k": [0.05, -0.01, 0.002, -0.0003],
    }


class TestDoubleSphereTumVI(CameraModelTester):
    camera_dict: ClassVar[dict] = CALIBRATIONS["tumvi512_cam0_ds"]["camera"]


class TestEucmTumVI(CameraModelTester):
    camera_dict: ClassVar[dict] = CALIBRATIONS["tumvi512_cam0_eucm"]["camera"]


class TestFovColmap(CameraModelTester):
    # COLMAP's own FOV test parameters (src/colmap/sensor/models_test.cc, FOV.Nominal) on the image they centre.
    camera_dict: ClassVar[dict] = {
        "model": "fov",
        "width": 772,
        "height": 1022,
        "fx": 651.123,
        "fy": 655.123,
        "cx": 386.123,
        "cy": 511.123,
        "omega": 0.9,
    }


class TestThinPrismFisheyeColmap(CameraModelTester):
    # COLMAP's own THIN_PRISM_FISHEYE test parameters (models_test.cc, ThinPrismFisheye.Nominal).
    camera_dict: ClassVar[dict] = {
        "model": "thin_prism_fisheye",
        "width": 772,
        "height": 1022,
        "fx": 651.123,
        "fy": 655.123,
        "cx": 386.123,
        "cy": 511.123,
        **dict(zip(("k1", "k2", "p1", "p2", "k3", "k4", "sx1", "sy1"),
                   (-0.471, 0.223, -0.001, 0.001, 0.001, 0.02, -0.02, 0.001), strict=True)),
    }  # fmt: skip


class TestThinPrismFisheyeFov(CameraModelTester):
    # A 195 deg image circle on TUM-VI cam0's Kannala-Brandt lens with tangential and thin-prism terms.
    camera_dict: ClassVar[dict] = {
        **{k: v for k, v in CALIBRATIONS["tumvi512_cam0_kb"]["camera"].items() if k != "skew"},
        "model": "thin_prism_fisheye",
        "p1": 5e-4,
        "p2": -3e-4,
        "sx1": 2e-3,
        "sy1": -1e-3,
        "fov_deg": 195.0,
    }


class TestRadTanThinPrismFisheyeColmap(CameraModelTester):
    # COLMAP's own RAD_TAN_THIN_PRISM_FISHEYE test parameters (models_test.cc, RadTanThinPrismFisheye.Nominal).
    camera_dict: ClassVar[dict] = {
        "model": "rad_tan_thin_prism_fisheye",
        "width": 772,
        "height": 1022,
        "fx": 651.123,
        "fy": 655.123,
        "cx": 386.123,
        "cy": 511.123,
        **dict(zip(("k0", "k1", "k2", "k3", "k4", "k5", "p0", "p1", "s0", "s1", "s2", "s3"),
                   (-0.0232, 0.0924, -0.0591, 0.003, 0.0048, -0.0009, 0.0002, 0.0005, -0.0009, -0.0001, 0.00007,
                    -0.00017), strict=True)),
    }  # fmt: skip


class TestDivisionColmapBarrel(CameraModelTester):
    # COLMAP's DIVISION test parameters (models_test.cc, Division.Nominal), k < 0: the region is the whole sphere.
    camera_dict: ClassVar[dict] = {
        "model": "division",
        "width": 772,
        "height": 1022,
        "fx": 651.123,
        "fy": 655.123,
        "cx": 386.123,
        "cy": 511.123,
        "k": -0.1,
    }
    full_sphere = True


class TestDivisionColmapPincushion(CameraModelTester):
    # COLMAP's k > 0 test parameters: in front of the camera, to the fold t = 1 / sqrt(k) (58 deg), outside the
    # image here (the random calibrations of test_unproject_exact.py put it inside).
    camera_dict: ClassVar[dict] = {**TestDivisionColmapBarrel.camera_dict, "k": 0.1}


class TestUnifiedKitti360Image02(CameraModelTester):
    camera_dict: ClassVar[dict] = CALIBRATIONS["kitti360_image_02"]["camera"]


class TestUnifiedKitti360Image03(CameraModelTester):
    camera_dict: ClassVar[dict] = CALIBRATIONS["kitti360_image_03"]["camera"]


class TestUnifiedSmallXi(CameraModelTester):
    camera_dict: ClassVar[dict] = {
        "model": "unified",
        "width": 400,
        "height": 300,
        "fx": 300.0,
        "fy": 290.0,
        "cx": 201.0,
        "cy": 148.0,
        "xi": 0.8,
        "k1": -0.1,
        "k2": 0.02,
        "p1": 1e-3,
        "p2": -5e-4,
    }


class TestRadialPolyWoodScape(CameraModelTester):
    camera_dict: ClassVar[dict] = CALIBRATIONS["woodscape_front"]["camera"]
    full_sphere = True  # no fov_deg, and the polynomial increases up to 180 deg


class TestOcamKodak(CameraModelTester):
    camera_dict: ClassVar[dict] = CALIBRATIONS["ocam_kodak_sp360"]["camera"]
    full_sphere = True  # no fov_deg, and the polynomial increases up to 180 deg


class TestOcamLongInvpolFile(CameraModelTester):
    """33 terms, -0.67 px on the axis (tests/helpers/calibration_fixtures.py)."""

    calibration_file = ("calib_results.txt", fx.OCAM_LONG_INVPOL)


class TestOcamNegativeAxisFile(CameraModelTester):
    """-0.64 px on the axis, where its 25 terms cancel from 3e11 px: float64 has the radius there to ~1e-4 px (at
    full size; ~3e-5 px on the tester's quarter-size copy), and the round trips are that exact, no more."""

    calibration_file = ("calib_results.txt", fx.OCAM_NEGATIVE_AXIS)
    max_pixel_err = 1e-4
    max_angle_rad = 1e-6


def _ocam_off_on_the_axis(c0: float, n: int = 30, f: float = 300.0) -> dict:
    """An OCamCalib model (1024 x 768, 220 deg) of the lens ``r = f theta`` whose world2cam is off by ``c0`` px on
    the axis as a fit is at the end of its data: ``f theta + c0 ((pi/2 - theta) / (pi/2))^n`` in powers of
    ``theta - pi/2`` (its slope on the axis ``f - c0 n / (pi/2)``: flat at ``c0 = f (pi/2) / n``, 15.7 px, and
    decreasing at first beyond). cam2world: the same lens's, ``-rho / tan(rho / f)`` to fourth order (a1 = 0)."""
    world2cam = [f * math.pi / 2, f] + [0.0] * (n - 2) + [c0 * (-1) ** n / (math.pi / 2) ** n]
    return {
        "model": "ocam",
        "width": 1024,
        "height": 768,
        "cx": 511.3,
        "cy": 383.6,
        "c": 1.0004,
        "d": 0.0003,
        "e": -0.0002,
        "cam2world": [-f, 0.0, 1.0 / (3.0 * f), 0.0, 1.0 / (45.0 * f**3)],
        "world2cam": world2cam,
        "fov_deg": 220.0,
    }


class TestOcamNegativeOnTheAxis(CameraModelTester):
    camera_dict: ClassVar[dict] = _ocam_off_on_the_axis(-0.6)


class TestOcamPositiveOnTheAxis(CameraModelTester):
    camera_dict: ClassVar[dict] = _ocam_off_on_the_axis(0.8)


class TestOcamFlatOnTheAxis(CameraModelTester):
    camera_dict: ClassVar[dict] = _ocam_off_on_the_axis(300.0 * (math.pi / 2) / 30)


class TestOcamDecreasingFromTheAxis(CameraModelTester):
    camera_dict: ClassVar[dict] = _ocam_off_on_the_axis(18.0)


class TestPinholeRadtanRos(CameraModelTester):
    camera_dict: ClassVar[dict] = CALIBRATIONS["ros_kodak_plumb_bob"]["camera"]


class TestPinholeCubeFace(CameraModelTester):
    camera_dict: ClassVar[dict] = {
        "model": "pinhole_radtan",
        "width": 64,
        "height": 64,
        "fx": 32.0,
        "fy": 32.0,
        "cx": 31.5,
        "cy": 31.5,
    }


class TestPinhole(CameraModelTester):
    # The ideal perspective lens: a 100 deg field of view across a 4:3 frame, the principal point off-centre; the
    # whole frame is valid (no image circle).
    camera_dict: ClassVar[dict] = {
        "model": "pinhole",
        "width": 320,
        "height": 240,
        "fov_deg": 100.0,
        "cx": 161.3,
        "cy": 118.2,
    }

    def test_the_whole_frame_is_valid_and_the_rings_reach_the_corners(self, camera) -> None:
        assert camera.valid_mask().all()
        corner = math.degrees(float(camera.theta_grid().max()))
        assert camera.coverage_deg == pytest.approx(2 * corner) and corner > camera.fov_deg / 2

    def test_fov_is_across_the_width(self, camera) -> None:
        edge = torch.tensor([[-0.5, camera.cy], [camera.width - 0.5, camera.cy]], dtype=torch.float64)
        rays = camera.unproject(edge)
        spread = math.degrees(float(angle_between(rays[:1], rays[1:])))
        focal = (camera.width / 2) / math.tan(math.radians(camera.fov_deg) / 2)
        # The principal point is off-centre: the two edges' angles add up to the field of view only at cx = W/2 - 1/2.
        assert camera.focal == pytest.approx(focal)
        assert math.radians(spread) == pytest.approx(
            math.atan((camera.cx + 0.5) / focal) + math.atan((camera.width - 0.5 - camera.cx) / focal)
        )


def test_pinhole_at_90_degrees_is_a_cube_face() -> None:
    """The default principal point and fov_deg=90 on an S x S image: the cube face's camera (focal S / 2)."""
    face = camera_from_dict(TestPinholeCubeFace.camera_dict)
    pinhole = ideal_camera(64, 64, fov_deg=90.0, model="pinhole")
    dirs = torch.randn(500, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(3))
    uv_a, valid_a = face.project(dirs)
    uv_b, valid_b = pinhole.project(dirs)
    assert torch.equal(valid_a, valid_b)
    torch.testing.assert_close(uv_a[valid_a], uv_b[valid_b], rtol=0, atol=1e-9)


def test_pinhole_field_of_view_is_below_180_and_focal_sets_it() -> None:
    for fov in (0.0, 180.0, 200.0):
        with pytest.raises(ValueError, match=r"fov_deg must be in \(0, 180\)"):
            ideal_camera(64, 64, fov_deg=fov, model="pinhole")
    assert ideal_camera(64, 64, model="pinhole", focal=32.0).fov_deg == pytest.approx(90.0)
    zoomed = ideal_camera(64, 64, fov_deg=90.0, model="pinhole").perturbed(1.25, (0.5, -1.0))
    assert zoomed.focal == pytest.approx(40.0) and (zoomed.cx, zoomed.cy) == (32.0, 30.5)


def test_every_model_is_tested_on_a_real_calibration_or_an_ideal_lens() -> None:
    tested = {c.camera_dict["model"] for c in CameraModelTester.__subclasses__() if not c.calibration_file}
    assert tested == set(CAMERA_MODELS)


def test_unknown_model_and_missing_parameters_are_named() -> None:
    with pytest.raises(ValueError, match=r"unknown camera model 'fisheye624'; expected one of \["):
        camera_from_dict({"model": "fisheye624", "width": 4, "height": 4})
    with pytest.raises(ValueError, match=r"missing \['alpha', 'xi'\].*parameters are"):
        camera_from_dict(
            {"model": "double_sphere", "width": 4, "height": 4, "fx": 1, "fy": 1, "cx": 1, "cy": 1}
        )
    with pytest.raises(ValueError, match="fx must be a finite positive number"):
        camera_from_dict(
            {
                "model": "eucm",
                "width": 4,
                "height": 4,
                "fx": -1,
                "fy": 1,
                "cx": 1,
                "cy": 1,
                "alpha": 0.5,
                "beta": 1.0,
            }
        )
    with pytest.raises(ValueError, match="alpha must be in"):
        camera_from_dict(
            {
                "model": "double_sphere",
                "width": 4,
                "height": 4,
                "fx": 1,
                "fy": 1,
                "cx": 1,
                "cy": 1,
                "xi": 0.0,
                "alpha": 1.5,
            }
        )


def test_kitti360_corners_lie_outside_the_unified_region() -> None:
    """KITTI-360's 1400 x 1400 frame reaches past the MEI model's region (z > -d / xi): the corners have no ray."""
    cam = camera_from_dict(CALIBRATIONS["kitti360_image_02"]["camera"])
    mask = cam.valid_mask()
    assert not mask[0, 0] and not mask[-1, -1] and mask[700, 700] and mask[700, 0]
    edge = math.degrees(math.acos(-1.0 / cam.xi))
    assert math.degrees(cam.theta_grid()[mask].max().item()) == pytest.approx(edge, abs=0.5)


def test_kannala_brandt_beyond_90_degrees_is_not_mirrored() -> None:
    """atan2(r, z), not OpenCV's atan(r / z): a point 100 deg off-axis lands further out than one at 80 deg."""
    cam = camera_from_dict(CALIBRATIONS["tumvi512_cam0_kb"]["camera"])
    t = torch.tensor([math.radians(80), math.radians(100)], dtype=torch.float64)
    uv, valid = cam.project(
        torch.stack([torch.sin(t), torch.zeros(2, dtype=torch.float64), torch.cos(t)], -1)
    )
    assert valid.all() and uv[1, 0] > uv[0, 0] > cam.cx


@pytest.mark.parametrize("name", ["kitti360_image_02", "ros_kodak_plumb_bob"])
def test_radtan_inverse_numba_and_torch_paths_agree(name: str) -> None:
    """The fused CPU loop and the masked torch steps (other devices) solve the same undistortion."""
    cam = camera_from_dict(CALIBRATIONS[name]["camera"])
    uv = cam.pixel_grid()[::37, ::37].reshape(-1, 2)
    mx, my = (uv[:, 0] - cam.cx) / cam.fx, (uv[:, 1] - cam.cy) / cam.fy
    fused = cam._undistort(mx, my)
    masked = cam._undistort(mx, my, fused=False)
    for a, b in zip(fused, masked, strict=True):
        torch.testing.assert_close(a, b, rtol=0, atol=1e-13, equal_nan=True)
    assert torch.isfinite(fused[0]).float().mean() > 0.8
