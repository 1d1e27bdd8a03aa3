"""A virtual gimbal on the served camera (``data.gimbal``): the remap and the LiDAR turn together, draws are
reproducible, evaluation views are fixed."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry import CubemapToFisheye
from airfisheye_bench.geometry.gimbal import Gimbal
from airfisheye_bench.geometry.transforms import gimbal_rotation
from airfisheye_bench.io import DatasetReader
from datamodules import AirFisheyeDataModule, AirFisheyeDataset, CameraConfig

SIZE = 48


def _dataset(root: Path, task: str, gimbal, split: str = "train", **kwargs) -> AirFisheyeDataset:
    g = Gimbal.parse(gimbal)
    return AirFisheyeDataset.from_root(
        root,
        split,
        task,
        camera=CameraConfig(size=SIZE),
        gimbal=None if g is None else g.for_split(split == "train"),
        **kwargs,
    )


def test_a_fixed_view_is_the_rotated_remap(tiny_dataset: Path) -> None:
    ds = _dataset(tiny_dataset, "depth", [20, 30, 5])
    sid = ds.sample_ids[0]
    faces = DatasetReader(tiny_dataset).cubemap(sid, "depth")
    expected = CubemapToFisheye(ds.camera, ds.face_size, rotation=gimbal_rotation(20, 30, 5))(
        torch.from_numpy(faces)[:, None], "nearest"
    )
    sample = ds[0]
    torch.testing.assert_close(sample["depth"], ds._clip_depth(expected))
    assert not torch.equal(sample["depth"], _dataset(tiny_dataset, "depth", None)[0]["depth"])


def _sparse_vs_dense(sample: dict) -> float:
    """Median relative difference between the LiDAR's range and the dense range at the pixels it lands on."""
    sparse, dense = sample["sparse_depth"][0], sample["depth"][0]
    both = (sparse > 0) & (dense > 0)
    assert int(both.sum()) > 50
    return float(((sparse - dense).abs() / dense)[both].median())


@pytest.mark.parametrize("view", [[0, 40], [35, 25, 10]])
def test_the_lidar_turns_with_the_camera(tiny_dataset: Path, view: list[float]) -> None:
    turned = _dataset(tiny_dataset, "completion", view, occlusion="none")
    plain = _dataset(tiny_dataset, "completion", None, occlusion="none")
    for i in range(3):
        baseline = _sparse_vs_dense(plain[i])
        # Points land where the dense map has the same surface: as close as without the gimbal.
        assert _sparse_vs_dense(turned[i]) <= max(2 * baseline, 0.02)


def test_training_draws_follow_seed_epoch_and_index(tiny_dataset: Path) -> None:
    gimbal = {"yaw_deg": [-30, 30], "pitch_deg": [0, 45]}
    ds = _dataset(tiny_dataset, "seg", gimbal, seed=3)
    again = _dataset(tiny_dataset, "seg", gimbal, seed=3)
    views = [ds.sample_view(i) for i in range(len(ds))]
    assert views == [again.sample_view(i) for i in range(len(ds))]  # a resumed run serves the same views
    torch.testing.assert_close(ds[1]["image"], again[1]["image"])
    assert len(set(views)) > 1 and all(-30 <= y <= 30 and 0 <= p <= 45 for y, p, _ in views)
    ds.set_epoch(1)
    assert [ds.sample_view(i) for i in range(len(ds))] != views  # a new epoch, new draws
    other_seed = _dataset(tiny_dataset, "seg", gimbal, seed=4)
    assert [other_seed.sample_view(i) for i in range(len(ds))] != views


def test_evaluation_views_do_not_change_with_the_epoch(tiny_dataset: Path) -> None:
    ds = _dataset(tiny_dataset, "seg", {"pitch_deg": [0, 45]}, split="val")
    views = [ds.sample_view(i) for i in range(len(ds))]
    ds.set_epoch(5)
    assert [ds.sample_view(i) for i in range(len(ds))] == views
    assert views == [
        _dataset(tiny_dataset, "seg", {"pitch_deg": [0, 45]}, "val", seed=9).sample_view(i)
        for i in range(len(ds))
    ]


def test_the_datamodule_gives_training_draws_and_evaluation_fixed_views(tiny_dataset: Path) -> None:
    dm = AirFisheyeDataModule("seg", root=tiny_dataset, camera={"size": SIZE}, gimbal={"pitch_deg": [0, 45]})
    dm.setup("fit")
    train, val = dm.datasets["train"], dm.datasets["val"]
    assert train.gimbal.training and not val.gimbal.training
    sample = train[0]
    view = train.sample_view(0)
    assert torch.equal(sample["valid_mask"], train._remap_for(view).valid_mask)


def test_bad_gimbal_values_are_config_errors(tiny_dataset: Path) -> None:
    with pytest.raises(ConfigError, match=r"data.gimbal: pitch_deg=\[45, 0\]"):
        AirFisheyeDataModule("seg", root=tiny_dataset, gimbal={"pitch_deg": [45, 0]})
    with pytest.raises(ConfigError, match=r"needs data\.source=cubemap"):
        _dataset(tiny_dataset, "seg", [0, 30], source="fisheye")
