"""The camera models against the implementations people trust, on published calibrations.

Committed golden values (``tests/geometry/golden/*.json``, written by ``scripts/golden_cameras.py``; each file names
its source, version and command): basalt's camera headers compiled (DS, EUCM, KB4 beyond 90 deg, unified),
``cv2.fisheye``, ``cv2.omnidir``, ``cv2.projectPoints``, the KITTI-360 devkit, WoodScape's ``projection.py`` and
OCamCalib's ``world2cam`` / ``cam2world``. Bars: projection <= 1e-6 px, back-projection <= 1e-9 rad, over the
model's whole valid field of view. Where OpenCV (opencv-contrib-python-headless, the ``test-ref`` extra) is
installed the OpenCV models are also compared live, on fresh points.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry.cameras import camera_from_dict
from tests.helpers.camera_tester import CALIBRATIONS, angle_between, sphere_directions

GOLDEN = Path(__file__).parent / "golden"
FILES = ("basalt", "opencv_fisheye", "opencv_omnidir", "opencv_pinhole", "kitti360", "woodscape", "ocamcalib")
CASES = [
    pytest.param(json.loads((GOLDEN / f"{name}.json").read_text()), case, id=f"{name}:{case['name']}")
    for name in FILES
    for case in json.loads((GOLDEN / f"{name}.json").read_text())["cases"]
]
MAX_PX = 1e-6
MAX_RAD = 1e-9


def test_every_golden_file_names_its_source_version_and_command() -> None:
    for name in FILES:
        header = json.loads((GOLDEN / f"{name}.json").read_text())
        assert (
            header["source"]
            and header["version"]
            and header["command"].startswith("python scripts/golden_cameras.py")
        )
    assert {case.values[1]["camera"]["model"] for case in CASES} >= {
        "kannala_brandt",
        "unified",
        "double_sphere",
        "eucm",
        "ocam",
        "radial_poly",
        "pinhole_radtan",
        "pinhole",
    }


@pytest.mark.parametrize(("golden", "case"), CASES)
def test_projection_matches_the_reference(golden: dict, case: dict) -> None:
    cam = camera_from_dict(case["camera"])
    points = np.array(case["project"]["points"])
    expected_uv = np.array(case["project"]["uv"])
    expected_valid = np.array(case["project"]["valid"])
    uv, valid = cam.project(points)
    # The reference's valid region (basalt reports it; the others were sampled inside it) is ours too.
    np.testing.assert_array_equal(valid, expected_valid, err_msg=golden["source"])
    err = np.abs(uv[valid] - expected_uv[valid]).max()
    assert err <= MAX_PX, f"{golden['source']}: {err:.3g} px"
    # Points spread over the field of view up to its edge (the pinhole is sampled to 55 deg).
    theta = np.degrees(np.arctan2(np.hypot(points[:, 0], points[:, 1]), points[:, 2]))
    assert theta[expected_valid].max() >= 55.0


@pytest.mark.parametrize(
    ("golden", "case"), [c for c in CASES if "unproject" in c.values[1]], ids=lambda v: None
)
def test_back_projection_matches_the_reference(golden: dict, case: dict) -> None:
    cam = camera_from_dict(case["camera"])
    uv = np.array(case["unproject"]["uv"])
    rays = cam.unproject(uv)
    assert np.isfinite(rays).all()
    err = angle_between(rays, np.array(case["unproject"]["rays"])).max().item()
    assert err <= MAX_RAD, f"{golden['source']}: {err:.3g} rad"


def test_ocam_cam2world_matches_ocamcalib_and_unproject_inverts_world2cam() -> None:
    """``cam2world_rays`` is OCamCalib's cam2world; ``unproject`` inverts world2cam (the toolbox's fit of the
    inverse), so the two differ by that fit's error, here below 5e-5 rad (0.02 px)."""
    case = json.loads((GOLDEN / "ocamcalib.json").read_text())["cases"][0]
    cam = camera_from_dict(case["camera"])
    uv = torch.tensor(case["cam2world"]["uv"], dtype=torch.float64)
    expected = torch.tensor(case["cam2world"]["rays"], dtype=torch.float64)
    assert angle_between(cam.cam2world_rays(uv), expected).max() <= MAX_RAD
    assert angle_between(cam.unproject(uv), expected).max() <= 5e-5


def test_ocam_negative_on_the_axis_has_rays_about_the_centre() -> None:
    """``OCAM_NEGATIVE_AXIS`` (tests/helpers/calibration_fixtures.py): world2cam -0.64 px on the axis, where its terms
    cancel from 3e11 px (float64 has the radius there to ~1e-4 px). An inverse held to 1e-7 px had no ray for any
    pixel within 68 px of the centre (incidences to 24 deg), where OCamCalib's cam2world has them (the golden values,
    by the toolbox's formulas, on circles 0.1-60 px about the centre). Now every one has its ray, and it is as close
    to cam2world's as the file's two fits of the lens (ss and invpol) agree anywhere: within 0.33 deg."""
    case = next(
        c
        for c in json.loads((GOLDEN / "ocamcalib.json").read_text())["cases"]
        if c["name"] == "ocam_negative_axis"
    )
    cam = camera_from_dict(case["camera"])
    uv = torch.tensor(case["cam2world"]["uv"], dtype=torch.float64)
    expected = torch.tensor(case["cam2world"]["rays"], dtype=torch.float64)
    assert angle_between(cam.cam2world_rays(uv), expected).max() <= MAX_RAD
    rays = cam.unproject(uv)
    assert torch.isfinite(rays).all()
    near = torch.arange(len(uv)) < 1 + 14 * 8  # the centre, then the circles
    assert (uv[near] - torch.tensor([cam.cx, cam.cy], dtype=torch.float64)).norm(dim=-1).max() <= 60.0 + 1e-9
    error = angle_between(rays, expected)
    assert error[near].max() <= math.radians(0.33) and error.max() <= math.radians(0.33)
    # The centre is the axis, and the incidence grows from it as cam2world's does, to 24 deg at 68 px.
    theta = torch.acos(rays[near][:, 2].clamp(-1, 1))
    theta_ref = torch.acos(expected[near][:, 2].clamp(-1, 1))
    assert theta[0] == 0 and theta_ref[0] == 0
    torch.testing.assert_close(theta, theta_ref, rtol=0.05, atol=math.radians(0.33))
    # The radii of the report (1-30 px, 0.6-11 deg) have their incidence, where world2cam puts it.
    r = torch.tensor([1.0, 5.0, 13.0, 30.0], dtype=torch.float64)
    assert torch.isfinite(cam._inverse(r)).all()


# ---------------------------------------------------------------------------------------------- live OpenCV
def _cv2():
    return pytest.importorskip("cv2", reason="opencv-contrib-python-headless (extra test-ref) not installed")


def test_live_cv2_fisheye_project_points() -> None:
    cv2 = _cv2()
    cam_d = {**CALIBRATIONS["tumvi512_cam0_kb"]["camera"], "skew": 0.003}
    cam = camera_from_dict(cam_d)
    dirs = sphere_directions(3000, seed=7)
    dirs = dirs[dirs[:, 2] > 0.02]  # cv2.fisheye: theta = atan(r / z), valid below 90 deg only
    K = np.array([[cam.fx, cam.fx * cam.skew, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1.0]])
    D = np.array(cam.k)
    expected, _ = cv2.fisheye.projectPoints(
        dirs.numpy()[:, None], np.zeros(3), np.zeros(3), K, D, alpha=cam.skew
    )
    uv, valid = cam.project(dirs.numpy())
    assert valid.all()
    assert np.abs(uv - expected[:, 0]).max() <= MAX_PX


def test_live_cv2_omnidir_project_points() -> None:
    cv2 = _cv2()
    if not hasattr(cv2, "omnidir"):
        pytest.skip("cv2 without the contrib modules (cv2.omnidir)")
    for name in ("kitti360_image_02", "kitti360_image_03"):
        cam = camera_from_dict(CALIBRATIONS[name]["camera"])
        dirs = sphere_directions(3000, seed=8)
        _, valid = cam.project(dirs)
        pts = dirs[valid].numpy()
        K = np.array([[cam.fx, 0.0, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1.0]])
        D = np.array([[cam.k1, cam.k2, cam.p1, cam.p2]])
        expected, _ = cv2.omnidir.projectPoints(
            pts[:, None], np.zeros((1, 3)), np.zeros((1, 3)), K, cam.xi, D
        )
        uv, _ = cam.project(pts)
        theta = np.degrees(np.arccos(pts[:, 2]))
        assert theta.max() > 110  # past 90 deg: the KITTI-360 lens reaches ~117 deg
        assert np.abs(uv - expected[:, 0]).max() <= MAX_PX


def test_live_cv2_pinhole_project_and_undistort() -> None:
    cv2 = _cv2()
    cam = camera_from_dict(CALIBRATIONS["ros_kodak_plumb_bob"]["camera"])
    dirs = sphere_directions(3000, seed=9)
    dirs = dirs[dirs[:, 2] > math.cos(math.radians(55))]
    K = np.array([[cam.fx, 0.0, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1.0]])
    D = np.array([cam.k1, cam.k2, cam.p1, cam.p2, cam.k3])
    expected, _ = cv2.projectPoints(dirs.numpy()[:, None], np.zeros(3), np.zeros(3), K, D)
    uv, valid = cam.project(dirs.numpy())
    assert valid.all() and np.abs(uv - expected[:, 0]).max() <= MAX_PX
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    und = cv2.undistortPoints(uv[:, None], K, D, None, None, None, crit)[:, 0]
    rays = np.concatenate([und, np.ones((len(und), 1))], 1)
    assert angle_between(cam.unproject(uv), rays).max() <= MAX_RAD


def test_live_cv2_ideal_pinhole_project_and_undistort() -> None:
    """The ideal pinhole is cv2.projectPoints with zero distortion and fx = fy = (W / 2) / tan(fov_deg / 2), over
    the whole frame (its corners beyond fov_deg / 2) and past it; cv2.undistortPoints gives its rays."""
    cv2 = _cv2()
    cam = camera_from_dict(
        {"model": "pinhole", "width": 800, "height": 600, "fov_deg": 120.0, "cx": 401.2, "cy": 297.9}
    )
    f = 400.0 / math.tan(math.radians(60.0))
    K = np.array([[f, 0.0, cam.cx], [0, f, cam.cy], [0, 0, 1.0]])
    dirs = sphere_directions(3000, seed=11)
    dirs = dirs[dirs[:, 2] > math.cos(math.radians(80))].numpy()
    expected, _ = cv2.projectPoints(dirs[:, None], np.zeros(3), np.zeros(3), K, np.zeros(5))
    uv, valid = cam.project(dirs)
    assert valid.all() and np.abs(uv - expected[:, 0]).max() <= MAX_PX
    inside = cam.in_image(uv)
    theta = np.degrees(np.arccos(dirs[inside][:, 2]))
    assert theta.max() > 61.0  # the frame's corners see past fov_deg / 2 (65 deg)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    und = cv2.undistortPoints(uv[:, None], K, np.zeros(5), None, None, None, crit)[:, 0]
    rays = np.concatenate([und, np.ones((len(und), 1))], 1)
    assert angle_between(cam.unproject(uv), rays).max() <= MAX_RAD


#: A rational calibration (cv::calibrateCamera with CALIB_RATIONAL_MODEL) of realistic size: OpenCV's order.
RATIONAL = {"model": "pinhole_radtan", "width": 1280, "height": 960, "fx": 700.0, "fy": 702.0, "cx": 639.2,
            "cy": 481.7, "k1": -0.3, "k2": 0.1, "p1": 1e-3, "p2": -5e-4, "k3": 0.0, "k4": 0.05, "k5": 0.01,
            "k6": 0.0}  # fmt: skip


def test_live_cv2_rational_project_and_undistort() -> None:
    """OpenCV's 8-coefficient model: cv2.projectPoints to 1e-6 px over the image, cv2.undistortPoints to 1e-9 rad."""
    cv2 = _cv2()
    cam = camera_from_dict(RATIONAL)
    dirs = sphere_directions(6000, seed=10)
    uv, valid = cam.project(dirs.numpy())
    valid &= cam.in_image(uv)
    dirs = dirs[valid].numpy()
    K = np.array([[cam.fx, 0.0, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1.0]])
    D = np.array([cam.k1, cam.k2, cam.p1, cam.p2, cam.k3, cam.k4, cam.k5, cam.k6])
    expected, _ = cv2.projectPoints(dirs[:, None], np.zeros(3), np.zeros(3), K, D)
    uv, _ = cam.project(dirs)
    theta = np.degrees(np.arccos(dirs[:, 2]))
    assert theta.max() > 55 and np.abs(uv - expected[:, 0]).max() <= MAX_PX
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    und = cv2.undistortPoints(uv[:, None], K, D, None, None, None, crit)[:, 0]
    rays = np.concatenate([und, np.ones((len(und), 1))], 1)
    assert angle_between(cam.unproject(uv), rays).max() <= MAX_RAD
