"""Channel tables of real sensors: presets against their published values, specs from files and Ouster metadata."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.lidar_layout import rings_from_elevation
from airfisheye_bench.geometry.lidar_presets import LIDAR_PRESETS, ouster_metadata_table
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.lidar_spec import load_lidar_spec


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
    with pytest.raises(ValueError, match="beam_altitude_angles"):
        ouster_metadata_table({"beam_intrinsics": {}})
