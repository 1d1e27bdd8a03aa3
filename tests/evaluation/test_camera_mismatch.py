"""An ONNX model carries its camera; evaluation refuses data served with another one unless told to."""

from __future__ import annotations

import logging
from types import SimpleNamespace

import pytest
from omegaconf import OmegaConf

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.evaluation.command import _check_camera
from airfisheye_bench.export.deploy import _portable_data_config
from airfisheye_bench.geometry import ideal_camera
from airfisheye_bench.io.calibration_files import load_camera
from tests.helpers import calibration_fixtures as fx


def test_another_camera_is_refused_naming_both(tmp_path, caplog) -> None:
    model_camera = load_camera(fx.write_kitti360(tmp_path / "image_02.yaml")).resized(64, 64)
    served = ideal_camera(64, 64, fov_deg=190.0)
    cfg = OmegaConf.create({"onnx_path": "m.onnx", "allow_camera_mismatch": False})
    _check_camera(cfg, model_camera.to_dict(), model_camera)  # the same camera passes
    with pytest.raises(ConfigError) as err:
        _check_camera(cfg, model_camera.to_dict(), served)
    message = str(err.value)
    assert "\n" not in message and "ONNX model m.onnx" in message
    assert (
        "unified 64x64" in message
        and "equidistant 64x64" in message
        and "allow_camera_mismatch=true" in message
    )
    cfg.allow_camera_mismatch = True
    with caplog.at_level(logging.WARNING):
        _check_camera(cfg, model_camera.to_dict(), served)
    assert "scoring anyway" in caplog.text


def test_the_exported_data_config_carries_the_lens_not_the_file(tmp_path) -> None:
    camchain = fx.write_kalibr_camchain(tmp_path / "camchain.yaml", "ds")
    lens = load_camera(camchain, "cam1")
    data = OmegaConf.create(
        {"camera": {"size": 64, "calibration": str(camchain), "camera": "cam1", "fit": "pad"}}
    )
    datamodule = SimpleNamespace(camera_config=SimpleNamespace(lens=lens))
    portable = _portable_data_config(data, datamodule)
    assert portable["camera"] == {"size": 64, "calibration": lens.to_dict(), "camera": None, "fit": "pad"}
    plain = OmegaConf.create({"camera": {"size": 64, "calibration": None}})
    assert _portable_data_config(plain, datamodule) == {"camera": {"size": 64, "calibration": None}}
