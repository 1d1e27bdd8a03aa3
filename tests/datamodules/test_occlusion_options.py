"""``data.occlusion`` / ``data.occlusion_options``: every method and its options reach the sparse depth map."""

from __future__ import annotations

from pathlib import Path

import hydra
import numpy as np
import pytest
import torch
from omegaconf import OmegaConf

from airfisheye_bench.config_checks import check_common_values
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.occlusion import (
    OCCLUSION_METHODS,
    OCCLUSION_OPTIONS,
    Occlusion,
    lidar_depth_map,
)
from datamodules import AirFisheyeDataModule
from datamodules.dataset import AirFisheyeDataset, CameraConfig
from tests.helpers.configs import compose_train


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
    check_common_values(cfg)
    datamodule = hydra.utils.instantiate(cfg.data, _convert_="partial")  # builds no dataset yet
    occlusion = datamodule.dataset_kwargs["occlusion"]
    assert isinstance(occlusion, Occlusion) and occlusion.method == method
    assert set(occlusion.options) == set(OCCLUSION_OPTIONS[method])  # the defaults fill in the rest
    given = OmegaConf.to_container(cfg.data.occlusion_options)
    assert {k: occlusion.options[k] for k in given} == given


@pytest.mark.parametrize(
    ("method", "options", "message"),
    [
        (
            "zbuffer",
            "{size:3}",
            r"data\.occlusion_options=\{'size': 3\}: unknown option\(s\) \['size'\].*zbuffer",
        ),
        ("hpr", "{radius:0.5}", r"data\.occlusion_options=\{'radius': 0\.5\}: radius must be a number > 1"),
        ("ordering", "{radius:100}", r"data\.occlusion_options=.*unknown option.*data\.occlusion=ordering"),
    ],
)
def test_bad_options_are_refused_by_the_schema_naming_the_key(
    method: str, options: str, message: str
) -> None:
    """The config's one check (``config_checks.RULES``); the datamodule does not repeat it."""
    cfg = compose_train(["task=completion", f"data.occlusion={method}", f"data.occlusion_options={options}"])
    with pytest.raises(ConfigError, match=message):
        check_common_values(cfg)


def test_a_library_caller_gets_the_constructor_check() -> None:
    """Built directly, the datamodule checks its arguments once (building the ``Occlusion`` its datasets take)."""
    with pytest.raises(ValueError, match=r"unknown option\(s\) \['size'\] for method 'zbuffer'"):
        AirFisheyeDataModule("completion", preset="tiny", occlusion="zbuffer", occlusion_options={"size": 3})
    with pytest.raises(ValueError, match=r"occlusion method must be one of .*'zbufer'"):
        AirFisheyeDataModule("completion", preset="tiny", occlusion="zbufer")


@pytest.mark.parametrize("method", OCCLUSION_METHODS)
def test_sparse_depth_follows_method_and_options(tiny_dataset: Path, method: str) -> None:
    options = {"ordering": {"elevation_tolerance": -0.25}, "zbuffer": {"kernel": 3}, "hpr": {"radius": 50.0}}
    options = options.get(method, {})
    ds = AirFisheyeDataset.from_root(
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
