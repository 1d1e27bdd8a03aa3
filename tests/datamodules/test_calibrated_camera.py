"""``data.camera.calibration``: the datamodule serves a calibrated lens read from a calibration file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry import CubemapToFisheye
from airfisheye_bench.geometry.serving import serve_camera
from airfisheye_bench.io.calibration_files import load_camera
from datamodules import AirFisheyeDataModule
from tests.helpers import calibration_fixtures as fx


def _datamodule(root: Path, task: str = "completion", **camera) -> AirFisheyeDataModule:
    dm = AirFisheyeDataModule(task, root=root, camera=camera, batch_size=2, augment=None)
    dm.setup("validate")
    return dm


def test_kalibr_ds_camera_is_served(tiny_dataset: Path, tmp_path: Path) -> None:
    camchain = fx.write_kalibr_camchain(tmp_path / "camchain.yaml", "ds")
    dm = _datamodule(tiny_dataset, size=64, calibration=str(camchain), camera="cam1")
    expected = load_camera(camchain, "cam1").resized(64, 64)
    assert dm.camera == expected and dm.camera.model == "double_sphere"
    dataset = dm.split_dataset("val")
    sample = dataset[0]
    # The image is the cube faces seen through that lens: the remap with the expected camera, pixel for pixel.
    faces = dataset._faces(sample["sample_id"], "rgb")
    rgb = CubemapToFisheye(expected, dataset.face_size)(faces, "bilinear")
    mean, std = (
        torch.tensor([0.485, 0.456, 0.406])[:, None, None],
        torch.tensor([0.229, 0.224, 0.225])[:, None, None],
    )
    assert torch.allclose(sample["image"], (rgb.float() / 255 - mean) / std, atol=1e-6)
    assert torch.equal(sample["valid_mask"], CubemapToFisheye(expected, dataset.face_size).valid_mask)
    assert not (sample["sparse_depth"][0][~sample["valid_mask"]]).any()


def test_non_square_calibration_is_padded_not_stretched(tiny_dataset: Path, tmp_path: Path) -> None:
    front = tmp_path / "front.json"
    front.write_text(json.dumps(fx.WOODSCAPE_FRONT))
    dm = _datamodule(tiny_dataset, "seg", size=64, calibration=str(front))
    served = serve_camera(load_camera(front), 64, "pad")  # 1280 x 966 -> 64 x 48.3, 7.85 px bands
    assert dm.camera == served.camera
    sample = dm.split_dataset("val")[0]
    outside = ~served.frame_mask()
    assert outside[:7].all() and outside[-7:].all() and not outside[8:-8].any()
    assert not sample["valid_mask"][outside].any() and (sample["label"][outside] == 255).all()
    black = (torch.zeros(3) - torch.tensor([0.485, 0.456, 0.406])) / torch.tensor([0.229, 0.224, 0.225])
    assert torch.allclose(sample["image"][:, outside].T, black.expand(int(outside.sum()), 3))
    crop = _datamodule(tiny_dataset, "seg", size=64, calibration=str(front), fit="crop")
    assert crop.camera == serve_camera(load_camera(front), 64, "crop").camera
    assert crop.split_dataset("val")[0]["valid_mask"].float().mean() > sample["valid_mask"].float().mean()


def test_calibration_errors_name_the_key(tiny_dataset: Path, tmp_path: Path) -> None:
    camchain = fx.write_kalibr_camchain(tmp_path / "camchain.yaml", "ds")
    with pytest.raises(
        ConfigError, match=r"data.camera.calibration: .*holds 2 cameras .*data.camera.camera="
    ):
        AirFisheyeDataModule("seg", root=tiny_dataset, camera={"calibration": str(camchain)})
    with pytest.raises(ConfigError, match=r"drop data.camera.model / fov_deg / k"):
        _datamodule(tiny_dataset, "seg", calibration=str(camchain), camera=0, fov_deg=180.0)
    with pytest.raises(ConfigError, match=r"data.camera.calibration needs data.source=cubemap"):
        dm = AirFisheyeDataModule(
            "seg", root=tiny_dataset, source="fisheye", camera={"calibration": str(camchain), "camera": 0}
        )
        dm.setup("validate")


def test_an_inline_camera_dict_serves_the_same_camera(tiny_dataset: Path, tmp_path: Path) -> None:
    """What an ONNX model's data config carries in place of the file gives the same served camera."""
    image_02 = fx.write_kitti360(tmp_path / "image_02.yaml")
    from_file = _datamodule(tiny_dataset, "seg", size=64, calibration=str(image_02))
    inline = _datamodule(tiny_dataset, "seg", size=64, calibration=load_camera(image_02).to_dict())
    assert inline.camera == from_file.camera and from_file.camera.model == "unified"
    assert np.isclose(from_file.camera.fx, load_camera(image_02).fx * 64 / 1400)
