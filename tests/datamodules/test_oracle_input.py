"""``data.occlusion=oracle``: the generator's exact visibility as the sparse input, through the scan filtering."""

from __future__ import annotations

import shutil
from pathlib import Path

import hydra
import numpy as np
import pytest
import yaml

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.occlusion import ORACLE, SPARSE_INPUTS, lidar_depth_map
from datamodules.dataset import AirFisheyeDataset, CameraConfig
from tests.helpers.configs import compose_train


def _dataset(root: Path, occlusion: str, min_range: float = 0.5) -> AirFisheyeDataset:
    return AirFisheyeDataset.from_root(
        root,
        "val",
        "completion",
        camera=CameraConfig(size=64),
        occlusion=occlusion,
        lidar_min_range=min_range,
    )


def test_oracle_is_a_sparse_input_beside_the_methods() -> None:
    assert SPARSE_INPUTS[-1] == ORACLE and ORACLE not in SPARSE_INPUTS[:-1]
    cfg = compose_train(["task=completion", "data.occlusion=oracle"])
    datamodule = hydra.utils.instantiate(cfg.data, _convert_="partial")  # builds no dataset yet
    assert datamodule.dataset_kwargs["occlusion"] == ORACLE  # no Occlusion: the oracle is no method
    cfg = compose_train(["task=completion", "data.occlusion=oracle", "data.occlusion_options={kernel:3}"])
    with pytest.raises(Exception, match=r"data.occlusion_options \(data.occlusion=oracle\).*no options"):
        hydra.utils.instantiate(cfg.data, _convert_="partial")


def test_oracle_keeps_exactly_the_visible_points_after_the_filtering(tiny_dataset: Path) -> None:
    # tiny's val frames have hidden points at 10-110 m among returns at 6-120 m: a 20 m "self-hit" radius removes
    # a good part of the scan, so the visibility must be indexed with the same keep mask.
    ds = _dataset(tiny_dataset, ORACLE, min_range=20.0)
    index = 1
    sample_id = ds.sample_ids[index]
    points, rings, spec, keep = ds.filtered_scan(sample_id)
    assert not keep.all(), "the filter removes nothing here: the test would not see a misaligned index"
    visible = ds.reader.lidar_visible(sample_id)
    assert len(visible) == len(keep)
    expected = (
        lidar_depth_map(
            points[visible[keep]],
            ds.T_cam_lidar(sample_id),
            ds.camera,
            spec,
            "none",
            max_depth=ds.max_depth,
            rings=rings[visible[keep]],
        )
        * ds.valid_mask.numpy()
    )
    served = ds[index]["sparse_depth"][0].numpy()
    np.testing.assert_array_equal(served, expected)
    assert (served > 0).any()

    # The oracle only removes points of `none`: its pixels are a subset, each as far or farther.
    none = _dataset(tiny_dataset, "none", min_range=20.0)[index]["sparse_depth"][0].numpy()
    assert ((served > 0) <= (none > 0)).all()
    assert (served[served > 0] >= none[served > 0]).all()
    assert (~visible[keep]).any() and (none != served).any(), "the frame should have hidden points in view"


def test_oracle_is_refused_in_one_line_without_visibility(tiny_dataset: Path, tmp_path: Path) -> None:
    root = tmp_path / "no_visibility"
    shutil.copytree(tiny_dataset, root)
    meta = yaml.safe_load((root / "dataset.yaml").read_text())
    meta["contents"] = [c for c in meta["contents"] if c != "lidar_visible"]
    (root / "dataset.yaml").write_text(yaml.safe_dump(meta))
    with pytest.raises(ConfigError, match=r"^data.occlusion=oracle needs .*lidar_visible") as err:
        _dataset(root, ORACLE)
    assert "\n" not in str(err.value)
    _dataset(root, "none")  # the methods still work there
