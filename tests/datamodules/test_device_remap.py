"""``data.remap_on=device``: the batch finished on the device is the batch the workers would have served."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf, open_dict

from airfisheye_bench.config_checks import check_common_values
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.gimbal import Gimbal
from airfisheye_bench.io import DatasetFormatError
from airfisheye_bench.io.dataset_spec import remap_site_problem
from airfisheye_bench.training import train
from datamodules import AirFisheyeDataModule, AirFisheyeDataset, CameraConfig, FisheyeAugment, collate
from datamodules.augment import AugmentParams, augment_sample
from datamodules.augment_batch import augment_batch, pack_params
from datamodules.device_remap import CUBE_KEYS, CubeFaces, DeviceRemap
from tests.helpers.configs import compose_train
from tests.helpers.runs import tiny_run_overrides

AUGMENTS = {
    "none": None,
    "flip+rotate+jitter": FisheyeAugment(hflip=1.0, rotate_deg=10.0),
    "paper (flip 0.5, jitter)": FisheyeAugment(),
}


def assert_same_batch(device: dict, worker: dict) -> None:
    """Labels and masks exactly; RGB and depth within 1e-5 of the value (relative to the map's scale)."""
    assert set(device) == set(worker)
    for key, expected in worker.items():
        got = device[key]
        if not isinstance(expected, torch.Tensor):
            assert got == expected, key
            continue
        assert got.dtype == expected.dtype and got.shape == expected.shape, key
        if expected.dtype.is_floating_point:
            scale = float(expected.abs().max()) or 1.0
            torch.testing.assert_close(got, expected, rtol=1e-5, atol=1e-5 * scale, msg=key)
        else:
            assert torch.equal(got, expected), f"{key}: {int((got != expected).sum())} values differ"


@pytest.mark.parametrize("augment", AUGMENTS, ids=list(AUGMENTS))
@pytest.mark.parametrize("task", ["seg", "depth", "completion"])
def test_device_batch_is_worker_batch(tiny_dataset: Path, task: str, augment: str) -> None:
    ds = AirFisheyeDataset.from_root(
        tiny_dataset, "train", task, camera=CameraConfig(size=64), augment=AUGMENTS[augment], seed=5
    )
    worker = collate([ds[i] for i in range(len(ds))])
    faces = collate([ds.load_faces(i) for i in range(len(ds))])
    assert CUBE_KEYS["rgb"] in faces and "image" not in faces
    assert_same_batch(ds.device_remap()(faces), worker)


def test_augment_batch_is_the_kernel() -> None:
    """Off-centre principal point, border taps, rotation and jitter: the batched torch version is the CPU kernel."""
    g = torch.Generator().manual_seed(0)
    h, w, cx, cy = 23, 31, 14.3, 10.9
    rgb = torch.randint(0, 256, (2, 3, h, w), generator=g, dtype=torch.uint8)
    valid = torch.rand(h, w, generator=g) > 0.1
    maps = torch.randint(0, 13, (2, 2, h, w), generator=g).float()
    draws = [AugmentParams(True, 0.31, (1.1, 0.8, 1.2, 0.04)), AugmentParams(False, -0.2, None)]
    image, moved, moved_maps = augment_batch(
        rgb, valid, maps, [255.0, 0.0], torch.stack([pack_params(p) for p in draws]), cx, cy
    )
    for i, params in enumerate(draws):
        ref_image, ref_moved, ref_maps = augment_sample(rgb[i], valid, maps[i], [255.0, 0.0], params, cx, cy)
        assert torch.equal(moved[i], ref_moved) and torch.equal(moved_maps[i], ref_maps)
        torch.testing.assert_close(image[i], ref_image, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("task", ["seg", "completion"])
def test_datamodule_finishes_the_batch_after_transfer(tiny_dataset: Path, task: str) -> None:
    """The loaders serve faces; ``on_after_batch_transfer`` (what Lightning calls) gives the worker path's batch."""
    common = dict(root=tiny_dataset, camera={"size": 64}, batch_size=3, augment={"hflip": 0.5}, seed=2)
    batches = {}
    for where in ("worker", "device"):
        dm = AirFisheyeDataModule(task, remap_on=where, **common)
        dm.setup("fit")
        loader = dm.train_dataloader()
        assert isinstance(loader.dataset, CubeFaces) == (where == "device")
        batches[where] = dm.on_after_batch_transfer(next(iter(loader)), 0)
    assert_same_batch(batches["device"], batches["worker"])
    dm.setup("validate")
    val = dm.on_after_batch_transfer(next(iter(dm.val_dataloader())), 0)
    assert val["image"].shape[1:] == (3, 64, 64) and CUBE_KEYS["rgb"] not in val


def test_a_fixed_gimbal_view_is_served_and_varying_views_are_refused(tiny_dataset: Path) -> None:
    """One view per split: its rotated tables on the device, the LiDAR turned with it in the worker."""
    common = dict(root=tiny_dataset, camera={"size": 64}, batch_size=3, augment={"hflip": 0.5}, seed=1)
    batches = {}
    for where in ("worker", "device"):
        dm = AirFisheyeDataModule("completion", remap_on=where, gimbal=[10.0, 20.0], **common)
        dm.setup("fit")
        batches[where] = dm.on_after_batch_transfer(next(iter(dm.train_dataloader())), 0)
    assert_same_batch(batches["device"], batches["worker"])
    with pytest.raises(
        ConfigError, match=r"data\.gimbal turns the samples of a split to views of their own"
    ) as err:
        AirFisheyeDataModule("seg", remap_on="device", gimbal={"pitch_deg": [0, 45]}, **common)
    assert "\n" not in str(err.value)
    # A library caller's dataset refuses it too.
    ds = AirFisheyeDataset.from_root(tiny_dataset, "train", "seg", gimbal=Gimbal.parse([[0, 10], [0, 20]]))
    with pytest.raises(ConfigError, match="through a view per sample"):
        ds.device_remap()


def test_file_checks_stay_in_the_worker(tiny_dataset: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """An unknown raw label id fails the frame in the worker when the fisheye sees it, as on the worker path."""
    ds = AirFisheyeDataset.from_root(tiny_dataset, "train", "seg", camera=CameraConfig(size=64))
    read = ds.reader.cubemap
    seen = int(ds._seen_texels[len(ds._seen_texels) // 2])
    unseen = int(np.setdiff1d(np.arange(5 * ds.face_size**2), ds._seen_texels)[0])

    def corrupt(texel: int):
        def cubemap(sample_id: str, modality: str) -> np.ndarray:
            faces = read(sample_id, modality)
            if modality == "seg":
                faces = faces.copy()
                faces.reshape(-1)[texel] = 200  # no raw class of the tiny preset
            return faces

        return cubemap

    monkeypatch.setattr(ds.reader, "cubemap", corrupt(unseen))
    ds.load_faces(0)
    ds[0]
    monkeypatch.setattr(ds.reader, "cubemap", corrupt(seen))
    for load in (ds.load_faces, ds.__getitem__):
        with pytest.raises(DatasetFormatError, match=r"label ids \[200\]"):
            load(0)


def test_refused_combinations(tiny_dataset: Path) -> None:
    with pytest.raises(ConfigError, match=r"data\.source=fisheye has no cube faces") as err:
        AirFisheyeDataModule("seg", root=tiny_dataset, source="fisheye", remap_on="device")
    assert "\n" not in str(err.value)
    assert remap_site_problem("device", "equirect") == (
        "data.source=equirect: the device remaps cube faces only; use data.remap_on=worker"
    )
    with pytest.raises(ConfigError, match="expected one of worker, device"):
        AirFisheyeDataModule("seg", root=tiny_dataset, remap_on="gpu")
    cfg = OmegaConf.create({"data": {"source": "fisheye", "remap_on": "device"}})
    with pytest.raises(ConfigError, match=r"^data.remap_on='device': data.source=fisheye has no cube faces"):
        check_common_values(cfg)
    with open_dict(cfg):
        cfg.data.source = "cubemap"
    check_common_values(cfg)


@pytest.mark.integration
def test_trainer_calls_the_hook(tiny_dataset: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A debug run with ``remap_on=device``: Lightning hands the task finished batches (train, val and test)."""
    finished: list[int] = []
    finish = DeviceRemap.__call__

    def counted(self: DeviceRemap, batch: dict) -> dict:
        out = finish(self, batch)
        finished.append(int(out["image"].shape[0]))
        return out

    monkeypatch.setattr(DeviceRemap, "__call__", counted)
    cfg = compose_train([*tiny_run_overrides("seg", tiny_dataset), "data.remap_on=device"])
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path / "run")
    returned = train(cfg)
    assert "mIoU" in returned["metrics"]
    assert len(finished) >= 4 and all(finished)  # two training batches, one validation, one test
