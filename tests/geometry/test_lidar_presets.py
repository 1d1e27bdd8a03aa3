"""Channel tables of real sensors: presets against their published values, specs from files and Ouster metadata."""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_layout import organize_scan, rings_from_elevation
from airfisheye_bench.geometry.lidar_presets import HDL32E_VERTICAL_ANGLES_DEG, LIDAR_PRESETS
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.lidar_spec import load_lidar_spec, ouster_metadata_spec


@pytest.mark.parametrize("name", sorted(LIDAR_PRESETS))
def test_every_preset_builds_and_round_trips(name: str) -> None:
    spec = LidarSpec.from_preset(name)
    assert spec.name == name
    assert LidarSpec.from_dict(spec.to_dict()) == spec
    assert np.all(np.diff(spec.channel_elevations()) > 0)
    assert spec.beam_directions().shape == (spec.channels, spec.points_per_channel, 3)


def test_hdl64e_matches_the_kitti_calibration() -> None:
    """Golden values: KITTI's velodynecalib_S2_factory_flatness_intensity.xml (laser 0: rotCorrection -5.0704789,
    vertCorrection -7.287312, vertOffsetCorrection 19.737808 cm, horizOffsetCorrection 2.5999999 cm; the highest
    laser is ID 29 at 1.9367 deg, the lowest ID 38 at -24.999201 deg)."""
    spec = LidarSpec.from_preset("hdl64e")
    assert spec.channels == 64 and spec.hfov_deg == 360.0
    assert spec.vfov_deg == (-24.999201, 1.9367)
    ring = spec.elevations_deg.index(-7.287312)
    assert spec.azimuth_offsets_deg[ring] == -5.0704789
    assert spec.beam_origins_m[ring] == pytest.approx((0.0, 0.025999999, 0.19737808))
    # 1/3 deg upper block, 1/2 deg lower block: far from a uniform grid (the issue measured up to 2.9 deg)
    uniform = np.linspace(*spec.vfov_deg, 64)
    assert np.abs(np.asarray(spec.elevations_deg) - uniform).max() > 2.0
    spacing = np.diff(spec.elevations_deg)
    assert 0.3 < np.median(spacing[40:]) < 0.45 and 0.4 < np.median(spacing[:20]) < 0.6


def test_hdl32e_matches_the_manuals_table() -> None:
    """Golden values: the HDL-32E manual's "Laser Firing Sequence" (laser 0 at -30.67 deg fires first, then the lower
    and upper banks interleave: laser 1 at -9.33, laser 2 at -29.33, ...; laser 15 is the 0 deg one, laser 31 the
    highest at +10.67); no beam origins (Appendix D: every laser fires from the centre of the lenses)."""
    spec = LidarSpec.from_preset("hdl32e")
    assert spec.channels == 32 and spec.vfov_deg == (-30.67, 10.67) and spec.beam_origins_m is None
    angles = np.asarray(HDL32E_VERTICAL_ANGLES_DEG)
    assert angles[:4].tolist() == [-30.67, -9.33, -29.33, -8.0] and angles[15] == 0.0 and angles[31] == 10.67
    ring_of_laser = np.argsort(np.argsort(angles))  # the ring (elevation order) of each laser in firing order
    assert ring_of_laser[:6].tolist() == [0, 16, 1, 17, 2, 18]
    # the manual's 2-decimal angles on the datasheet's 4/3 deg grid
    np.testing.assert_allclose(spec.elevations_deg, np.linspace(-30.67, 10.67, 32), atol=0.011)


def test_other_presets_have_their_datasheet_values() -> None:
    hdl32 = LidarSpec.from_preset("hdl32e")  # HDL-32E: +10.67 .. -30.67 deg, 4/3 deg spacing
    assert hdl32.channels == 32 and math.degrees(hdl32.vertical_resolution) == pytest.approx(4 / 3, abs=1e-3)
    vlp16 = LidarSpec.from_preset(
        "vlp16"
    )  # VLP-16 manual: -15..15 in 2 deg steps, laser 0 (-15 deg) 11.2 mm up
    assert vlp16.elevations_deg == tuple(float(v) for v in range(-15, 16, 2))
    assert vlp16.beam_origins_m[0] == pytest.approx((0.0, 0.0, 0.0112))
    vlp32 = LidarSpec.from_preset("vlp32c")  # VLP-32C manual: -25 .. +15, densest 1/3 deg at the horizon
    assert vlp32.vfov_deg == (-25.0, 15.0) and min(np.diff(vlp32.elevations_deg)) == pytest.approx(
        0.333, abs=1e-3
    )
    os1 = LidarSpec.from_preset("os1-64")  # Ouster SDK gen1 design values, 15.806 mm beam origin
    assert os1.vfov_deg == (-16.611, 16.611) and os1.beam_origins_m[0][0] == pytest.approx(0.015806)
    assert sorted(set(os1.azimuth_offsets_deg)) == [-3.164, -1.055, 1.055, 3.164]
    pandar = LidarSpec.from_preset("pandar64")  # HesaiLidar_General_SDK: 14.882 .. -24.897
    assert pandar.vfov_deg == (-24.897, 14.882)
    assert LidarSpec.from_preset("paper") == LidarSpec(name="paper")


def test_the_uniform_spec_and_old_calibration_dicts_still_load() -> None:
    old = {
        "channels": 16,
        "points_per_channel": 128,
        "hfov_deg": 270.0,
        "vfov_deg": [-45.0, 15.0],
        "max_range": 120,
    }
    spec = LidarSpec.from_dict(old)
    assert spec.is_uniform and spec.to_dict() == {**old, "max_range": 120.0}
    r = np.full(3, 10.0)
    el = np.radians([-45.0, -41.1, 15.0])
    assert rings_from_elevation(r, el, spec).tolist() == [0, 1, 15]


def test_bad_tables_are_refused() -> None:
    with pytest.raises(ValueError, match="strictly ascending"):
        LidarSpec(elevations_deg=(1.0, 0.0))
    with pytest.raises(ValueError, match="azimuth_offsets_deg"):
        LidarSpec(elevations_deg=(0.0, 1.0), azimuth_offsets_deg=(0.0,))
    with pytest.raises(ValueError, match="channels=16"):
        LidarSpec(channels=16, elevations_deg=(0.0, 1.0))
    with pytest.raises(ValueError, match="unknown LiDAR preset 'hdl65e'"):
        LidarSpec.from_preset("hdl65e")


def _ouster_legacy() -> dict:
    """The flat layout of Ouster's legacy metadata (firmware 1.x), e.g. ``os1-991901000584.json``."""
    return {
        "prod_line": "OS-1-64",
        "lidar_mode": "2048x10",
        "beam_altitude_angles": [16.611 - 0.527 * i for i in range(64)],
        "beam_azimuth_angles": [3.164, 1.055, -1.055, -3.164] * 16,
        "lidar_origin_to_beam_origin_mm": 15.806,
    }


def _ouster_nested() -> dict:
    """The nested layout of firmware 2.x / ouster-sdk (``beam_intrinsics``, ``lidar_data_format``)."""
    legacy = _ouster_legacy()
    return {
        "sensor_info": {"prod_line": "OS-1-64"},
        "beam_intrinsics": {k: legacy[k] for k in legacy if k.startswith(("beam", "lidar_origin"))},
        "lidar_data_format": {"pixels_per_column": 64, "columns_per_frame": 1024},
        "config_params": {"lidar_mode": "1024x10"},
    }


@pytest.mark.parametrize("layout", [_ouster_legacy, _ouster_nested])
def test_an_ouster_metadata_json_becomes_a_spec(layout, tmp_path: Path) -> None:
    path = tmp_path / "os1.json"
    path.write_text(json.dumps(layout()))
    spec = load_lidar_spec(str(path))
    assert spec.channels == 64 and spec.hfov_deg == 360.0
    assert spec.points_per_channel == (2048 if layout is _ouster_legacy else 1024)
    assert spec.vfov_deg[1] == pytest.approx(16.611) and spec.vfov_deg[0] == pytest.approx(
        16.611 - 0.527 * 63
    )
    top = spec.channels - 1  # beam 0 is the top one: its azimuth 3.164 deg is subtracted by Ouster
    assert spec.azimuth_offsets_deg[top] == pytest.approx(-3.164)
    assert spec.beam_origins_m[top] == pytest.approx((0.015806, 0.0, 0.0))


def test_spec_files_and_their_errors(tmp_path: Path) -> None:
    path = tmp_path / "sensor.yaml"
    path.write_text("preset: hdl64e\npoints_per_channel: 1024\n")
    assert load_lidar_spec(str(path)).points_per_channel == 1024
    path.write_text("elevations_deg: [-2, 0, 2]\npoints_per_channel: 90\nhfov_deg: 360\n")
    assert load_lidar_spec(str(path)).channels == 3
    path.write_text("channels: many\n")
    with pytest.raises(DatasetFormatError, match=r"sensor\.yaml"):
        load_lidar_spec(str(path))
    with pytest.raises(ValueError, match="unknown LiDAR preset 'vlp17'"):
        load_lidar_spec("vlp17")
    with pytest.raises(DatasetFormatError, match=r"key 'beam_intrinsics\.beam_altitude_angles': is missing"):
        ouster_metadata_spec({"beam_intrinsics": {}})


# ------------------------------------------------------------------ Ouster metadata as the SDK reads it
# github:ouster-lidar/ouster-sdk at commit 46b7bceee7995914e2f3f3facf4d78418335b2d7 (release 1.0.1): the sample
# metadata in tests/metadata/ and the values tests/bcompat_meta_json_test.cpp expects the SDK to parse from them.
# 1_13_os1-991937000062-16A0_legacy.json (firmware 1.13, an OS-1-16-A0): 64 entries, (0, 0) where no beam fires.
SDK_1_13_16A0_ALTITUDES = [0, 0, 0, 14.799, 0, 0, 0, 12.648, 0, 0, 0, 10.537, 0, 0, 0, 8.442, 0, 0, 0, 6.357, 0, 0, 0,
    4.262, 0, 0, 0, 2.183, 0, 0, 0, 0.1, 0, 0, 0, -1.991, 0, 0, 0, -4.079, 0, 0, 0, -6.168, 0, 0, 0, -8.275, 0, 0, 0,
    -10.373, 0, 0, 0, -12.489, 0, 0, 0, -14.658, 0, 0, 0, -16.858]  # fmt: skip
SDK_1_13_16A0_AZIMUTHS = [0, 0, 0, -3.387, 0, 0, 0, -3.326, 0, 0, 0, -3.288, 0, 0, 0, -3.243, 0, 0, 0, -3.206, 0, 0,
    0, -3.183, 0, 0, 0, -3.159, 0, 0, 0, -3.129, 0, 0, 0, -3.1, 0, 0, 0, -3.083, 0, 0, 0, -3.067, 0, 0, 0, -3.048, 0, 0,
    0, -3.04, 0, 0, 0, -3.037, 0, 0, 0, -3.043, 0, 0, 0, -3.041]  # fmt: skip
# 1_14_beta_os1-991937000062-16A0_legacy.json: the same unit on firmware 1.14, its 16 beams only.
SDK_1_14_16A0_ALTITUDES = [14.799, 12.648, 10.537, 8.442, 6.357, 4.262, 2.183, 0.1, -1.991, -4.079, -6.168, -8.275,
    -10.373, -12.489, -14.658, -16.858]  # fmt: skip
SDK_1_14_16A0_AZIMUTHS = [-3.387, -3.326, -3.288, -3.243, -3.206, -3.183, -3.159, -3.129, -3.1, -3.083, -3.067,
    -3.048, -3.04, -3.037, -3.043, -3.041]  # fmt: skip
# 2_0_0_os1-992008000494-128_col_win_legacy.json: an OS-1-128 at 2048x10 returning columns 2014..2036 only (its
# beams 0-3 here), with the SDK's default lidar_to_sensor_transform.
SDK_COL_WIN = {
    "prod_line": "OS-1-128",
    "lidar_mode": "2048x10",
    "beam_altitude_angles": [21.4764, 21.1679, 20.8583, 20.5477],
    "beam_azimuth_angles": [4.2521, 1.4197, -1.4196, -4.252],
    "lidar_origin_to_beam_origin_mm": 15.806,
    "data_format": {"column_window": [2014, 2036], "columns_per_frame": 2048, "pixels_per_column": 4},
    "lidar_to_sensor_transform": [-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 36.18, 0, 0, 0, 1],
}


def _write_json(path: Path, meta: dict) -> str:
    path.write_text(json.dumps(meta))
    return str(path)


@pytest.mark.parametrize(
    ("prod_line", "origin_mm"),
    [
        ("OS-0-32-U0", 27.67),  # 1_14_6cccd_os-882002000138-32U0_legacy.json: bcompat expects 27.67
        ("OS-1-16-A0", 15.806),  # 1_14_beta_os1-991937000062-16A0_legacy.json: bcompat expects 15.806
        ("OS-2-32-U0", 13.762),  # ouster_core/src/sensor_info.cpp default_lidar_origin_to_beam_origin
        ("OS-DOME-128", 12.163),  # any other product line: the SDK's "default for gen 1"
    ],
)
def test_legacy_ouster_metadata_without_a_beam_origin_takes_the_sdk_default(
    prod_line: str, origin_mm: float, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Firmware 1.12-1.14 wrote no lidar_origin_to_beam_origin_mm: the SDK uses its product line's default
    (ouster-sdk 46b7bce, ``sensor_info.cpp`` ``default_lidar_origin_to_beam_origin``; ``bcompat_meta_json_test.cpp``
    expects 27.67 for 1_14_6cccd_os-882002000138-32U0_legacy.json and 15.806 for the 1_14_beta 16A0 file)."""
    meta = {"prod_line": prod_line, "lidar_mode": "1024x10", "beam_altitude_angles": SDK_1_14_16A0_ALTITUDES,
            "beam_azimuth_angles": SDK_1_14_16A0_AZIMUTHS, "data_format": {"pixels_per_column": 16}}  # fmt: skip
    with caplog.at_level(logging.INFO, logger="airfisheye_bench.io.lidar_spec"):
        spec = load_lidar_spec(_write_json(tmp_path / "os.json", meta))
    assert {o for o in spec.beam_origins_m} == {(origin_mm / 1000.0, 0.0, 0.0)}
    assert "no lidar_origin_to_beam_origin_mm" in caplog.text and f"{origin_mm:g} mm" in caplog.text


def test_firmware_1_13_placeholders_are_dropped(tmp_path: Path) -> None:
    """ouster-sdk 46b7bce tests/metadata/1_13_os1-991937000062-16A0_legacy.json (64 entries, 48 of them (0, 0))
    reads as the same unit's 1_14_beta_os1-991937000062-16A0_legacy.json (its 16 beams): beams 3, 7, ..., 63."""
    legacy = {"prod_line": "OS-1-16-A0", "lidar_mode": "1024x10", "beam_altitude_angles": SDK_1_13_16A0_ALTITUDES,
              "beam_azimuth_angles": SDK_1_13_16A0_AZIMUTHS}  # fmt: skip
    newer = {**legacy, "beam_altitude_angles": SDK_1_14_16A0_ALTITUDES,
             "beam_azimuth_angles": SDK_1_14_16A0_AZIMUTHS, "data_format": {"pixels_per_column": 16}}  # fmt: skip
    spec = load_lidar_spec(_write_json(tmp_path / "os.json", legacy))
    assert spec == load_lidar_spec(_write_json(tmp_path / "os.json", newer))
    assert spec.channels == 16 and spec.vfov_deg == (-16.858, 14.799)
    assert spec.azimuth_offsets_deg[-1] == 3.387  # beam 3 of 64, the top one: Ouster subtracts -3.387
    # A 32-beam sensor (prod_line OS-1-32-A02) keeps the 32 non-placeholders, as 1_13_...-32A02_legacy.json lists.
    assert ouster_metadata_spec({**legacy, "prod_line": "OS-1-32-A02"} | _odd_beams()).channels == 32


def _odd_beams() -> dict:
    alt = [0.0 if i % 2 == 0 else 16.0 - i * 0.5 for i in range(64)]
    return {"beam_altitude_angles": alt, "beam_azimuth_angles": [0.0 if a == 0 else 1.0 for a in alt]}


def _sdk_directions(meta: dict) -> np.ndarray:
    """``[beams, window columns, 3]`` unit directions as ouster-sdk 46b7bce ``ouster_core/src/xyzlut.cpp``
    ``make_xyz_lut`` computes them (encoder ``2 pi - 2 pi m / W``, azimuth ``-beam_azimuth_angles``), turned by
    ``lidar_to_sensor_transform``'s rotation into the sensor frame, for the window's columns first..last."""
    fmt = meta["data_format"]
    w, (first, last) = fmt["columns_per_frame"], fmt["column_window"]
    cols = (first + np.arange((last - first) % w + 1)) % w
    encoder = 2.0 * np.pi - cols * (2.0 * np.pi / w)
    az = -np.radians(meta["beam_azimuth_angles"])[:, None]
    alt = np.radians(meta["beam_altitude_angles"])[:, None]
    d = np.stack(np.broadcast_arrays(np.cos(encoder + az) * np.cos(alt), np.sin(encoder + az) * np.cos(alt),
                                     np.sin(alt)), axis=-1)  # fmt: skip
    rotation = np.asarray(meta["lidar_to_sensor_transform"], dtype=np.float64).reshape(4, 4)[:3, :3]
    return d @ rotation.T


@pytest.mark.parametrize(
    "meta",
    [
        SDK_COL_WIN,  # 23 of 2048 columns, behind the sensor (-176 deg)
        {**SDK_COL_WIN, "data_format": {**SDK_COL_WIN["data_format"], "column_window": [960, 1087]}},  # ahead
        {  # a window through column 0 (it wraps), with the lidar frame as the sensor frame: centred ahead
            **SDK_COL_WIN,
            "data_format": {**SDK_COL_WIN["data_format"], "column_window": [1990, 57]},
            "lidar_to_sensor_transform": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1],
        },
    ],
)
def test_a_column_window_is_the_field_of_view_the_sdk_computes(meta: dict, tmp_path: Path) -> None:
    """The spec's beams are the SDK's for the window's columns (ouster-sdk 46b7bce xyzlut.cpp; the window of
    tests/metadata/2_0_0_os1-992008000494-128_col_win_legacy.json, [2014, 2036] at 2048 columns, and two more)."""
    spec = load_lidar_spec(_write_json(tmp_path / "os.json", meta))
    first, last = meta["data_format"]["column_window"]
    count = (last - first) % 2048 + 1
    assert spec.points_per_channel == count and spec.hfov_deg == pytest.approx(360.0 * count / 2048)
    # Ours: channels by ascending elevation (Ouster's beam 0 is the top one), columns by ascending azimuth (the
    # SDK's columns turn clockwise): the same beams, both axes reversed.
    ours = spec.beam_directions(dtype=torch.float64).numpy()
    np.testing.assert_allclose(ours, _sdk_directions(meta)[::-1, ::-1], atol=1e-12)
    # A return at each column's azimuth lands in that column of I_LiDAR (the sectors count from the window's edge).
    az = spec.column_azimuths()
    pts = np.stack([10.0 * np.cos(az), 10.0 * np.sin(az), np.full_like(az, 3.7)], axis=-1)
    assert organize_scan(pts, spec).column.tolist() == list(range(count))
    assert LidarSpec.from_dict(spec.to_dict()) == spec
    if meta is SDK_COL_WIN:
        assert spec.azimuth_center_deg == pytest.approx(180.0 - 360.0 * 2025 / 2048)  # -175.96 deg


@pytest.mark.parametrize(
    ("change", "key", "expected"),
    [
        # 1_12_os1-991937000062-16A0_legacy.json: 64 real angles for 16 beams (the SDK refuses it too)
        ({"beam_altitude_angles": [16.5 - 0.5 * i for i in range(64)], "beam_azimuth_angles": [1.0] * 64},
         "beam_altitude_angles", "has 64 angles, 0 of them (0, 0) placeholders, for the 16 beams of prod_line"),
        # malformed/incorrect_nbeam_angles_legacy_113.json: 63 altitudes, 64 azimuths
        ({"beam_altitude_angles": SDK_1_13_16A0_ALTITUDES[1:]}, "beam_altitude_angles",
         "has 63 angles but beam_azimuth_angles has 64"),
        ({"data_format": {"pixels_per_column": 32}}, "beam_altitude_angles",
         "has 64 angles, 48 of them (0, 0) placeholders, for the 32 beams of data_format.pixels_per_column=32"),
        ({"prod_line": None, "beam_altitude_angles": SDK_1_14_16A0_ALTITUDES * 2, "beam_azimuth_angles": [0.0] * 32},
         "beam_altitude_angles", "lists altitude 14.799 twice"),
        ({"lidar_mode": "fast"}, "lidar_mode", "must be columns x rate such as '1024x10', got 'fast'"),
        ({"lidar_mode": None}, "lidar_mode", "is missing, and so is columns_per_frame"),
        ({"lidar_origin_to_beam_origin_mm": "15.8"}, "lidar_origin_to_beam_origin_mm", "must be millimetres"),
        ({"data_format": {"column_window": [0, 1024]}}, "data_format.column_window",
         "must be [first, last] columns in [0, 1023], got [0, 1024]"),
        ({"data_format": {"column_window": [1020, 3]}}, "data_format.column_window",
         "[1020, 3] points at -179.8 +- 1.4 deg, across +-180 deg"),
    ],
)  # fmt: skip
def test_a_bad_ouster_metadata_is_one_line_naming_the_key(
    change: dict, key: str, expected: str, tmp_path: Path
) -> None:
    meta = {"prod_line": "OS-1-16-A0", "lidar_mode": "1024x10", "beam_altitude_angles": SDK_1_13_16A0_ALTITUDES,
            "beam_azimuth_angles": SDK_1_13_16A0_AZIMUTHS, **change}  # fmt: skip
    meta = {k: v for k, v in meta.items() if v is not None}
    with pytest.raises(DatasetFormatError) as info:
        load_lidar_spec(_write_json(tmp_path / "os.json", meta))
    err = info.value
    assert err.key == key and expected in err.message, str(err)
    assert "\n" not in str(err) and "os.json" in str(err) and len(f"key '{key}': {err.message}") <= 200


def test_a_window_centre_is_part_of_the_spec() -> None:
    spec = LidarSpec(
        channels=2, points_per_channel=10, hfov_deg=36.0, vfov_deg=(-1.0, 1.0), azimuth_center_deg=90.0
    )
    np.testing.assert_allclose(np.degrees(spec.column_azimuths()), [73.8 + 3.6 * j for j in range(10)])
    assert spec.to_dict()["azimuth_center_deg"] == 90.0 and "azimuth_center_deg" not in LidarSpec().to_dict()
    with pytest.raises(ValueError, match="azimuth_center_deg=170 with hfov_deg=36"):
        LidarSpec(hfov_deg=36.0, azimuth_center_deg=170.0)
    with pytest.raises(ValueError, match="azimuth_center_deg=10 with hfov_deg=360"):
        LidarSpec(hfov_deg=360.0, azimuth_center_deg=10.0)


# ------------------------------------------------------------------ the ROS Velodyne driver's calibration YAML
# github:ros-drivers/velodyne velodyne_pointcloud/params/VLP16db.yaml (commit 29abd0e), vert_correction of laser
# IDs 0-15 in radians: the VLP-16's -15..15 deg in 2 deg steps, interleaved.
VLP16DB_VERT_CORRECTION = (
    -0.2617993877991494, 0.017453292519943295, -0.22689280275926285, 0.05235987755982989, -0.19198621771937624,
    0.08726646259971647, -0.15707963267948966, 0.12217304763960307, -0.12217304763960307, 0.15707963267948966,
    -0.08726646259971647, 0.19198621771937624, -0.05235987755982989, 0.22689280275926285, -0.017453292519943295,
    0.2617993877991494,
)  # fmt: skip
# The same repository's 64e_s2.1-sztaki.yaml (an HDL-64E S2), laser IDs 0-3: (rot_correction, vert_correction,
# vert_offset_correction, horiz_offset_correction), radians and metres.
SZTAKI_LASERS = (
    (-0.1248942899601548, -0.15304134919741974, 0.19548199, 0.025999999),
    (-0.06924466398252106, -0.1458455539136526, 0.19601112, -0.025999999),
    (0.0824016906676694, 0.04339494149708345, 0.20969539999999998, 0.025999999),
    (0.137808349360133, 0.05196082373432465, 0.21031273, -0.025999999),
)


def _velodyne_yaml(path: Path, lasers: list[dict], **top) -> Path:
    """A calibration file in the driver's own layout: one flow mapping per laser, as gen_calibration.py writes."""
    lines = ["lasers:"]
    for laser in lasers:
        values = {"dist_correction": 0.0, "dist_correction_x": 0.0, "dist_correction_y": 0.0}
        values.update({"focal_distance": 0.0, "focal_slope": 0.0, **laser})
        lines.append("- {" + ", ".join(f"{k}: {v!r}" for k, v in sorted(values.items())) + "}")
    top = {"num_lasers": len(lasers), "distance_resolution": 0.002, **top}
    lines += [f"{k}: {v}" for k, v in top.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def _laser(laser_id: int, vert: float, rot: float = 0.0, v_off: float = 0.0, h_off: float = 0.0) -> dict:
    return {"laser_id": laser_id, "rot_correction": rot, "vert_correction": vert,
            "vert_offset_correction": v_off, "horiz_offset_correction": h_off}  # fmt: skip


def test_a_velodyne_driver_calibration_becomes_a_spec(tmp_path: Path) -> None:
    """VLP16db.yaml: its 16 lasers sorted by elevation (ring 0 the lowest, as the driver numbers its rings) give
    the VLP-16's -15..15 deg, the vlp16 preset's table; no offsets in the file, none in the spec."""
    lasers = [_laser(i, v) for i, v in enumerate(VLP16DB_VERT_CORRECTION)]
    spec = load_lidar_spec(str(_velodyne_yaml(tmp_path / "VLP16db.yaml", lasers)))
    np.testing.assert_allclose(spec.elevations_deg, np.arange(-15.0, 16.0, 2.0), atol=1e-12)
    np.testing.assert_allclose(spec.elevations_deg, LIDAR_PRESETS["vlp16"]["elevations_deg"], atol=1e-12)
    assert spec.azimuth_offsets_deg is None and spec.beam_origins_m is None
    assert (spec.channels, spec.hfov_deg, spec.points_per_channel, spec.name) == (16, 360.0, 1800, "VLP16db")
    reordered = _velodyne_yaml(tmp_path / "any_order.yaml", lasers[::-1], points_per_channel=900)
    assert (
        load_lidar_spec(str(reordered)).elevations_deg == spec.elevations_deg
    )  # by laser_id, not list order
    assert load_lidar_spec(str(reordered)).points_per_channel == 900


def test_a_velodyne_calibration_places_the_beams_as_the_driver_does(tmp_path: Path) -> None:
    """Four HDL-64E S2 lasers of 64e_s2.1-sztaki.yaml: every point the driver's ``RawData::unpack``
    (velodyne_pointcloud/src/lib/rawdata.cc, without the two-point distance correction) computes from an encoder
    angle and a distance lies on the spec's beam of that laser, from its origin, at that distance."""
    lasers = [_laser(i, vert, rot, v_off, h_off) for i, (rot, vert, v_off, h_off) in enumerate(SZTAKI_LASERS)]
    spec = load_lidar_spec(str(_velodyne_yaml(tmp_path / "64e_s2.yaml", lasers)))
    rng = np.random.default_rng(0)
    laser = rng.integers(0, 4, 500)
    rotation = rng.uniform(0.0, 2.0 * math.pi, 500)  # the encoder angle, clockwise from forward
    distance = rng.uniform(1.0, 80.0, 500)
    rot, vert, v_off, h_off = np.array(SZTAKI_LASERS)[laser].T
    cos_rot = np.cos(rotation) * np.cos(rot) + np.sin(rotation) * np.sin(
        rot
    )  # cos(rotation - rot_correction)
    sin_rot = np.sin(rotation) * np.cos(rot) - np.cos(rotation) * np.sin(rot)
    xy_distance = distance * np.cos(vert) - v_off * np.sin(vert)
    x = xy_distance * sin_rot - h_off * cos_rot
    y = xy_distance * cos_rot + h_off * sin_rot
    z = distance * np.sin(vert) + v_off * np.cos(vert)
    driver = np.stack([y, -x, z], axis=1)  # "Use standard ROS coordinate system": x_coord = y, y_coord = -x
    ring = np.argsort(np.argsort(np.array(SZTAKI_LASERS)[:, 1]))[laser]  # laser -> its rank in elevation
    azimuth = -rotation + spec.channel_azimuth_offsets()[ring]
    elevation = spec.channel_elevations()[ring]
    direction = np.stack(
        [np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)], axis=1
    )
    ours = spec.beam_origins(azimuth, ring) + distance[:, None] * direction
    np.testing.assert_allclose(ours, driver, atol=1e-9)
    by_elevation = np.array(SZTAKI_LASERS)[np.argsort(np.array(SZTAKI_LASERS)[:, 1])]
    np.testing.assert_allclose(spec.azimuth_offsets_deg, np.degrees(by_elevation[:, 0]), atol=1e-12)
    assert spec.beam_origins_m[0][1] == pytest.approx(0.025999999)  # laser 0, the lowest: h_off to its left


@pytest.mark.parametrize(
    ("change", "key", "expected"),
    [
        (lambda lasers: lasers[3].update(vert_correction=-15.0), "lasers[3].vert_correction", "radians"),
        (lambda lasers: lasers[2].pop("rot_correction"), "lasers[2].rot_correction", "radians"),
        (lambda lasers: lasers[1].update(vert_offset_correction=19.5), "lasers[1].vert_offset_correction", "metres"),
        (lambda lasers: lasers[1].update(laser_id=0), "lasers[1].laser_id", "listed twice"),
        (lambda lasers: lasers[1].update(laser_id=16), "lasers[1].laser_id", "integer in [0, 16)"),
        (lambda lasers: lasers[5].update(vert_correction=lasers[0]["vert_correction"]), "lasers[5].vert_correction",
         "its own elevation"),
    ],
)  # fmt: skip
def test_a_bad_velodyne_calibration_is_one_line_naming_the_key(tmp_path: Path, change, key, expected) -> None:
    lasers = [_laser(i, v) for i, v in enumerate(VLP16DB_VERT_CORRECTION)]
    change(lasers)
    path = _velodyne_yaml(tmp_path / "calib.yaml", lasers)
    with pytest.raises(DatasetFormatError) as info:
        load_lidar_spec(str(path))
    message = str(info.value)
    assert str(path) in message and f"key '{key}'" in message and expected in message
    assert "\n" not in message and len(message.replace(str(path), "")) <= 200


def test_a_velodyne_calibration_with_other_top_level_keys_is_refused(tmp_path: Path) -> None:
    lasers = [_laser(i, v) for i, v in enumerate(VLP16DB_VERT_CORRECTION)]
    for top, key in (({"num_lasers": 32}, "num_lasers"), ({"rpm": 600}, "rpm")):
        path = _velodyne_yaml(tmp_path / "calib.yaml", lasers, **top)
        with pytest.raises(DatasetFormatError, match=rf"calib\.yaml: key '{key}': .{{10,200}}$"):
            load_lidar_spec(str(path))
