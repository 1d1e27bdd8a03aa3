"""Serving a calibrated camera at another size (airfisheye_bench.geometry.serving): a similarity of the pixel grid,
never a stretch, for every model."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry.serving import serve_camera
from airfisheye_bench.io.calibration_files import load_camera
from tests.helpers import calibration_fixtures as fx


def _woodscape(tmp_path: Path):
    path = tmp_path / "front.json"
    path.write_text(json.dumps(fx.WOODSCAPE_FRONT))
    return load_camera(path)


def _ocam(tmp_path: Path):
    path = tmp_path / "calib_results.txt"
    path.write_text(fx.OCAM_KODAK)
    return load_camera(path)


@pytest.mark.parametrize("fit", ["pad", "crop"])
def test_served_pixels_look_along_the_calibrated_rays(tmp_path: Path, fit: str) -> None:
    """Every served pixel centre looks along the ray of the calibrated camera at the mapped sensor position."""
    for camera in (
        _woodscape(tmp_path),  # 1280 x 966: padded or cropped
        load_camera(fx.write_kitti360(tmp_path / "image_02.yaml")),  # square: resized
        load_camera(fx.write_basalt(tmp_path / "ds.json", fx.TUMVI_DS, "ds"), 0),
        _ocam(tmp_path),
    ):
        served = serve_camera(camera, 96, fit)
        assert (served.camera.width, served.camera.height) == (96, 96)
        grid = served.camera.pixel_grid()
        rays = served.camera.unproject(grid)
        expected = camera.unproject(served.to_source(grid))
        both = torch.isfinite(rays).all(-1) & torch.isfinite(expected).all(-1)
        assert both.float().mean() > 0.5
        assert torch.allclose(rays[both], expected[both], atol=1e-9), camera.model


@pytest.mark.parametrize(
    "line",
    [
        "THIN_PRISM_FISHEYE 772 1022 651.123 655.123 386.123 511.123 -0.471 0.223 -0.001 0.001 0.001 0.02 -0.02 0.001",
        "RAD_TAN_THIN_PRISM_FISHEYE 772 1022 651.123 655.123 386.123 511.123 -0.0232 0.0924 -0.0591 0.003 0.0048 "
        "-0.0009 0.0002 0.0005 -0.0009 -0.0001 0.00007 -0.00017",
        "DIVISION 772 1022 651.123 655.123 386.123 511.123 -0.1",
    ],
)
def test_colmap_models_are_served_along_their_rays(tmp_path: Path, line: str) -> None:
    """COLMAP's thin-prism and division models (models_test.cc's parameters) served at 96 x 96, padded."""
    path = tmp_path / "cameras.txt"
    path.write_text(f"1 {line}\n")
    camera = load_camera(path)
    served = serve_camera(camera, 96, "pad")
    assert served.camera.model == camera.model and served.scale == pytest.approx(96 / 1022)
    grid = served.camera.pixel_grid()
    rays, expected = served.camera.unproject(grid), camera.unproject(served.to_source(grid))
    on_sensor = served.frame_mask()
    assert torch.isfinite(rays[on_sensor]).all()
    torch.testing.assert_close(rays[on_sensor], expected[on_sensor], rtol=0, atol=1e-9)


def test_non_square_pad_and_crop(tmp_path: Path) -> None:
    camera = _woodscape(tmp_path)
    pad, crop = serve_camera(camera, 512, "pad"), serve_camera(camera, 512, "crop")
    assert pad.scale == pytest.approx(512 / 1280) and crop.scale == pytest.approx(512 / 966)
    # pad: the sensor is 1280 x 966 * 0.4 = 512 x 386.4, centred: 62.8 px bands above and below are off the sensor.
    mask = pad.frame_mask()
    assert mask[:62].any(-1).sum() == 0 and mask[63:449].all() and not mask[450:].any()
    assert "padded by 62.8 px above and below" in pad.describe()
    # crop: every served pixel is on the sensor; (1280 * 512 / 966 - 512) / 2 = 83.2 px cut at each side.
    assert crop.frame_mask().all() and crop.offset[0] == pytest.approx(-(1280 * 512 / 966 - 512) / 2)
    assert "cropped by 83.2" in crop.describe()
    # Focal lengths scale with the image, the lens is not stretched: radial_poly's k_i are pixel lengths.
    assert pad.camera.k1 == pytest.approx(camera.k1 * 0.4) and pad.camera.aspect_ratio == camera.aspect_ratio


def test_square_and_identity(tmp_path: Path) -> None:
    camera = load_camera(fx.write_kitti360(tmp_path / "image_02.yaml"))
    assert serve_camera(camera, None).camera is camera and serve_camera(camera, 1400).camera is camera
    half = serve_camera(camera, 700)
    assert half.fit is None and half.camera == camera.resized(700, 700)
    assert np.isclose(half.camera.cx, (camera.cx + 0.5) * 0.5 - 0.5)
    with pytest.raises(ValueError, match="fit must be one of pad, crop"):
        serve_camera(camera, 64, "stretch")
