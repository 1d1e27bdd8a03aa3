"""Lenses drawn per sample (``data.camera.lenses``, ``data.camera.jitter``): draws are reproducible in (seed, epoch,
index) and follow the weights, jitter stays on its grid, a drawn lens's sample is the sample of that lens served
alone, evaluation serves lens ``i mod n``, and what cannot be served is refused in one line."""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import pytest
import torch
from omegaconf import OmegaConf

import datamodules.serving_remaps as serving_remaps
from airfisheye_bench.config_checks import check_common_values
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry.cameras import KannalaBrandt
from airfisheye_bench.geometry.lens_draws import (
    DISTORTION_STEP,
    FOCAL_STEP,
    PRINCIPAL_POINT_STEP_PX,
    LensDraw,
    LensDraws,
    LensJitter,
)
from datamodules import AirFisheyeDataModule, AirFisheyeDataset, CameraConfig
from datamodules.dataset import collate
from tests.helpers.omni360_fixture import write_omni360_fixture

SIZE = 32
LENSES = [
    {"model": "equidistant", "fov_deg": 190},
    {"model": "kannala_brandt", "fov_deg": 180, "k": [0.0, 0.01, 0.0, 0.0], "weight": 3},
]
JITTER = {"focal": 0.05, "principal_point_px": 1.0, "distortion": 0.05}


def _dataset(
    root: Path, task: str = "completion", split: str = "train", seed: int = 0, **camera
) -> AirFisheyeDataset:
    config = CameraConfig(size=SIZE, **{"lenses": LENSES, "jitter": JITTER, **camera})
    return AirFisheyeDataset.from_root(root, split, task, camera=config, seed=seed, occlusion="none")


def test_training_draws_follow_seed_epoch_and_index(tiny_dataset: Path) -> None:
    ds, again = _dataset(tiny_dataset, seed=3), _dataset(tiny_dataset, seed=3)
    draws = [ds.sample_lens(i) for i in range(len(ds))]
    assert draws == [again.sample_lens(i) for i in range(len(ds))]
    assert len(set(draws)) == len(draws)  # jittered: every sample its own lens here
    ds.set_epoch(1)
    assert [ds.sample_lens(i) for i in range(len(ds))] != draws  # a new epoch, new draws
    again.set_epoch(1)
    torch.testing.assert_close(ds[2]["image"], again[2]["image"])  # a resumed process serves the same sample
    assert [_dataset(tiny_dataset, seed=4).sample_lens(i) for i in range(len(ds))] != draws


def test_a_pool_bounds_the_lenses_an_epoch_serves(tiny_dataset: Path) -> None:
    pooled = _dataset(tiny_dataset, seed=3, jitter={**JITTER, "pool": 2})
    epochs = []
    for epoch in (0, 1):
        pooled.set_epoch(epoch)
        draws = [pooled.sample_lens(i) for i in range(len(pooled))]
        assert 1 <= len(set(draws)) <= 2 and pooled._remap_count() == 2
        epochs.append(draws)
    assert set(epochs[0]) != set(epochs[1])  # each epoch its own pool
    again = _dataset(tiny_dataset, seed=3, jitter={**JITTER, "pool": 2})
    again.set_epoch(1)
    assert [again.sample_lens(i) for i in range(len(again))] == epochs[1]  # from (seed, epoch, index) alone
    with pytest.raises(ValueError, match=r"^data.camera.jitter.pool=0: expected null or a whole number"):
        LensJitter.parse({"pool": 0})


def test_weights_are_respected() -> None:
    draws = LensDraws(weights=(1.0, 3.0))
    counts = Counter(draws.draw(i, seed=i * 7919 + 1).lens for i in range(2000))
    assert abs(counts[1] / 2000 - 0.75) < 0.05
    assert {LensDraws(weights=(1.0, 1.0, 1.0)).draw(i, seed=i).lens for i in range(60)} == {0, 1, 2}


def test_jitter_stays_in_range_and_on_the_grid() -> None:
    draws = LensDraws((1.0,), LensJitter.parse(JITTER), distortion_counts=(4,))
    drawn = [draws.draw(i, seed=1000 + i) for i in range(500)]
    seen = [d.jitter for d in drawn]
    for d in seen:
        assert 0.95 - 1e-12 <= d.focal <= 1.05 + 1e-12
        assert math.isclose((d.focal - 1) / FOCAL_STEP, round((d.focal - 1) / FOCAL_STEP), abs_tol=1e-6)
        for shift in d.shift:
            assert abs(shift) <= 1.0 and (shift / PRINCIPAL_POINT_STEP_PX).is_integer()
        factors = d.distortion or (1.0,) * 4
        assert len(factors) == 4
        for f in factors:
            assert 0.95 - 1e-12 <= f <= 1.05 + 1e-12
            assert math.isclose((f - 1) / DISTORTION_STEP, round((f - 1) / DISTORTION_STEP), abs_tol=1e-6)
    # The whole range is used, ends included.
    assert min(d.focal for d in seen) == 0.95 and max(d.focal for d in seen) == 1.05
    # lens_params round-trips through float32 to the same grid point.
    d = drawn[0]
    assert LensDraw.from_params(d.lens, d.params(6), 4) == d
    # A range under one step does not jitter.
    assert LensDraws((1.0,), LensJitter(focal=0.001), (0,)).draw(3, seed=5) == LensDraw(0)


def test_perturbed_scales_only_the_declared_distortion() -> None:
    cam = KannalaBrandt(32, 32, 10.0, 11.0, 15.5, 15.5, k1=0.1, k2=0.02, skew=0.5)
    p = cam.perturbed(1.02, (0.5, -1.0), (1.1, 0.9, 1.05, 1.0))
    assert KannalaBrandt.distortion_params == ("k1", "k2", "k3", "k4")
    assert (p.fx, p.fy, p.cx, p.cy) == pytest.approx((10.2, 11.22, 16.0, 14.5))
    assert (p.k1, p.k2, p.k3, p.skew) == pytest.approx((0.11, 0.018, 0.0, 0.5))


def _fixed_to(root: Path, camera, task: str = "completion", split: str = "train") -> AirFisheyeDataset:
    """The split served through ``camera`` alone (its flat dict as a calibration: no list, no jitter)."""
    config = CameraConfig(size=SIZE, calibration=camera.to_dict())
    return AirFisheyeDataset.from_root(root, split, task, camera=config, occlusion="none")


@pytest.mark.parametrize("task", ["completion", "seg"])
def test_a_drawn_lens_serves_what_that_lens_serves_alone(tiny_dataset: Path, task: str) -> None:
    ds = _dataset(tiny_dataset, task)
    keys = ("image", "valid_mask", "depth", "sparse_depth") if task == "completion" else ("image", "label")
    for i in range(3):
        sample = ds[i]
        camera = ds.lens_camera(sample["lens"], sample["lens_params"])
        assert camera == ds._camera_of(ds.sample_lens(i))
        alone = _fixed_to(tiny_dataset, camera, task)[i]
        for key in keys:
            torch.testing.assert_close(sample[key], alone[key], msg=f"sample {i}: {key}")
        if task == "completion":
            assert int((sample["sparse_depth"] > 0).sum()) > 20  # the LiDAR lands through the drawn lens
    # Two draws are two lenses: their valid masks differ.
    masks = {tuple(ds[i]["valid_mask"].flatten().tolist()) for i in range(4)}
    assert len(masks) > 1


@pytest.mark.parametrize("jitter", [JITTER, None])
def test_the_paper_density_input_is_corrected_through_the_drawn_lens(tiny_dataset: Path, jitter) -> None:
    options = dict(occlusion="ordering", lidar_density="paper", seed=1)
    config = CameraConfig(size=SIZE, lenses=LENSES, jitter=jitter)
    ds = AirFisheyeDataset.from_root(tiny_dataset, "train", "completion", camera=config, **options)
    for i in range(2):
        sample = ds[i]
        camera = ds.lens_camera(sample["lens"], sample["lens_params"])
        fixed = CameraConfig(size=SIZE, calibration=camera.to_dict())
        alone = AirFisheyeDataset.from_root(tiny_dataset, "train", "completion", camera=fixed, **options)[i]
        torch.testing.assert_close(sample["sparse_depth"], alone["sparse_depth"])
        torch.testing.assert_close(
            ds[i]["sparse_depth"], sample["sparse_depth"]
        )  # again: a cached mask, if any


def test_an_equirect_source_serves_the_drawn_lens(tmp_path: Path) -> None:
    root = write_omni360_fixture(tmp_path / "root", height=32, frames=3)

    def split(camera: CameraConfig) -> AirFisheyeDataset:
        options = {"scenes": ["NYC"]}
        return AirFisheyeDataset.from_root(
            root, "train", "depth", format="omni360", format_options=options, source="equirect", camera=camera
        )

    ds = split(CameraConfig(size=SIZE, lenses=LENSES, jitter=JITTER))
    sample = ds[0]
    camera = ds.lens_camera(sample["lens"], sample["lens_params"])
    assert camera != ds.camera
    alone = split(CameraConfig(size=SIZE, calibration=camera.to_dict()))[0]
    torch.testing.assert_close(sample["depth"], alone["depth"])
    torch.testing.assert_close(sample["valid_mask"], alone["valid_mask"])


def test_evaluation_serves_lens_i_mod_n_unjittered(tiny_dataset: Path) -> None:
    lenses = [*LENSES, {"model": "equisolid", "fov_deg": 170}]
    ds = _dataset(tiny_dataset, split="val", lenses=lenses)
    draws = [ds.sample_lens(i) for i in range(len(ds))]
    assert draws == [LensDraw(i % 3) for i in range(len(ds))]
    ds.set_epoch(4)
    assert [ds.sample_lens(i) for i in range(len(ds))] == draws
    sample = ds[1]
    assert int(sample["lens"]) == 1 and torch.equal(sample["lens_params"], LensDraw(1).params(4))
    fixed = CameraConfig(size=SIZE, model="kannala_brandt", fov_deg=180, k=(0.0, 0.01, 0.0, 0.0))
    alone = AirFisheyeDataset.from_root(tiny_dataset, "val", "completion", camera=fixed, occlusion="none")[1]
    for key in ("image", "valid_mask", "depth", "sparse_depth"):
        torch.testing.assert_close(sample[key], alone[key])


def test_a_calibrated_lens_of_the_list_keeps_its_padded_bands(tiny_dataset: Path, tmp_path: Path) -> None:
    woodscape = {"model": "radial_poly", "width": 1280, "height": 966, "k1": 339.749, "k2": -31.988,
                 "k3": 48.275, "k4": -7.201, "cx": 643.442, "cy": 479.407, "aspect_ratio": 1.0}  # fmt: skip
    lenses = [LENSES[0], {"calibration": woodscape}]
    ds = _dataset(tiny_dataset, "depth", split="val", lenses=lenses)
    sample = ds[1]
    alone = AirFisheyeDataset.from_root(
        tiny_dataset, "val", "depth", camera=CameraConfig(size=SIZE, calibration=woodscape)
    )[1]
    for key in ("image", "valid_mask", "depth"):
        torch.testing.assert_close(sample[key], alone[key])
    assert not sample["valid_mask"][0].any()  # the band above the 1280x966 sensor
    assert ds[0]["valid_mask"][0].any() or ds[0]["valid_mask"][:, 0].any()  # lens 0 has no band there
    missing = tmp_path / "nope.yaml"
    with pytest.raises(ConfigError, match=r"data.camera.lenses\[1\].calibration: .*nope.yaml"):
        AirFisheyeDataModule(
            "seg", root=tiny_dataset, camera={"lenses": [LENSES[0], {"calibration": str(missing)}]}
        )


def test_the_datamodule_resumes_the_same_draws(tiny_dataset: Path) -> None:
    kwargs = dict(
        root=tiny_dataset,
        camera={"size": SIZE, "lenses": LENSES, "jitter": JITTER},
        batch_size=2,
        num_workers=0,
        augment=None,
    )
    run = AirFisheyeDataModule("depth", **kwargs)
    run.setup("fit")
    loader = run.train_dataloader()
    loader.sampler.set_epoch(2)  # what the trainer and the task do at the start of epoch 2
    run.set_epoch(2)
    uninterrupted = list(loader)
    resumed = AirFisheyeDataModule("depth", **kwargs)
    resumed.load_state_dict({"train_epoch": 2, "train_batches_done": 1})
    resumed.setup("fit")
    batches = list(resumed.train_dataloader())
    assert len(batches) == len(uninterrupted) - 1
    for a, b in zip(batches, uninterrupted[1:], strict=True):
        assert a["sample_id"] == b["sample_id"]
        assert torch.equal(a["lens"], b["lens"]) and torch.equal(a["lens_params"], b["lens_params"])
        torch.testing.assert_close(a["depth"], b["depth"])
    assert batches[0]["lens_params"].shape == (2, 3 + 4)
    # Validation: fixed lenses, every epoch.
    val = run.datasets["val"]
    assert [val.sample_lens(i).lens for i in range(len(val))] == [i % 2 for i in range(len(val))]


def test_the_cache_of_remaps_stays_bounded(tiny_dataset: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    per_remap = _dataset(tiny_dataset, "depth")._remap_bytes()
    monkeypatch.setattr(serving_remaps, "GIMBAL_TABLE_BUDGET_BYTES", 3 * per_remap)
    ds = _dataset(tiny_dataset, "depth")
    ds.warm_up()  # far more grid points than fit: none built ahead, a cache of what fits
    assert ds._remaps.maxsize == 4 and len(ds._remaps) == 0
    for epoch in range(3):
        ds.set_epoch(epoch)
        for i in range(len(ds)):
            ds[i]
    assert len(ds._remaps) <= 4


def test_a_list_of_unjittered_lenses_is_built_ahead(tiny_dataset: Path) -> None:
    ds = _dataset(tiny_dataset, "seg", jitter=None)
    ds.warm_up()
    built = {key for key in ds._remaps._items}
    assert {draw for _, draw in built} == {LensDraw(0), LensDraw(1)}
    batch = collate([ds[i] for i in range(3)])
    assert batch["lens"].dtype == torch.int64 and batch["lens_params"].shape == (3, 3 + 4)


def test_what_cannot_be_served_is_refused_in_one_line(tiny_dataset: Path) -> None:
    with pytest.raises(
        ConfigError, match=r"data.camera.lenses / data.camera.jitter .* need data.source=cubemap"
    ):
        AirFisheyeDataset.from_root(
            tiny_dataset, "train", "seg", source="fisheye", camera=CameraConfig(size=SIZE, jitter=JITTER)
        )
    bad = [LENSES[0], {"model": "equidistant", "fov_deg": 400}]
    with pytest.raises(ConfigError, match=r"data.camera.lenses\[1\].fov_deg=400"):
        AirFisheyeDataModule("seg", root=tiny_dataset, camera={"lenses": bad})
    with pytest.raises(ConfigError, match=r"data.camera.lenses\[0\]: unknown key 'fov'"):
        AirFisheyeDataModule(
            "seg", root=tiny_dataset, camera={"lenses": [{"model": "equidistant", "fov": 1}]}
        )
    with pytest.raises(ConfigError, match=r"data.camera.jitter.focal=2"):
        AirFisheyeDataModule("seg", root=tiny_dataset, camera={"jitter": {"focal": 2}})
    with pytest.raises(ConfigError, match=r"drop data.camera.model"):
        AirFisheyeDataModule("seg", root=tiny_dataset, camera={"lenses": LENSES, "model": "equisolid"})
    dm = AirFisheyeDataModule(
        "seg", root=tiny_dataset, camera={"size": SIZE, "lenses": LENSES}, remap_on="device"
    )
    with pytest.raises(ConfigError, match=r"data.remap_on=device: data.camera.lenses / jitter"):
        dm.setup("fit")


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (
            {"source": "fisheye", "camera": {"lenses": [{"model": "equidistant", "fov_deg": 190}]}},
            r"^data.camera.lenses=.*: needs data.source=cubemap or equirect",
        ),
        (
            {"camera": {"lenses": [{"model": "equidistant"}, {"model": "fisheye62"}]}},
            r"^data.camera.lenses=.*: lenses\[1\].model='fisheye62': expected one of",
        ),
        ({"camera": {"jitter": {"focal": 0.1, "zoom": 1}}}, r"^data.camera.jitter=.*: unknown key 'zoom'"),
        (
            {"source": "fisheye", "camera": {"jitter": {"focal": 0.1}}},
            r"^data.camera.jitter=.*: needs data.source",
        ),
    ],
)
def test_the_config_check_names_the_lens_and_key(data: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as err:
        check_common_values(OmegaConf.create({"data": data}))
    assert "\n" not in str(err.value)
    check_common_values(OmegaConf.create({"data": {"camera": {"lenses": LENSES, "jitter": JITTER}}}))
