"""The sample key ``rays`` (``data.camera_input=rays``): the ray map of the sample's lens over its pixels with data,
one shared tensor for a fixed lens, the drawn lens's for lenses drawn per sample, on every serving path."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.ray_maps import ray_map
from datamodules import AirFisheyeDataModule, AirFisheyeDataset, CameraConfig

SIZE = 32
LENSES = [{"model": "equidistant", "fov_deg": 190}, {"model": "kannala_brandt", "fov_deg": 180}]


def test_a_fixed_lens_serves_one_shared_ray_map(tiny_dataset: Path) -> None:
    ds = AirFisheyeDataset.from_root(
        tiny_dataset, "val", "depth", camera=CameraConfig(size=SIZE), camera_input="rays"
    )
    first, second = ds[0], ds[1]
    assert first["rays"] is second["rays"] is ds.ray_map  # no work per sample
    torch.testing.assert_close(first["rays"], ray_map(ds.camera, first["valid_mask"]))
    assert (
        "rays"
        not in AirFisheyeDataset.from_root(tiny_dataset, "val", "depth", camera=CameraConfig(size=SIZE))[0]
    )


def test_a_drawn_lens_serves_its_own_ray_map(tiny_dataset: Path) -> None:
    camera = CameraConfig(size=SIZE, lenses=LENSES, jitter={"focal": 0.05, "principal_point_px": 1.0})
    ds = AirFisheyeDataset.from_root(tiny_dataset, "train", "completion", camera=camera, camera_input="rays")
    maps = []
    for i in range(3):
        sample = ds[i]
        lens = ds.lens_camera(sample["lens"], sample["lens_params"])
        torch.testing.assert_close(sample["rays"], ray_map(lens, sample["valid_mask"]), msg=f"sample {i}")
        maps.append(sample["rays"])
    assert not torch.equal(maps[0], maps[1])  # two draws, two lenses


@pytest.mark.parametrize("remap_on", ["worker", "device"])
def test_the_datamodule_batches_the_ray_maps(tiny_dataset: Path, remap_on: str) -> None:
    data = AirFisheyeDataModule(
        "seg",
        root=tiny_dataset,
        camera={"size": SIZE},
        batch_size=2,
        num_workers=0,
        remap_on=remap_on,
        camera_input="rays",
    )
    data.setup("fit")
    batch = data.on_after_batch_transfer(next(iter(data.train_dataloader())), 0)
    assert batch["rays"].shape == (2, 4, SIZE, SIZE)
    # The training augmentation moves the image, not the lens's map: the map of the served camera.
    torch.testing.assert_close(batch["rays"][1], data.ray_map())
    torch.testing.assert_close(data.ray_map(), ray_map(data.camera, data.split_dataset("val").valid_mask))


def test_an_unknown_camera_input_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"data\.camera_input"):
        AirFisheyeDataModule("seg", camera_input="ray")
