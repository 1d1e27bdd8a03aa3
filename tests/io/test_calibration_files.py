"""Calibration files as the tools write them -> the camera contract's flat dicts (airfisheye_bench.io.calibration_files).

The fixtures are real published calibrations (tests/helpers/calibration_fixtures.py names each source) written in their
tools' formats; expected values are those of the source, converted by the documented pixel conventions.
"""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np
import pytest

from airfisheye_bench.errors import MissingFileError
from airfisheye_bench.io.calibration_files import FORMATS, load_camera, read_calibration, save_camera
from airfisheye_bench.io.calibration_files.colmap import PARAMETERS as COLMAP_PARAMETERS
from airfisheye_bench.io.calibration_files.colmap import REFUSED as COLMAP_REFUSED
from airfisheye_bench.io.errors import CalibrationFileError
from tests.helpers import calibration_fixtures as fx
from tests.helpers import colmap_models as colmap
from tests.helpers.camera_tester import angle_between


def _rigid(T: np.ndarray) -> bool:
    R = T[:3, :3]
    return (
        np.allclose(R @ R.T, np.eye(3), atol=1e-12)
        and math.isclose(np.linalg.det(R), 1.0)
        and list(T[3]) == [0, 0, 0, 1]
    )


# ------------------------------------------------------------------------------------------------------------ basalt
@pytest.mark.parametrize(
    ("camera_type", "values", "model"),
    [("ds", fx.TUMVI_DS, "double_sphere"), ("eucm", fx.TUMVI_EUCM, "eucm")],
)
def test_basalt_tumvi(tmp_path: Path, camera_type: str, values: list[dict], model: str) -> None:
    path = fx.write_basalt(tmp_path / f"tumvi_512_{camera_type}_calib.json", values, camera_type)
    with pytest.raises(CalibrationFileError, match=r"holds 2 cameras \(0, 1\).*camera="):
        read_calibration(path)
    for index in (0, 1):
        record = read_calibration(path, camera=index)
        assert (record.format, record.name) == ("basalt", str(index))
        assert record.camera == {"model": model, "width": 512, "height": 512, **values[index]}
        assert _rigid(record.extrinsics["T_imu_cam"])
        np.testing.assert_allclose(
            record.extrinsics["T_cam_imu"] @ record.extrinsics["T_imu_cam"], np.eye(4), atol=1e-12
        )
    assert read_calibration(path, camera="1").camera["fx"] == values[1]["fx"]


def test_basalt_ucm_is_the_unified_model(tmp_path: Path) -> None:
    # basalt's UCM (unified_camera.hpp): u = fx x / (alpha d + (1 - alpha) z) + cx. Mei: gamma x / (z + xi d) + u0.
    p = {"fx": 150.0, "fy": 151.0, "cx": 255.0, "cy": 256.0, "alpha": 0.6}
    path = tmp_path / "ucm.json"
    path.write_text(
        json.dumps(
            {"value0": {"intrinsics": [{"camera_type": "ucm", "intrinsics": p}], "resolution": [[512, 512]]}}
        )
    )
    camera = read_calibration(path).camera
    x, y, z = 0.3, -0.2, 0.5
    d = math.sqrt(x * x + y * y + z * z)
    basalt_u = p["fx"] * x / (p["alpha"] * d + (1 - p["alpha"]) * z) + p["cx"]
    basalt_v = p["fy"] * y / (p["alpha"] * d + (1 - p["alpha"]) * z) + p["cy"]
    mei_u = camera["fx"] * x / (z + camera["xi"] * d) + camera["cx"]
    mei_v = camera["fy"] * y / (z + camera["xi"] * d) + camera["cy"]
    assert camera["model"] == "unified"
    assert mei_u == pytest.approx(basalt_u, abs=1e-12) and mei_v == pytest.approx(basalt_v, abs=1e-12)


def test_basalt_unsupported_type(tmp_path: Path) -> None:
    path = tmp_path / "calib.json"
    intrinsics = [
        {"camera_type": "fov", "intrinsics": {"fx": 1.0, "fy": 1.0, "cx": 0.0, "cy": 0.0, "w": 0.9}}
    ]
    path.write_text(json.dumps({"value0": {"intrinsics": intrinsics, "resolution": [[64, 64]]}}))
    with pytest.raises(CalibrationFileError) as err:
        read_calibration(path)
    assert str(path) in str(err.value) and "value0.intrinsics[0].camera_type" in str(err.value)
    assert "'fov' is not supported; supported: ds, eucm, kb4, ucm, pinhole" in str(err.value)


# ------------------------------------------------------------------------------------------------------------ Kalibr
def test_kalibr_ds_camchain(tmp_path: Path) -> None:
    path = fx.write_kalibr_camchain(tmp_path / "camchain.yaml", "ds")
    with pytest.raises(CalibrationFileError, match=r"holds 2 cameras \(cam0, cam1\)"):
        read_calibration(path)
    for camera in ("cam1", 1, "1"):
        record = read_calibration(path, camera=camera)
        assert (record.format, record.name) == ("kalibr", "cam1")
        assert record.camera == {"model": "double_sphere", "width": 512, "height": 512, **fx.TUMVI_DS[1]}
    assert read_calibration(path, camera="cam1").extrinsics["T_cn_cnm1"][0, 3] == -0.101
    with pytest.raises(CalibrationFileError, match=r"camera='cam7' is not in the file; it holds cam0, cam1"):
        read_calibration(path, camera="cam7")


def test_kalibr_pinhole_equi_is_kannala_brandt(tmp_path: Path) -> None:
    path = fx.write_kalibr_camchain(tmp_path / "camchain-imucam.txt", "equi")  # recognised from the contents
    camera = read_calibration(path, camera="cam0").camera
    fu, fv, pu, pv = fx.TUMVI_EQUI[0]["intrinsics"]
    k1, k2, k3, k4 = fx.TUMVI_EQUI[0]["distortion_coeffs"]
    assert camera == {
        "model": "kannala_brandt", "width": 512, "height": 512, "fx": fu, "fy": fv, "cx": pu, "cy": pv,
        "k1": k1, "k2": k2, "k3": k3, "k4": k4, "skew": 0.0,
    }  # fmt: skip


@pytest.mark.parametrize(
    ("camera_model", "distortion", "intrinsics", "key"),
    [
        ("ds", "radtan", [0.1, 0.5, 1, 1, 1, 1], "cam0.distortion_model"),
        ("omni", "equidistant", [1.0, 1, 1, 1, 1], "cam0.distortion_model"),
        ("fisheye62", "none", [1, 1, 1, 1], "cam0.camera_model"),
    ],
)
def test_kalibr_unsupported_pair(
    tmp_path: Path, camera_model: str, distortion: str, intrinsics: list, key: str
) -> None:
    path = tmp_path / "camchain.yaml"
    path.write_text(
        f"cam0:\n  camera_model: {camera_model}\n  distortion_model: {distortion}\n  distortion_coeffs: [0, 0, 0, 0]\n"
        f"  intrinsics: {intrinsics}\n  resolution: [64, 64]\n"
    )
    with pytest.raises(CalibrationFileError) as err:
        read_calibration(path)
    message = str(err.value)
    assert f"key '{key}'" in message and f"{camera_model}-{distortion} is not supported" in message
    assert "pinhole-equidistant" in message and "ds-none" in message and "eucm-none" in message


def test_kalibr_missing_and_wrong_keys(tmp_path: Path) -> None:
    path = tmp_path / "camchain.yaml"
    path.write_text(
        "cam0:\n  camera_model: eucm\n  distortion_model: none\n  intrinsics: [0.6, 1.0, 190, 190, 255, 256]\n"
    )
    with pytest.raises(CalibrationFileError, match=r"key 'cam0.resolution': is missing"):
        read_calibration(path)
    path.write_text(
        "cam0:\n  camera_model: eucm\n  distortion_model: none\n  intrinsics: [0.6, 1.0, 190]\n  resolution: [64, 64]\n"
    )
    with pytest.raises(CalibrationFileError, match=r"key 'cam0.intrinsics': expected 6 numbers, got 3"):
        read_calibration(path)


def _camchain_with(tmp_path: Path, transforms: dict[str, np.ndarray]) -> Path:
    """TUM-VI's cam0 (pinhole-equi) as a one-camera chain with the given 4x4 blocks."""
    text = fx.write_kalibr_camchain(tmp_path / "camchain.yaml", "equi", cameras=1).read_text()
    for key, T in transforms.items():
        text += f"  {key}:\n" + "".join(f"  - {row}\n" for row in T.tolist())
    path = tmp_path / "camchain-imucam.yaml"
    path.write_text(text)
    return path


# A rigid transform: a quarter turn about x, then 30 deg about z, and an offset of a few centimetres.
_R = np.array([[math.cos(0.5236), -math.sin(0.5236), 0], [math.sin(0.5236), math.cos(0.5236), 0], [0, 0, 1]])
T_IMU_CAM = np.eye(4)
T_IMU_CAM[:3, :3] = _R @ np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
T_IMU_CAM[:3, 3] = [0.045, -0.071, -0.046]


@pytest.mark.parametrize("stored", ["T_imu_cam", "T_cam_imu"])
def test_kalibr_extrinsics_either_direction(tmp_path: Path, stored: str, caplog) -> None:
    T = T_IMU_CAM if stored == "T_imu_cam" else np.linalg.inv(T_IMU_CAM)
    path = _camchain_with(tmp_path, {stored: T})
    with caplog.at_level(logging.INFO, logger="airfisheye_bench.io.calibration_files"):
        extrinsics = read_calibration(path).extrinsics
    # Both directions, whichever the file stores: the stored one as written, the other its inverse.
    assert set(extrinsics) == {"T_imu_cam", "T_cam_imu"} and np.array_equal(extrinsics[stored], T)
    np.testing.assert_allclose(extrinsics["T_imu_cam"], T_IMU_CAM, atol=1e-12)
    np.testing.assert_allclose(extrinsics["T_cam_imu"] @ extrinsics["T_imu_cam"], np.eye(4), atol=1e-12)
    assert f"extrinsics {stored} read from key 'cam0.{stored}'" in caplog.text


def test_kalibr_extrinsics_never_dropped_silently(tmp_path: Path, caplog) -> None:
    path = _camchain_with(tmp_path, {"T_body_cam": T_IMU_CAM})
    with caplog.at_level(logging.INFO, logger="airfisheye_bench.io.calibration_files"):
        assert read_calibration(path).extrinsics == {}
    warned = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warned) == 1 and "'cam0.T_body_cam' is not read" in warned[0].getMessage()
    # Both directions stored: they must agree.
    path = _camchain_with(tmp_path, {"T_cam_imu": np.linalg.inv(T_IMU_CAM), "T_imu_cam": T_IMU_CAM})
    np.testing.assert_allclose(read_calibration(path).extrinsics["T_imu_cam"], T_IMU_CAM, atol=1e-12)
    path = _camchain_with(tmp_path, {"T_cam_imu": T_IMU_CAM, "T_imu_cam": T_IMU_CAM})
    with pytest.raises(CalibrationFileError, match=r"key 'cam0.T_imu_cam': disagrees with the inverse"):
        read_calibration(path)
    skewed = T_IMU_CAM.copy()
    skewed[0, 0] += 0.1
    with pytest.raises(CalibrationFileError, match=r"key 'cam0.T_imu_cam': expected a rigid 4x4 transform"):
        read_calibration(_camchain_with(tmp_path, {"T_imu_cam": skewed}))


# ------------------------------------------------------------------------------------------------ KITTI-360 (MEI)
@pytest.mark.parametrize("name", ["image_02", "image_03"])
def test_kitti360_mei(tmp_path: Path, name: str) -> None:
    path = fx.write_kitti360(tmp_path / f"{name}.yaml", name)
    assert path.read_text().startswith("%YAML:1.0\n")
    record = read_calibration(path)
    p = fx.KITTI360[name]
    assert (record.format, record.name) == ("kitti360", name)
    assert record.camera == {
        "model": "unified", "width": 1400, "height": 1400, "fx": p["gamma1"], "fy": p["gamma2"], "cx": p["u0"],
        "cy": p["v0"], "xi": p["xi"], "k1": p["k1"], "k2": p["k2"], "p1": p["p1"], "p2": p["p2"],
    }  # fmt: skip


def test_kitti360_devkit_projection_agrees(tmp_path: Path) -> None:
    """Without p1, p2 the unified dict projects as the KITTI-360 devkit's cam2image (kitti360scripts/helpers/project.py)."""
    camera = read_calibration(fx.write_kitti360(tmp_path / "image_02.yaml")).camera
    p = fx.KITTI360["image_02"]
    rng = np.random.default_rng(0)
    points = rng.normal(size=(100, 3)) + np.array([0.0, 0.0, 1.0])
    # The devkit's cam2image, step by step.
    norm = np.linalg.norm(points, axis=1)
    x, y, z = (points / norm[:, None]).T
    x, y = x / (z + p["xi"]), y / (z + p["xi"])
    ro2 = x * x + y * y
    x, y = x * (1 + p["k1"] * ro2 + p["k2"] * ro2 * ro2), y * (1 + p["k1"] * ro2 + p["k2"] * ro2 * ro2)
    devkit = np.stack([p["gamma1"] * x + p["u0"], p["gamma2"] * y + p["v0"]], -1)
    # The same from the dict's parameters (Mei's unified model with p1 = p2 = 0).
    xs, ys, zs = (points / norm[:, None]).T
    mx, my = xs / (zs + camera["xi"]), ys / (zs + camera["xi"])
    r2 = mx * mx + my * my
    radial = 1 + camera["k1"] * r2 + camera["k2"] * r2 * r2
    ours = np.stack(
        [camera["fx"] * mx * radial + camera["cx"], camera["fy"] * my * radial + camera["cy"]], -1
    )
    assert np.abs(ours - devkit).max() < 1e-9


def test_camodocal_kannala_brandt_projects_as_camodocal(tmp_path: Path) -> None:
    """VINS-Fusion's KANNALA_BRANDT YAML against camodocal's EquidistantCamera::spaceToPlane, written out."""
    path = fx.write_camodocal_kannala_brandt(tmp_path / "cam0_fisheye.yaml")
    record = read_calibration(path)
    assert (record.format, record.name, record.camera["model"]) == ("kitti360", "cam0", "kannala_brandt")
    p = {line.split(":")[0].strip(): float(line.split(":")[1]) for line in path.read_text().splitlines()[7:]}
    rng = np.random.default_rng(1)
    points = rng.normal(size=(200, 3))  # the whole sphere: camodocal's acos reaches behind the camera too
    # camodocal (src/camera_models/EquidistantCamera.cc, spaceToPlane; r() in EquidistantCamera.h):
    theta = np.arccos(points[:, 2] / np.linalg.norm(points, axis=1))
    phi = np.arctan2(points[:, 1], points[:, 0])
    r = theta + p["k2"] * theta**3 + p["k3"] * theta**5 + p["k4"] * theta**7 + p["k5"] * theta**9
    camodocal = np.stack([p["mu"] * r * np.cos(phi) + p["u0"], p["mv"] * r * np.sin(phi) + p["v0"]], -1)
    uv, valid = load_camera(path).project(points)
    assert valid.all()  # TUM-VI's polynomial increases up to 180 deg
    assert np.abs(uv - camodocal).max() < 1e-9


def test_camodocal_pinhole_and_refusals(tmp_path: Path) -> None:
    path = tmp_path / "cam.yaml"
    path.write_text(
        "%YAML:1.0\n---\nmodel_type: PINHOLE\ncamera_name: camera\nimage_width: 752\nimage_height: 480\n"
        "distortion_parameters:\n   k1: -2.9e-01\n   k2: 8.1e-02\n   p1: 1.9e-05\n   p2: 1.8e-05\n"
        "projection_parameters:\n   fx: 4.616e+02\n   fy: 4.603e+02\n   cx: 3.630e+02\n   cy: 2.484e+02\n"
    )  # the layout of VINS-Fusion's config/euroc/cam0_pinhole.yaml
    assert read_calibration(path).camera == {
        "model": "pinhole_radtan", "width": 752, "height": 480, "fx": 461.6, "fy": 460.3, "cx": 363.0, "cy": 248.4,
        "k1": -0.29, "k2": 0.081, "p1": 1.9e-05, "p2": 1.8e-05, "k3": 0.0,
    }  # fmt: skip
    path.write_text("%YAML:1.0\n---\nmodel_type: SCARAMUZZA\nimage_width: 640\nimage_height: 480\n")
    with pytest.raises(CalibrationFileError) as err:
        read_calibration(path)
    assert str(err.value) == (
        f"{path}: key 'model_type': 'SCARAMUZZA' is not supported; supported: MEI, KANNALA_BRANDT, PINHOLE"
    )
    # k2..k5 under distortion_parameters: camodocal itself would read 0 for each; refused, saying where they go.
    kb = fx.write_camodocal_kannala_brandt(tmp_path / "kb.yaml").read_text()
    kb = kb.replace("projection_parameters:\n", "distortion_parameters:\n").replace(
        "   mu:", "projection_parameters:\n   mu:"
    )
    path.write_text(kb)
    with pytest.raises(CalibrationFileError) as err:
        read_calibration(path)
    message = str(err.value)
    assert "key 'distortion_parameters.k2'" in message and "move them there" in message
    assert "\n" not in message and len(message) - len(str(path)) <= 200


# ------------------------------------------------------------------------------------------------------- WoodScape
def test_woodscape_front(tmp_path: Path) -> None:
    path = tmp_path / "front.json"
    path.write_text(json.dumps(fx.WOODSCAPE_FRONT, indent=2))
    record = read_calibration(path)
    intrinsic = fx.WOODSCAPE_FRONT["intrinsic"]
    # WoodScape's Camera: principle point = 0.5 * size + offset - 0.5 (projection.py).
    assert record.camera == {
        "model": "radial_poly", "width": 1280, "height": 966, "k1": 339.749, "k2": -31.988, "k3": 48.275,
        "k4": -7.201, "cx": 0.5 * 1280 + intrinsic["cx_offset"] - 0.5, "cy": 0.5 * 966 + intrinsic["cy_offset"] - 0.5,
        "aspect_ratio": 1.0,
    }  # fmt: skip
    assert record.name == "FV"
    T = record.extrinsics["T_vehicle_cam"]
    assert _rigid(T) and T[:3, 3].tolist() == fx.WOODSCAPE_FRONT["extrinsic"]["translation"]
    # The front camera looks forward along the vehicle's x axis, tilted down, its image x axis to the vehicle's right.
    forward, right = T[:3, 2], T[:3, 0]
    assert forward[0] > 0.8 and forward[2] < 0 and right[1] < -0.9


def test_woodscape_other_model(tmp_path: Path) -> None:
    doc = json.loads(json.dumps(fx.WOODSCAPE_FRONT))
    doc["intrinsic"]["model"] = "polynomial_8"
    path = tmp_path / "front.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(
        CalibrationFileError,
        match=r"key 'intrinsic.model': 'polynomial_8' is not supported; supported: radial_poly",
    ):
        read_calibration(path)


# ------------------------------------------------------------------------------------------------------- OCamCalib
def test_ocamcalib_kodak(tmp_path: Path) -> None:
    path = tmp_path / "calib_results.txt"
    path.write_text(fx.OCAM_KODAK)
    record = read_calibration(path)
    assert record.format == "ocamcalib"
    assert record.camera == {
        "model": "ocam", "width": 1440, "height": 1440, "cx": 729.090632, "cy": 728.648728, "c": 1.001407,
        "d": -0.000818, "e": 0.000221,
        "cam2world": [-2.716972e02, 0.0, -2.741744e-06, 1.840940e-06, -8.024838e-10],
        "world2cam": [583.439624, 470.805865, 97.165132, 120.712689, 100.686168, 55.067847, 67.348203, 15.186683,
                      1.492255, 84.459767, 105.607698, 48.090642, 7.785426],
    }  # fmt: skip


def test_ocamcalib_matlab_centre_and_bad_counts(tmp_path: Path) -> None:
    old = fx.OCAM_KODAK.replace(
        '#center: "row" and "column", starting from 0 (C convention)',
        "#center: (ocam_model.xc and ocam_model.yc in MATLAB)",
    )
    path = tmp_path / "calib_results.txt"
    path.write_text(old)
    camera = read_calibration(path).camera
    assert (camera["cx"], camera["cy"]) == (729.090632 - 1, 728.648728 - 1)
    path.write_text(fx.OCAM_KODAK.replace("\n5 -2.716972e+02", "\n6 -2.716972e+02"))
    with pytest.raises(
        CalibrationFileError, match=r"key 'ss': expected the coefficient count N followed by N"
    ):
        read_calibration(path)


def test_ocamcalib_negative_on_the_axis(tmp_path: Path) -> None:
    """A file whose world2cam is -0.64 px on the axis, where its terms cancel from 3e11 px: every pixel about the
    centre has its ray (they had none within 68 px), and the rays project back onto their pixels to the polynomial's
    own float64 rounding there (~1e-4 px)."""
    path = tmp_path / "calib_results.txt"
    path.write_text(fx.OCAM_NEGATIVE_AXIS)
    record = read_calibration(path)
    assert record.format == "ocamcalib"
    assert {k: record.camera[k] for k in ("width", "height", "cx", "cy")} == {
        "width": 1024, "height": 768, "cx": 511.3, "cy": 383.6,
    }  # fmt: skip
    assert len(record.camera["world2cam"]) == 25 and record.camera["cam2world"][1] == 0.0
    camera = load_camera(path)
    assert 0 < camera.theta_head < math.radians(1.0)
    u, v = np.meshgrid(np.arange(440.0, 584.0), np.arange(312.0, 456.0))  # 72 px about the centre
    uv = np.stack([u.ravel(), v.ravel()], -1)
    rays = camera.unproject(uv)
    assert np.isfinite(rays).all()
    uv2, valid = camera.project(rays)
    assert valid.all() and np.abs(uv2 - uv).max() <= 1e-3


def test_ocamcalib_refuses_a_world2cam_far_off_on_the_axis(tmp_path: Path) -> None:
    path = tmp_path / "calib_results.txt"
    path.write_text(fx.OCAM_NEGATIVE_AXIS.replace("\n25 473.808559 ", "\n25 173.808559 "))
    with pytest.raises(
        CalibrationFileError,
        match=r"not a valid ocam camera \(world2cam's radius is -300.6 px on the optical axis .* a quarter of the "
        r"image's shorter side",
    ):
        load_camera(path)


# ------------------------------------------------------------------------------------------------------ OpenCV
OPENCV_FISHEYE_YAML = """%YAML:1.0
---
calibration_time: "Wed 25 Nov 2026 10:00:00 UTC"
nr_of_frames: 25
image_width: 1280
image_height: 960
board_width: 9
board_height: 6
square_size: 25.
flags: 0
fisheye_model: 1
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 4.1234567890123457e+02, 2.0000000000000001e-01, 6.3950000000000000e+02, 0., 4.1300000000000000e+02,
       4.7950000000000000e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 4
   cols: 1
   dt: d
   data: [ 1.2000000000000000e-02, -3.0000000000000001e-03, 5.0000000000000001e-04, -2.0000000000000001e-05 ]
avg_reprojection_error: 2.1000000000000002e-01
"""


def test_opencv_filestorage_fisheye_yaml(tmp_path: Path) -> None:
    path = tmp_path / "out_camera_data.yml"
    path.write_text(OPENCV_FISHEYE_YAML)
    record = read_calibration(path)
    assert record.format == "opencv"
    assert record.camera == {
        "model": "kannala_brandt", "width": 1280, "height": 960, "fx": 412.34567890123457, "fy": 413.0,
        "cx": 639.5, "cy": 479.5, "k1": 0.012, "k2": -0.003, "k3": 0.0005, "k4": -2e-05,
        "skew": 0.2 / 412.34567890123457,
    }  # fmt: skip


def test_opencv_plumb_bob_json_and_bad_coefficients(tmp_path: Path) -> None:
    matrix = {
        "type_id": "opencv-matrix",
        "rows": 3,
        "cols": 3,
        "dt": "d",
        "data": [500.0, 0, 319.5, 0, 501.0, 239.5, 0, 0, 1],
    }
    dist = {
        "type_id": "opencv-matrix",
        "rows": 1,
        "cols": 5,
        "dt": "d",
        "data": [-0.2, 0.05, 0.001, -0.002, 0.01],
    }
    doc = {"image_width": 640, "image_height": 480, "camera_matrix": matrix, "distortion_coefficients": dist}
    path = tmp_path / "calibration.json"
    path.write_text(json.dumps(doc, indent=4))
    assert read_calibration(path).camera == {
        "model": "pinhole_radtan", "width": 640, "height": 480, "fx": 500.0, "fy": 501.0, "cx": 319.5, "cy": 239.5,
        "k1": -0.2, "k2": 0.05, "p1": 0.001, "p2": -0.002, "k3": 0.01,
    }  # fmt: skip
    # CALIB_RATIONAL_MODEL's 8 coefficients: k4..k6 the radial factor's denominator.
    dist["rows"], dist["data"] = 1, [-0.2, 0.05, 0.001, -0.002, 0.01, 0.3, 0.02, -0.001]
    dist["cols"] = 8
    path.write_text(json.dumps(doc))
    assert read_calibration(path).camera == {
        "model": "pinhole_radtan", "width": 640, "height": 480, "fx": 500.0, "fy": 501.0, "cx": 319.5, "cy": 239.5,
        "k1": -0.2, "k2": 0.05, "p1": 0.001, "p2": -0.002, "k3": 0.01, "k4": 0.3, "k5": 0.02, "k6": -0.001,
    }  # fmt: skip
    # 12 with the thin-prism terms at 0: the same lens.
    dist["cols"], dist["data"] = 12, [*dist["data"], 0.0, 0.0, 0.0, 0.0]
    path.write_text(json.dumps(doc))
    assert read_calibration(path).camera["k4"] == 0.3
    dist["data"][8] = 1e-3
    path.write_text(json.dumps(doc))
    with pytest.raises(
        CalibrationFileError, match=r"key 'distortion_coefficients': non-zero s1: the thin-prism"
    ):
        read_calibration(path)


def test_opencv_live_filestorage(tmp_path: Path) -> None:
    """What OpenCV's own cv::FileStorage writes (YAML and JSON) reads back to the same numbers."""
    cv2 = pytest.importorskip("cv2")
    K = np.array([[412.3456789, 0.0, 639.5], [0.0, 413.0, 479.5], [0.0, 0.0, 1.0]])
    for suffix, D, fisheye in (
        (".yml", np.array([[0.012], [-0.003], [5e-4], [-2e-5]]), 1),
        (".json", np.array([[-0.2, 0.05, 1e-3, -2e-3, 0.01]]), 0),
        # cv::calibrateCamera with CALIB_RATIONAL_MODEL writes 8 coefficients.
        (".yaml", np.array([[-0.3], [0.1], [1e-3], [-5e-4], [0.0], [0.05], [0.01], [0.0]]), 0),
    ):
        path = tmp_path / f"camera{suffix}"
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
        fs.write("image_width", 1280)
        fs.write("image_height", 960)
        fs.write("fisheye_model", fisheye)
        fs.write("camera_matrix", K)
        fs.write("distortion_coefficients", D)
        fs.release()
        camera = read_calibration(path).camera
        assert camera["model"] == ("kannala_brandt" if fisheye else "pinhole_radtan")
        assert (camera["fx"], camera["fy"], camera["cx"], camera["cy"]) == (
            K[0, 0],
            K[1, 1],
            K[0, 2],
            K[1, 2],
        )
        names = ("k1", "k2", "k3", "k4") if fisheye else ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")
        assert [camera.get(n, 0.0) for n in names[: D.size]] == D.reshape(-1).tolist()


@pytest.mark.parametrize(
    ("text", "name"),
    [
        # cv::FileStorage of calibrateCamera's own argument names, the size as a cv::Size.
        ("%YAML:1.0\n---\nimageSize: [ 1280, 960 ]\ncameraMatrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n"
         "   dt: d\n   data: [ 412.5, 0., 639.5, 0., 413., 479.5, 0., 0., 1. ]\ndistCoeffs: !!opencv-matrix\n"
         "   rows: 1\n   cols: 4\n   dt: d\n   data: [ 0.012, -0.003, 5.e-04, -2.e-05 ]\n", "opencv.yml"),
        # A script's JSON: K and D as plain lists, width and height.
        (json.dumps({"width": 1280, "height": 960, "K": [[412.5, 0, 639.5], [0, 413.0, 479.5], [0, 0, 1]],
                     "D": [[0.012], [-0.003], [5e-4], [-2e-5]]}), "fisheye.json"),
        # The Python tutorial's names, K flat (row-major), image_size as [width, height].
        ("image_size: [1280, 960]\nmtx: [412.5, 0, 639.5, 0, 413.0, 479.5, 0, 0, 1]\n"
         "dist: [0.012, -0.003, 0.0005, -0.00002]\n", "calib.yaml"),
    ],
)  # fmt: skip
def test_opencv_other_key_spellings(tmp_path: Path, text: str, name: str) -> None:
    path = tmp_path / name
    path.write_text(text)
    record = read_calibration(path)
    assert record.format == "opencv"
    assert record.camera == {
        "model": "kannala_brandt", "width": 1280, "height": 960, "fx": 412.5, "fy": 413.0, "cx": 639.5,
        "cy": 479.5, "k1": 0.012, "k2": -0.003, "k3": 0.0005, "k4": -2e-05, "skew": 0.0,
    }  # fmt: skip


def test_opencv_without_an_image_size_names_the_key(tmp_path: Path) -> None:
    path = tmp_path / "calib.yaml"
    path.write_text(
        "cameraMatrix: [[500, 0, 320], [0, 500, 240], [0, 0, 1]]\ndistCoeffs: [0.1, 0, 0, 0, 0]\n"
    )
    with pytest.raises(CalibrationFileError) as err:
        read_calibration(path)
    message = str(err.value)
    assert message.startswith(f"{path}: key 'image_width': is missing: the image size is needed (image_width")
    assert "\n" not in message and len(message) - len(str(path)) <= 200


# ------------------------------------------------------------------------------------------------------------ ROS
def test_ros_parsers_layout_plumb_bob(tmp_path: Path) -> None:
    path = tmp_path / "kodak.yaml"
    path.write_text(fx.ROS_KODAK)
    record = read_calibration(path)
    assert (record.format, record.name) == ("ros", "kodak")
    assert record.camera == {
        "model": "pinhole_radtan", "width": 1440, "height": 1440, "fx": 559.7772332675477, "fy": 537.9001480261843,
        "cx": 654.6891822497959, "cy": 757.5374958985061, "k1": -0.1710342568253523, "k2": 0.01562344385534763,
        "p1": -0.006842079559350427, "p2": 0.005880933792022186, "k3": 0.0,
    }  # fmt: skip


@pytest.mark.parametrize(("k", "d"), [("K", "D"), ("k", "d")])
def test_ros_message_dump_equidistant(tmp_path: Path, k: str, d: str) -> None:
    equi = fx.TUMVI_EQUI[0]
    fu, fv, pu, pv = equi["intrinsics"]
    path = tmp_path / "camera_info.yaml"
    path.write_text(
        "header:\n  seq: 12\n  frame_id: cam0\nheight: 512\nwidth: 512\ndistortion_model: equidistant\n"
        f"{d}: {equi['distortion_coeffs']}\n{k}: {[fu, 0.0, pu, 0.0, fv, pv, 0.0, 0.0, 1.0]}\n"
        "R: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]\nbinning_x: 0\nbinning_y: 0\n---\n"
        if k == "K"
        else "height: 512\nwidth: 512\ndistortion_model: equidistant\n"
        f"{d}:\n"
        + "".join(f"- {c!r}\n" for c in equi["distortion_coeffs"])
        + f"{k}:\n"
        + "".join(f"- {v!r}\n" for v in [fu, 0.0, pu, 0.0, fv, pv, 0.0, 0.0, 1.0])
    )
    camera = read_calibration(path).camera
    assert camera["model"] == "kannala_brandt" and (camera["fx"], camera["cy"]) == (fu, pv)
    assert [camera[n] for n in ("k1", "k2", "k3", "k4")] == equi["distortion_coeffs"]


def test_ros_unsupported_distortion_model(tmp_path: Path) -> None:
    path = tmp_path / "info.yaml"
    path.write_text(fx.ROS_KODAK.replace("plumb_bob", "fov"))
    with pytest.raises(
        CalibrationFileError,
        match=r"key 'distortion_model': 'fov' is not supported; supported: equidistant, plumb_bob, rational_polynomial",
    ):
        read_calibration(path)


# ---------------------------------------------------------------------------------------------------------- COLMAP
COLMAP_TXT = """# Camera list with one line of data per camera:
#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]
# Number of cameras: 3
1 OPENCV_FISHEYE 512 512 190.97847715128717 190.9733070521226 255.43170605935475 257.3974428996504 0.0034823894022493434 0.0007150348452162257 -0.0020532361418706202 0.00020293673591811182
2 SIMPLE_RADIAL 640 480 500 320 240 -0.1
7 FOV 640 480 300 300 320 240 0.9
"""


def test_colmap_cameras_txt(tmp_path: Path) -> None:
    path = tmp_path / "cameras.txt"
    path.write_text(COLMAP_TXT)
    with pytest.raises(CalibrationFileError, match=r"holds 3 cameras \(1, 2, 7\)"):
        read_calibration(path)
    record = read_calibration(path, camera=1)
    fu, _fv, pu, pv = fx.TUMVI_EQUI[0]["intrinsics"]
    # COLMAP's pixel centres are at half-integers: the same lens has its principal point 0.5 px further.
    assert record.camera["model"] == "kannala_brandt" and record.name == "1"
    assert (record.camera["fx"], record.camera["cx"], record.camera["cy"]) == (fu, pu, pv)
    assert read_calibration(path, camera="2").camera == {
        "model": "pinhole_radtan", "width": 640, "height": 480, "fx": 500.0, "fy": 500.0, "cx": 319.5, "cy": 239.5,
        "k1": -0.1, "k2": 0.0, "p1": 0.0, "p2": 0.0, "k3": 0.0,
    }  # fmt: skip
    assert read_calibration(path, camera=7).camera["model"] == "fov"
    with pytest.raises(CalibrationFileError, match=r"camera='0' is not in the file; it holds 1, 2, 7"):
        read_calibration(path, camera="0")  # COLMAP ids are names, never indices


# COLMAP's own test parameters (src/colmap/sensor/models_test.cc, <Model>.Nominal) on the image they centre.
COLMAP_THIN_PRISM = [
    651.123,
    655.123,
    386.123,
    511.123,
    -0.471,
    0.223,
    -0.001,
    0.001,
    0.001,
    0.02,
    -0.02,
    0.001,
]
#: A rational calibration of realistic size (k1, k2, p1, p2, k3, k4, k5, k6) on a 1280 x 960 image.
COLMAP_FULL_OPENCV = [700.0, 702.0, 639.5, 481.0, -0.3, 0.1, 1e-3, -5e-4, 0.0, 0.05, 0.01, 0.002]
COLMAP_RAD_TAN_THIN_PRISM = [651.123, 655.123, 386.123, 511.123, -0.0232, 0.0924, -0.0591, 0.003, 0.0048, -0.0009,
                             0.0002, 0.0005, -0.0009, -0.0001, 0.00007, -0.00017]  # fmt: skip


def _colmap_camera(tmp_path: Path, model: str, params: list[float], size: tuple[int, int] = (772, 1022)):
    path = tmp_path / "cameras.txt"
    path.write_text(f"# Camera list\n3 {model} {size[0]} {size[1]} {' '.join(repr(v) for v in params)}\n")
    return load_camera(path)


@pytest.mark.parametrize(
    ("model", "params", "ours"),
    [
        ("SIMPLE_FISHEYE", [280.0, 320.0, 240.0], "kannala_brandt"),
        ("FISHEYE", [280.0, 282.0, 320.0, 240.0], "kannala_brandt"),
        # Kannala-Brandt k1..k4 of TUM-VI's cam0, the thin-prism and tangential terms 0 (what a file may hold).
        ("THIN_PRISM_FISHEYE", [190.98, 190.97, 255.43, 257.40, 0.00348, 0.000715, 0, 0, -0.00205, 0.000203, 0, 0],
         "kannala_brandt"),
        ("RAD_TAN_THIN_PRISM_FISHEYE", [190.98, 190.97, 255.43, 257.40, 0.00348, 0.000715, -0.00205, 0.000203,
                                        0, 0, 0, 0, 0, 0, 0, 0], "kannala_brandt"),
        ("THIN_PRISM_FISHEYE", COLMAP_THIN_PRISM, "thin_prism_fisheye"),
        ("RAD_TAN_THIN_PRISM_FISHEYE", COLMAP_RAD_TAN_THIN_PRISM, "rad_tan_thin_prism_fisheye"),
        # k5 alone: a radial term Kannala-Brandt has not.
        ("RAD_TAN_THIN_PRISM_FISHEYE", [*COLMAP_RAD_TAN_THIN_PRISM[:9], 0.0001, 0, 0, 0, 0, 0, 0],
         "rad_tan_thin_prism_fisheye"),
        ("SIMPLE_DIVISION", [651.123, 386.123, 511.123, -0.1], "division"),
        ("SIMPLE_DIVISION", [651.123, 386.123, 511.123, 0.0], "division"),
        ("DIVISION", [651.123, 655.123, 386.123, 511.123, -0.1], "division"),
        ("DIVISION", [651.123, 655.123, 386.123, 511.123, 0.1], "division"),
        ("FOV", [651.123, 655.123, 386.123, 511.123, 0.9], "fov"),
        ("FOV", [651.123, 655.123, 386.123, 511.123, -0.9], "fov"),  # the same lens: the map is even in omega
        ("EUCM", [191.148, 191.132, 255.459, 257.382, 0.6291, 1.0418], "eucm"),  # TUM-VI cam0's, COLMAP's pixels
        ("FULL_OPENCV", COLMAP_FULL_OPENCV, "pinhole_radtan"),
    ],
)  # fmt: skip
def test_colmap_models_project_as_colmap(tmp_path: Path, model: str, params: list[float], ours: str) -> None:
    """Every model of models.h against its ImgFromCam written out (tests/helpers/colmap_models.py): the same
    pixels to 1e-9 px wherever COLMAP projects a point in front of the camera, and the same points refused."""
    camera = _colmap_camera(tmp_path, model, params)
    assert camera.model == ours
    rng = np.random.default_rng(3)
    points = rng.normal(size=(2000, 3))
    points[:, 2] = np.abs(points[:, 2]) + 0.05  # in front of the camera, up to 87 deg off the axis
    uv, valid = camera.project(points)
    xy, ok = colmap.img_from_cam(model, params, points)
    if model == "FULL_OPENCV":
        # COLMAP projects every point in front; the model only where the distortion is one-to-one (77 deg here).
        theta = np.arctan2(np.hypot(points[:, 0], points[:, 1]), points[:, 2])
        assert math.radians(75) < camera.theta_limit < math.radians(80)
        ok &= theta <= camera.theta_limit
    # DIVISION with k > 0 has no real root past t = 1 / sqrt(k) (58 deg here): neither projects those.
    assert np.array_equal(valid, ok) and ok.mean() > (
        0.5 if (params[-1] > 0 and "DIVISION" in model) or model == "FULL_OPENCV" else 0.999
    )
    # Our pixel centres are at integers, COLMAP's at half-integers.
    assert np.abs(uv[ok] + 0.5 - xy[ok]).max() < 1e-9


@pytest.mark.parametrize(
    ("model", "params"),
    [
        ("THIN_PRISM_FISHEYE", COLMAP_THIN_PRISM),
        ("RAD_TAN_THIN_PRISM_FISHEYE", COLMAP_RAD_TAN_THIN_PRISM),
        ("SIMPLE_DIVISION", [651.123, 386.123, 511.123, 0.1]),
        ("DIVISION", [651.123, 655.123, 386.123, 511.123, -0.1]),
        ("FULL_OPENCV", COLMAP_FULL_OPENCV),
    ],
)
def test_colmap_models_unproject_as_colmap(tmp_path: Path, model: str, params: list[float]) -> None:
    """Pixels over the whole image against COLMAP's CamFromImg written out (for the thin-prism models its
    IterativeUndistortion): the same rays, and each projects back onto its pixel through COLMAP's ImgFromCam."""
    camera = _colmap_camera(tmp_path, model, params)
    u, v = np.meshgrid(np.linspace(-0.5, 771.5, 13), np.linspace(-0.5, 1021.5, 17))
    uv = np.stack([u.ravel(), v.ravel()], -1)
    rays = camera.unproject(uv)
    assert np.isfinite(rays).all()
    plane, ok = colmap.cam_from_img(model, params, uv + 0.5)
    assert ok.all()
    theirs = np.concatenate([plane, np.ones((len(plane), 1))], -1)
    theirs /= np.linalg.norm(theirs, axis=-1, keepdims=True)
    # COLMAP's Newton stops once a step is below 1e-5: its rays are exact to what that leaves, ~1e-10 rad.
    assert angle_between(rays, theirs).max() < 1e-9
    xy, ok = colmap.img_from_cam(model, params, rays)
    assert ok.all() and np.abs(xy - 0.5 - uv).max() < 1e-9


def test_colmap_division_past_90_degrees_is_the_ray_of_img_from_cam(tmp_path: Path) -> None:
    """Barrel DIVISION reaches past 90 deg (1 + k t^2 < 0) where COLMAP's CamFromImg, a point of the plane w = 1,
    is the opposite ray: the ray here is the one ImgFromCam (no cheirality test) maps onto the pixel."""
    camera = _colmap_camera(tmp_path, "SIMPLE_DIVISION", [200.0, 320.0, 240.0, -0.5], size=(640, 480))
    uv = np.array(
        [[-0.5, -0.5], [639.5, 239.5], [319.5, 479.5]]
    )  # t = 2, 1.6, 1.2: beyond t = sqrt(2), and not
    rays = camera.unproject(uv)
    assert (rays[:2, 2] < 0).all() and rays[2, 2] > 0
    xy, ok = colmap.img_from_cam("SIMPLE_DIVISION", [200.0, 320.0, 240.0, -0.5], rays)
    assert ok.all() and np.abs(xy - 0.5 - uv).max() < 1e-9
    plane, _ = colmap.cam_from_img("SIMPLE_DIVISION", [200.0, 320.0, 240.0, -0.5], uv + 0.5)
    np.testing.assert_allclose(
        rays[:2, :2] / rays[:2, 2:], plane[:2], rtol=1e-12
    )  # the same line, the other way
    assert camera.coverage_deg > 180.0


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("EQUIRECTANGULAR 800 400 800 400",
         "key '3.model': EQUIRECTANGULAR is a 360 x 180 deg panorama (COLMAP's spherical model, no focal length), "
         "not a lens: no fisheye image is served through it"),
        ("FISHEYE624 64 64 50 50 32 32",
         "key '3.model': FISHEYE624 is not a COLMAP camera model; supported: every model of COLMAP's models.h but "
         "EQUIRECTANGULAR"),
        ("DIVISION 64 64 50 50 32 32", "key '3.params': expected 5 numbers, got 4"),
    ],
)  # fmt: skip
def test_colmap_refusals_are_one_short_line(tmp_path: Path, line: str, message: str) -> None:
    path = tmp_path / "cameras.txt"
    path.write_text(f"3 {line}\n")
    with pytest.raises(CalibrationFileError) as err:
        load_camera(path)
    text = str(err.value)
    assert message in text and "\n" not in text and len(text) - len(str(path)) <= 200


def test_colmap_every_model_of_models_h_is_read() -> None:
    """The reader's table against the models models.h defines (CAMERA_MODEL_CASES; EQUIRECTANGULAR refused)."""
    models_h = {
        "SIMPLE_PINHOLE", "PINHOLE", "SIMPLE_RADIAL", "SIMPLE_RADIAL_FISHEYE", "RADIAL", "RADIAL_FISHEYE", "OPENCV",
        "OPENCV_FISHEYE", "FULL_OPENCV", "FOV", "THIN_PRISM_FISHEYE", "RAD_TAN_THIN_PRISM_FISHEYE",
        "SIMPLE_DIVISION", "DIVISION", "SIMPLE_FISHEYE", "FISHEYE", "EUCM", "EQUIRECTANGULAR",
    }  # fmt: skip
    assert set(COLMAP_PARAMETERS) | set(COLMAP_REFUSED) == models_h
    assert set(COLMAP_REFUSED) == {"EQUIRECTANGULAR"}


def test_colmap_full_opencv_rational(tmp_path: Path) -> None:
    """FULL_OPENCV with non-zero k4..k6 (OpenCV's rational model) loads as pinhole_radtan with them; zero, they are
    left out of the dict (the plumb_bob camera of before)."""
    camera = _colmap_camera(tmp_path, "FULL_OPENCV", COLMAP_FULL_OPENCV)
    assert camera.model == "pinhole_radtan"
    assert (camera.k4, camera.k5, camera.k6) == (0.05, 0.01, 0.002) and camera.cx == 639.5 - 0.5
    plumb_bob = _colmap_camera(tmp_path, "FULL_OPENCV", [*COLMAP_FULL_OPENCV[:9], 0, 0, 0]).to_dict()
    assert not {"k4", "k5", "k6"} & set(plumb_bob) and plumb_bob["k1"] == -0.3


def test_colmap_fov_of_omega_zero_is_the_pinhole(tmp_path: Path) -> None:
    path = tmp_path / "cameras.txt"
    path.write_text("1 FOV 640 480 500 501 320 240 0\n")
    assert read_calibration(path).camera == {
        "model": "pinhole_radtan", "width": 640, "height": 480, "fx": 500.0, "fy": 501.0, "cx": 319.5, "cy": 239.5,
        "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0, "k3": 0.0,
    }  # fmt: skip


# -------------------------------------------------------------------------------------- the project's own + errors
def test_project_calib_yaml_camera_section(tmp_path: Path) -> None:
    path = tmp_path / "calib.yaml"
    camera = {
        "model": "equidistant",
        "width": 64,
        "height": 64,
        "fov_deg": 190.0,
        "cx": 31.5,
        "cy": 31.5,
        "focal": 19.3,
    }
    path.write_text(
        json.dumps(
            {"camera": camera, "cubemap": {"face_size": 32}, "T_body_cam": np.eye(4).tolist(), "lidar": {}}
        )
    )
    record = read_calibration(path)
    assert record.format == "airfisheye" and record.camera == camera


def test_unknown_format_is_one_short_line(tmp_path: Path) -> None:
    path = tmp_path / "what.yaml"
    path.write_text("focal_length: 3.2\nsensor: imx477\n")
    with pytest.raises(CalibrationFileError) as err:
        read_calibration(path)
    message = str(err.value)
    assert message.startswith(f"{path}: not a calibration file of a known format")
    assert all(fmt.name in message for fmt in FORMATS) and "docs/design.md" in message
    assert "\n" not in message and len(message) - len(str(path)) <= 200


@pytest.mark.parametrize(
    ("name", "text", "where"),
    [
        # A Kalibr camchain whose list lost its closing bracket: the parser stops where the file ends.
        (
            "camchain.yaml",
            "cam0:\n  camera_model: ds\n  intrinsics: [0.5, 0.6, 190.9, 191.0\n",
            "YAML at line 4",
        ),
        # An OpenCV FileStorage file, mis-indented: its %YAML:1.0 line counts, as in an editor.
        ("out.yml", "%YAML:1.0\n---\nK: !!opencv-matrix\n  rows: 3\n cols: 3\n", "YAML at line 5, column 2"),
        ("calib.json", '{"value0": {"intrinsics": [1, 2}}', "JSON at line 1, column 32"),
    ],
)
def test_a_syntax_error_is_reported_with_its_line(tmp_path: Path, name: str, text: str, where: str) -> None:
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(CalibrationFileError) as err:
        load_camera(path)
    message = str(err.value)
    assert message.startswith(f"{path}: invalid {where}")
    assert "known format" not in message and "\n" not in message


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(MissingFileError, match="no such calibration file"):
        read_calibration(tmp_path / "nope.yaml")


def test_every_format_names_its_source() -> None:
    assert len({fmt.name for fmt in FORMATS}) == len(FORMATS) == 9
    assert all(fmt.source and fmt.summary for fmt in FORMATS)


# ------------------------------------------------------------------------------ cameras of the contract, round trip
def _every_fixture(tmp_path: Path) -> list[tuple[Path, str | None]]:
    woodscape = tmp_path / "front.json"
    woodscape.write_text(json.dumps(fx.WOODSCAPE_FRONT))
    ocam = tmp_path / "calib_results.txt"
    ocam.write_text(fx.OCAM_KODAK)
    ros = tmp_path / "kodak.yaml"
    ros.write_text(fx.ROS_KODAK)
    opencv_yaml = tmp_path / "out_camera_data.yml"
    opencv_yaml.write_text(OPENCV_FISHEYE_YAML)
    colmap = tmp_path / "cameras.txt"
    colmap.write_text(COLMAP_TXT)
    return [
        (fx.write_basalt(tmp_path / "ds.json", fx.TUMVI_DS, "ds"), "0"),
        (fx.write_basalt(tmp_path / "eucm.json", fx.TUMVI_EUCM, "eucm"), "1"),
        (fx.write_kalibr_camchain(tmp_path / "camchain_ds.yaml", "ds"), "cam0"),
        (fx.write_kalibr_camchain(tmp_path / "camchain_equi.yaml", "equi"), "cam1"),
        (fx.write_kitti360(tmp_path / "image_02.yaml", "image_02"), None),
        (fx.write_kitti360(tmp_path / "image_03.yaml", "image_03"), None),
        (woodscape, None),
        (ocam, None),
        (ros, None),
        (opencv_yaml, None),
        (colmap, "1"),
    ]


@pytest.mark.parametrize("suffix", [".yaml", ".json"])
def test_every_fixture_loads_and_round_trips_through_save_camera(tmp_path: Path, suffix: str) -> None:
    for path, name in _every_fixture(tmp_path):
        camera = load_camera(path, name)
        assert camera.to_dict() == read_calibration(path, name).camera, path.name
        saved = save_camera(camera, tmp_path / f"{path.stem}_saved{suffix}")
        again = load_camera(saved)
        assert again == camera and again.to_dict() == camera.to_dict(), path.name
        # The project's own format round-trips exactly: the same bytes when saved again.
        resaved = save_camera(again, tmp_path / f"{path.stem}_resaved{suffix}")
        assert resaved.read_bytes() == saved.read_bytes()


def test_load_camera_refuses_what_the_model_refuses(tmp_path: Path) -> None:
    path = tmp_path / "camchain.yaml"
    path.write_text(
        "cam0:\n  camera_model: eucm\n  distortion_model: none\n  intrinsics: [0.6, -1.0, 190, 190, 255, 256]\n"
        "  resolution: [512, 512]\n"
    )
    with pytest.raises(
        CalibrationFileError, match=r"camchain.yaml: key 'cam0': not a valid eucm camera \(.*beta"
    ):
        load_camera(path)


def test_basalt_and_kalibr_share_a_pixel_convention(tmp_path: Path) -> None:
    """TUM-VI's cam0 calibrated by basalt (ds, eucm) and by Kalibr (pinhole-equi): the principal points agree to a
    few hundredths of a pixel, so neither reader shifts by half a pixel against the other."""
    kalibr = read_calibration(fx.write_kalibr_camchain(tmp_path / "camchain.yaml", "equi"), "cam0").camera
    for values, kind in ((fx.TUMVI_DS, "ds"), (fx.TUMVI_EUCM, "eucm")):
        basalt = read_calibration(fx.write_basalt(tmp_path / f"{kind}.json", values, kind), 0).camera
        assert abs(basalt["cx"] - kalibr["cx"]) < 0.05 and abs(basalt["cy"] - kalibr["cy"]) < 0.05
