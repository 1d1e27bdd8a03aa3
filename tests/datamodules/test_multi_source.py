"""Several datasets in one run (``data.sources``): names, mistakes, the concatenation, classes, sampling, resume."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
import yaml

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.io import EmptySplitError
from airfisheye_bench.studies import multi_source_cost
from airfisheye_bench.studies.bench_record import tables as bench_tables
from airfisheye_bench.synth.cache import cached_dataset_path
from datamodules import AirFisheyeDataModule
from datamodules.multi_source import SourceMixtureSampler
from datamodules.sampling import EpochSeededSampler, draw_seed
from datamodules.sources import resolve_sources
from tests.helpers.woodscape_fixture import write_woodscape


def _datamodule(sources: list[str], options: dict, **kwargs) -> AirFisheyeDataModule:
    base = dict(
        camera={"size": 32}, batch_size=2, eval_batch_size=4, augment={"hflip": 0.5, "rotate_deg": 10.0}
    )
    return AirFisheyeDataModule("seg", sources=sources, source_options=options, **(base | kwargs))


def test_a_source_name_means_a_preset_a_format_or_what_its_options_say(tmp_path: Path) -> None:
    defaults = {"format": "airfisheye", "root": str(tmp_path), "preset": "quickstart", "dataset_seed": 3}
    options = {"mine": {"root": str(tmp_path)}, "tiny2": {"preset": "tiny", "dataset_seed": 1, "weight": 2}}
    names = ["synthetic", "tiny", "airfisheye", "mine", "tiny2"]
    options["synthetic"] = {"weight": 1}
    options |= {n: {**options.get(n, {}), "weight": 1} for n in ("tiny", "airfisheye", "mine")}
    got = {s.name: s for s in resolve_sources(names, options, defaults)}
    assert (got["synthetic"].preset, got["synthetic"].root, got["synthetic"].dataset_seed) == (
        "quickstart",
        None,
        3,
    )
    assert (got["tiny"].preset, got["tiny"].root) == ("tiny", None)
    # A format's name reads data.root when data.format is that format.
    assert (got["airfisheye"].format, got["airfisheye"].root, got["airfisheye"].preset) == (
        "airfisheye",
        str(tmp_path),
        None,
    )
    assert (got["mine"].root, got["mine"].preset) == (str(tmp_path), None)
    assert (got["tiny2"].preset, got["tiny2"].dataset_seed, got["tiny2"].weight) == ("tiny", 1, 2.0)
    assert resolve_sources(None, None) == () and resolve_sources([], {}) == ()
    # A data config without a preset (data=tartanair): synthetic is the default preset.
    assert (
        resolve_sources(["synthetic"], None, {"format": "tartanair", "preset": None})[0].preset
        == "quickstart"
    )


@pytest.mark.parametrize(
    ("names", "options", "message"),
    [
        (["tiny", "mystery"], {}, r"data\.sources: unknown source name 'mystery'"),
        (["tiny", "tiny"], {}, r"data\.sources lists \['tiny'\] more than once"),
        (["tiny"], {"tinny": {"dataset_seed": 1}}, r"data\.source_options\.tinny: no source 'tinny'"),
        (["tiny"], {"tiny": {"seed": 1}}, r"data\.source_options\.tiny\.seed: unknown setting"),
        (
            ["tiny", "quickstart"],
            {"tiny": {"weight": 2}},
            r"data\.source_options\.quickstart\.weight is unset",
        ),
        (["tiny"], {"tiny": {"weight": -1}}, r"data\.source_options\.tiny\.weight=-1"),
        (["ring_0-30"], {"ring_0-30": {"preset": "tiny"}}, r"'ring_0-30' is not a source name"),
        (
            ["mine"],
            {"mine": {"root": "/nowhere/at/all"}},
            r"data\.source_options\.mine\.root='/nowhere/at/all'",
        ),
        (["mine"], {"mine": {"preset": "tiniest"}}, r"data\.source_options\.mine\.preset='tiniest'"),
        (["mine"], {"mine": {"preset": "tiny", "source": "pinhole"}}, r"data\.source_options\.mine\.source"),
        ("tiny", {}, r"data\.sources='tiny': expected a list"),
    ],
)
def test_a_mistake_is_one_config_error_naming_the_key(names, options, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        resolve_sources(names, options, {"preset": "quickstart"})


def test_sources_are_concatenated_with_their_names(tiny_dataset: Path, tiny_dataset_seed1: Path) -> None:
    dm = _datamodule(["a", "b"], {"a": {"root": str(tiny_dataset)}, "b": {"root": str(tiny_dataset_seed1)}})
    single = AirFisheyeDataModule("seg", root=tiny_dataset_seed1, camera={"size": 32})
    test, alone = dm.split_dataset("test"), single.split_dataset("test")
    assert test.sizes == [2, 2] and len(test) == 4
    assert test.sample_ids[2:] == [f"b/{s}" for s in alone.sample_ids]
    sample = test[2]  # the first frame of b: b's own frame, named after its source
    assert sample["source"] == "b" and sample["sample_id"] == f"b/{alone.sample_ids[0]}"
    assert torch.equal(sample["image"], alone[0]["image"]) and torch.equal(sample["label"], alone[0]["label"])
    batch = next(iter(dm.test_dataloader()))
    assert batch["source"] == ["a", "a", "b", "b"]
    assert dm.class_names == single.class_names and dm.num_classes == 13
    assert dm.source_names == ["a", "b"] and dm.camera_of("b").width == 32


def _renamed_classes(original: Path, out: Path) -> Path:
    """``original`` with its training classes renamed (vehicle -> car, roof -> rooftop): a dataset with other
    classes than the benchmark's. Frames are shared through symbolic links."""
    out.mkdir()
    for item in original.iterdir():
        if item.name != "dataset.yaml":
            (out / item.name).symlink_to(item)
    spec = yaml.safe_load((original / "dataset.yaml").read_text())
    renamed = {"vehicle": "car", "roof": "rooftop"}
    for cls in spec["classes"]["train"]:
        cls["name"] = renamed.get(cls["name"], cls["name"])
    (out / "dataset.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    return out


def test_a_source_with_other_classes_maps_them_or_is_refused(tiny_dataset: Path, tmp_path: Path) -> None:
    other = _renamed_classes(tiny_dataset, tmp_path / "renamed")
    names = AirFisheyeDataModule("seg", root=other, camera={"size": 32}).class_names
    assert "car" in names and "rooftop" in names
    with pytest.raises(ConfigError, match=r"data\.source_options\.other\.class_map is needed: source other"):
        _datamodule(["a", "other"], {"a": {"root": str(tiny_dataset)}, "other": {"root": str(other)}}).setup(
            "test"
        )
    incomplete = {"root": str(other), "class_map": {"car": "vehicle"}}
    with pytest.raises(ConfigError, match=r"data\.source_options\.other\.class_map misses its classes"):
        _datamodule(["other"], {"other": incomplete}).setup("test")
    wrong = {"root": str(other), "class_map": {n: "lorry" for n in names}}
    with pytest.raises(ConfigError, match=r"maps to \['lorry'\], not benchmark classes"):
        _datamodule(["other"], {"other": wrong}).setup("test")
    # car -> vehicle keeps those pixels; rooftop -> null ignores them.
    class_map = {n: {"car": "vehicle", "rooftop": None}.get(n, n) for n in names}
    dm = _datamodule(
        ["a", "other"],
        {"a": {"root": str(tiny_dataset)}, "other": {"root": str(other), "class_map": class_map}},
    )
    test = dm.split_dataset("test")
    original, mapped = test[0]["label"], test[2]["label"]  # the same frame through both sources
    roof = dm.class_names.index("roof")
    assert (original == roof).any()  # the frame has pixels the map ignores
    assert torch.equal(mapped, original.masked_fill(original == roof, 255))


def test_weights_set_the_share_of_each_source_in_an_epoch() -> None:
    sampler = SourceMixtureSampler([4, 40], [1.0, 1.0], seed=7, num_replicas=1, rank=0)
    sampler.set_epoch(3)
    order = list(sampler)
    assert len(order) == 44 and sum(i < 4 for i in order) == 22  # the small source repeats to half the draws
    assert sorted(set(i for i in order if i < 4)) == [0, 1, 2, 3]
    assert list(sampler) == order  # a function of (seed, epoch) only
    sampler.set_epoch(4)
    assert list(sampler) != order


def test_the_unweighted_order_is_the_single_dataset_one() -> None:
    sampler = EpochSeededSampler(10, seed=3, num_replicas=1, rank=0)
    sampler.set_epoch(2)
    generator = torch.Generator().manual_seed(draw_seed(3, 2, -1))
    assert list(sampler) == torch.randperm(10, generator=generator).tolist()


@pytest.mark.parametrize("weights", [None, (3.0, 1.0)])
def test_a_mixture_resumes_mid_epoch_at_the_same_batch(
    tiny_dataset: Path, tiny_dataset_seed1: Path, weights
) -> None:
    options = {"a": {"root": str(tiny_dataset)}, "b": {"root": str(tiny_dataset_seed1)}}
    if weights is not None:
        options = {n: {**o, "weight": w} for (n, o), w in zip(options.items(), weights, strict=True)}
    uninterrupted = _datamodule(["a", "b"], options)
    loader = uninterrupted.train_dataloader()
    loader.sampler.set_epoch(1)
    uninterrupted.set_epoch(1)
    full = list(loader)
    assert len(full) == 8  # 16 training frames, batches of 2
    if weights is not None:  # a: 12 of the 16 draws
        assert sum(s == "a" for b in full for s in b["source"]) == 12
    resumed = _datamodule(["a", "b"], options)
    resumed.load_state_dict({"train_epoch": 1, "train_batches_done": 3})
    rest = list(resumed.train_dataloader())
    assert [b["sample_id"] for b in rest] == [b["sample_id"] for b in full[3:]]
    assert all(torch.equal(x["image"], y["image"]) for x, y in zip(rest, full[3:], strict=True))


def test_two_synthetic_sources_differ_by_their_dataset_seed(
    tiny_dataset: Path, tiny_dataset_seed1: Path, tmp_path: Path
) -> None:
    # The cache holds both seeds where ensure_dataset looks for them (linked: nothing is generated here).
    cached_dataset_path("tiny", tmp_path, 0).symlink_to(tiny_dataset)
    cached_dataset_path("tiny", tmp_path, 1).symlink_to(tiny_dataset_seed1)
    dm = _datamodule(
        ["tiny", "tiny_b"], {"tiny_b": {"preset": "tiny", "dataset_seed": 1}}, cache_dir=tmp_path
    )
    dm.prepare_data()
    assert dm.source_roots() == {
        "tiny": cached_dataset_path("tiny", tmp_path, 0),
        "tiny_b": cached_dataset_path("tiny", tmp_path, 1),
    }
    test = dm.split_dataset("test")
    seed1 = AirFisheyeDataModule("seg", root=tiny_dataset_seed1, camera={"size": 32}).split_dataset("test")
    assert torch.equal(test[2]["image"], seed1[0]["image"]) and not torch.equal(
        test[0]["image"], test[2]["image"]
    )


def test_the_benchmark_script_compares_one_source_with_two(tiny_dataset: Path, capsys) -> None:
    multi_source_cost.main(
        ["--root", str(tiny_dataset), "--size", "32", "--samples", "2", "--repeats", "1", "--batch", "2"]
    )
    (table,) = bench_tables(capsys.readouterr().out)  # one markdown table: header, separator, rows
    rows = table[2:]
    assert table[0] == "| step | sources | ms (CPU, min) | ms (CPU, median) |"
    assert len(rows) == 5 and sum("| two sources |" in r for r in rows) == 2 and "| pool: add |" in rows[-1]


def test_an_empty_split_of_a_source_names_the_root_and_the_source(tiny_dataset: Path, tmp_path: Path) -> None:
    ws = tmp_path / "woodscape"
    for folder in ("rgb_images", "semantic_annotations/gtLabels", "calibration"):
        (ws / folder).mkdir(parents=True)
    woodscape = {"root": str(ws), "source": "fisheye", "format_options": {"classes": "benchmark"}}
    dm = _datamodule(["a", "woodscape"], {"a": {"root": str(tiny_dataset)}, "woodscape": woodscape})
    with pytest.raises(
        EmptySplitError, match=r"split 'train' is empty .*\(data\.sources: source woodscape"
    ) as info:
        dm.setup("fit")
    assert str(info.value).startswith(f"{ws}: ")


def test_a_4x3_fisheye_source_is_padded_to_the_common_square(tiny_dataset: Path, tmp_path: Path) -> None:
    """WoodScape (recorded 4:3 fisheye frames, its own lens and classes) beside the synthetic data at 32^2."""
    ws = write_woodscape(tmp_path / "woodscape")
    woodscape = {"root": str(ws), "source": "fisheye", "splits": ["train", "val", "val"]}
    options = {"a": {"root": str(tiny_dataset)}, "woodscape": woodscape}
    with pytest.raises(ConfigError, match=r"data\.source_options\.woodscape\.class_map is needed"):
        _datamodule(["a", "woodscape"], options).setup("test")  # its own 10 classes
    woodscape["format_options"] = {"classes": "benchmark"}  # the source maps them onto the benchmark's
    dm = _datamodule(["a", "woodscape"], options, camera_input="rays")
    alone = AirFisheyeDataModule(
        "seg",
        root=ws,
        format="woodscape",
        source="fisheye",
        camera={"size": 32},
        format_options={"classes": "benchmark"},
        camera_input="rays",
    ).split_dataset("val")
    assert (alone.camera.width, alone.camera.height) == (32, 24)
    test = dm.split_dataset("test")
    mixed, own = test[test.sizes[0]], alone[0]  # the first WoodScape frame, both ways
    assert mixed["image"].shape == (3, 32, 32) and mixed["label"].shape == (32, 32)
    assert torch.equal(mixed["image"][:, 4:28], own["image"]) and torch.equal(
        mixed["label"][4:28], own["label"]
    )
    assert torch.equal(mixed["valid_mask"][4:28], own["valid_mask"]) and not mixed["valid_mask"][:4].any()
    assert (mixed["label"][:4] == 255).all() and not mixed["valid_mask"][28:].any()
    # Its lens's ray map, padded as the other maps: no ray in the bands.
    assert torch.equal(mixed["rays"][:, 4:28], own["rays"]) and not mixed["rays"][:, :4].any()
    assert torch.equal(test[0]["rays"], dm.ray_map())  # the run's camera: the first source's
    # The padded camera sees through row r + 4 what the source's own camera sees through row r.
    padded = dm.camera_of("woodscape")
    assert (padded.width, padded.height) == (32, 32) and padded.cy == pytest.approx(alone.camera.cy + 4)
    theta, theta_own = padded.theta_grid(), alone.camera.theta_grid()
    assert torch.allclose(theta[4:28], theta_own, atol=1e-6, equal_nan=True)
    batch = next(iter(dm.test_dataloader()))
    assert batch["image"].shape[-2:] == (32, 32) and batch["source"][-1] == "woodscape"
