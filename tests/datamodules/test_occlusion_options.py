"""``data.occlusion`` / ``data.occlusion_options``: every method and its options reach the sparse depth map."""

from __future__ import annotations

from pathlib import Path

import hydra
import numpy as np
import pytest
import torch

from airfisheye_bench.geometry.occlusion import OCCLUSION_METHODS, OCCLUSION_OPTIONS, lidar_depth_map
from datamodules.dataset import AirFisheyeDataset, CameraConfig
from tests.training.test_configs import compose_train


@pytest.mark.parametrize(
    ("method", "options"),
    [
        ("ordering", "{elevation_tolerance:-0.25,azimuth_window:16}"),
        ("zbuffer", "{kernel:5,threshold:1.0,relative:false}"),
        ("hpr", "{radius:100}"),
        ("none", "{}"),
    ],
)
def test_every_method_and_its_options_are_selectable_from_the_config(method: str, options: str) -> None:
    cfg = compose_train(["task=completion", f"data.occlusion={method}", f"data.occlusion_options={options}"])
    datamodule = hydra.utils.instantiate(cfg.data, _convert_="partial")  # builds no dataset yet
    kwargs = datamodule.dataset_kwargs
    assert kwargs["occlusion"] == method
    assert set(kwargs["occlusion_options"]) <= set(OCCLUSION_OPTIONS[method])
    assert len(kwargs["occlusion_options"]) == options.count(":")


def test_unknown_or_bad_options_name_the_key() -> None:
    # Hydra wraps the datamodule's ValueError; the message is the datamodule's
    cfg = compose_train(["task=completion", "data.occlusion=zbuffer", "data.occlusion_options={size:3}"])
    with pytest.raises(Exception, match=r"data.occlusion_options \(data.occlusion=zbuffer\).*\['size'\]"):
        hydra.utils.instantiate(cfg.data, _convert_="partial")
    cfg = compose_train(["task=completion", "data.occlusion=hpr", "data.occlusion_options={radius:0.5}"])
    with pytest.raises(Exception, match=r"data\.occlusion_options.*radius"):
        hydra.utils.instantiate(cfg.data, _convert_="partial")
    # options of another method are unknown here
    cfg = compose_train(["task=completion", "data.occlusion=ordering", "data.occlusion_options={radius:100}"])
    with pytest.raises(Exception, match="unknown option"):
        hydra.utils.instantiate(cfg.data, _convert_="partial")


@pytest.mark.parametrize("method", OCCLUSION_METHODS)
def test_sparse_depth_follows_method_and_options(tiny_dataset: Path, method: str) -> None:
    options = {"ordering": {"elevation_tolerance": -0.25}, "zbuffer": {"kernel": 3}, "hpr": {"radius": 50.0}}
    options = options.get(method, {})
    ds = AirFisheyeDataset(
        tiny_dataset,
        "val",
        "completion",
        camera=CameraConfig(size=64),
        occlusion=method,
        occlusion_options=options,
    )
    sid = ds.sample_ids[0]
    expected = lidar_depth_map(
        ds.reader.lidar(sid)[:, :3].astype(np.float64),
        ds.T_cam_lidar(sid),
        ds.camera,
        ds.reader.calib(sid).lidar_spec(),
        method,
        max_depth=ds.max_depth,
        **options,
    )
    sample = ds[0]
    sparse = sample["sparse_depth"][0]
    expected = torch.from_numpy(expected) * sample["valid_mask"]  # the loader masks what no face sees
    assert (sparse > 0).any()
    torch.testing.assert_close(sparse, expected)
