"""A run on several datasets (``data.sources``): composed by Hydra, trained, scored per source, on the board."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from omegaconf import open_dict

from airfisheye_bench.config_checks import check_train_config
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.evaluation import command
from airfisheye_bench.evaluation.command import evaluate
from airfisheye_bench.evaluation.leaderboard import collect_results
from airfisheye_bench.studies.miniature_datasets.tartanair import write_tartanair_fixture
from airfisheye_bench.training import check_sources, train
from tests.helpers.commands import TRAIN, assert_one_line_error, run_in_process
from tests.helpers.configs import compose_eval, compose_train
from tests.helpers.runs import tiny_run_overrides

pytestmark = pytest.mark.integration  # trains, evaluates or exports: seconds per test


def _overrides(root: Path, other: Path, *extra: str) -> list[str]:
    """The tiny run on the synthetic ``tiny`` preset plus an AirFisheye-format root (``other``)."""
    base = [o for o in tiny_run_overrides("seg", root) if not o.startswith("data.root=")]
    return [*base, "data.sources=[tiny,other]", f"data.source_options={{other:{{root:'{other}'}}}}", *extra]


def _check(cfg) -> None:
    """What the training command checks before it writes anything."""
    check_train_config(cfg)
    check_sources(cfg.data)


def test_sources_compose_from_the_command_line(tiny_dataset: Path, tmp_path: Path) -> None:
    cfg = compose_train(_overrides(tiny_dataset, tiny_dataset, "data.preset=quickstart"))
    assert list(cfg.data.sources) == ["tiny", "other"] and cfg.data.source_options.other.root == str(
        tiny_dataset
    )
    _check(cfg)
    cfg = compose_train(
        ["task=seg", "data.sources=[tiny,quickstart]", "data.source_options={quickstart:{weight:2}}"]
    )
    with pytest.raises(ConfigError, match=r"data\.source_options\.tiny\.weight is unset"):
        _check(cfg)
    # A real-data config with no root of its own: its sources carry the locations.
    cfg = compose_train(
        [
            "task=seg",
            "data=airfisheye",
            "data.sources=[tiny,mine]",
            f"data.source_options={{mine:{{root:'{tmp_path}'}}}}",
        ]
    )
    _check(cfg)
    cfg = compose_train(["task=seg", "data=airfisheye", "data.sources=[tiny,airfisheye]"])
    with pytest.raises(ConfigError, match=r"give data\.source_options\.airfisheye\.root"):
        _check(cfg)


def test_a_two_source_run_records_each_source(
    tiny_dataset: Path, tiny_dataset_seed1: Path, tmp_path: Path
) -> None:
    cfg = compose_train(_overrides(tiny_dataset, tiny_dataset_seed1, "logger=csv", "data.eval_batch_size=4"))
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path)
    results = train(cfg)
    record = json.loads((tmp_path / "results.json").read_text())
    assert record["dataset"]["name"] == "tiny + other" and record["dataset"]["sources"] == ["tiny", "other"]
    assert record["metrics"]["mIoU"] == pytest.approx(results["metrics"]["mIoU"])
    tiny, other = record["sources"]["tiny"], record["sources"]["other"]
    assert (tiny["dataset"]["preset"], tiny["dataset"]["dataset_seed"], tiny["dataset"]["format"]) == (
        "tiny",
        0,
        "airfisheye",
    )
    assert other["dataset"]["root"] == str(tiny_dataset_seed1) and "preset" not in other["dataset"]
    for part in (tiny, other):
        assert part["dataset"]["name"] == "airfisheye-synthetic-tiny" and part["dataset"]["frames"] == 2
        assert part["dataset"]["content_sha256"] and part["dataset"]["camera"]["width"] == 64
        assert 0.0 <= part["metrics"]["mIoU"] <= 1.0 and any(k.startswith("ring_") for k in part["breakdown"])
    # Different data (seed 0 and seed 1): different content, different scores.
    assert tiny["dataset"]["content_sha256"] != other["dataset"]["content_sha256"]
    assert tiny["metrics"]["pixel_acc"] != other["metrics"]["pixel_acc"]
    # Pixel accuracy pools pixels: the pooled value lies between the sources' (both have 2 full-circle frames).
    low, high = sorted((tiny["metrics"]["pixel_acc"], other["metrics"]["pixel_acc"]))
    assert low <= record["metrics"]["pixel_acc"] <= high
    with (tmp_path / "metrics.csv").open() as f:
        header = next(csv.reader(f))
    assert {"test/tiny/mIoU", "test/other/mIoU", "val/tiny/mIoU", "val/other/mIoU", "test/mIoU"} <= set(
        header
    )
    # The leaderboard ranks each source's numbers with its own dataset, and the pooled ones with the mixture.
    rows = collect_results([tmp_path])
    assert [r.dataset_name for r in rows] == [
        "tiny + other",
        "airfisheye-synthetic-tiny",
        "airfisheye-synthetic-tiny",
    ]
    assert (
        rows[1].content_sha256 == tiny["dataset"]["content_sha256"] and "its tiny frames" in rows[1].evaluated
    )
    assert (
        rows[2].metrics["mIoU"] == pytest.approx(other["metrics"]["mIoU"])
        and "its other frames" in rows[2].evaluated
    )
    # A source's numbers are what evaluate.py measures on that source alone (same checkpoint, same frames).
    alone = compose_eval([f"ckpt_path={tmp_path}", "num_panels=0"], tmp_path / "eval")
    evaluate(
        alone, data_overrides=["data.sources=null", f"data.root={tiny_dataset_seed1}"]
    )  # the command line's
    evaluated = json.loads((tmp_path / "eval" / "results.json").read_text())
    assert evaluated["dataset"]["content_sha256"] == other["dataset"]["content_sha256"]
    for key in ("mIoU", "pixel_acc"):
        assert evaluated["metrics"][key] == pytest.approx(other["metrics"][key], rel=1e-6), key
    rim = "ring_80-95/mIoU"
    assert evaluated["breakdown"][rim] == pytest.approx(other["breakdown"][rim], rel=1e-6)


def test_train_py_stops_on_an_unknown_source_with_one_line_before_writing(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    args = [
        "task=seg",
        "data.sources=[tiny,mystery]",
        f"hydra.run.dir={run_dir}",
        f"paths.data_dir={tmp_path}/cache",
    ]
    error = assert_one_line_error(
        run_in_process(TRAIN, args), "data.sources", "'mystery'", "data.source_options.mystery"
    )
    assert "unknown source name" in error
    assert not (run_dir / "config.yaml").exists()  # refused before the run directory is written
    assert not any((tmp_path / "cache").rglob("dataset.yaml"))  # ... and before any source is generated


def test_evaluate_scores_one_source_of_a_mixture_at_a_time(tiny_dataset: Path) -> None:
    data = compose_train(_overrides(tiny_dataset, tiny_dataset)).data  # a mixture run's data config
    with pytest.raises(
        ConfigError, match=r"data\.sources=\['tiny', 'other'\]: evaluation scores one dataset"
    ):
        command._datamodule(None, "seg", data, [])
    datamodule, _ = command._datamodule(None, "seg", data, ["data.sources=null", f"data.root={tiny_dataset}"])
    assert datamodule.source_names == [] and datamodule.dataset_root() == tiny_dataset


@pytest.fixture(scope="module")
def tartanair_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_tartanair_fixture(tmp_path_factory.mktemp("tartanair") / "root", size=32)


def test_the_synthetic_preset_and_tartanair_in_one_run(tartanair_root: Path, tmp_path: Path) -> None:
    """``data=tartanair data.root=<fixture> data.sources=[synthetic,tartanair]`` (docs/training.md's command): the
    source named after the format reads data.root and data.format_options; the synthetic preset (tiny here) comes
    from the cache."""
    base = [o for o in tiny_run_overrides("seg", tartanair_root, size=32) if not o.startswith("data.root=")]
    overrides = ["data=tartanair", f"data.root={tartanair_root}", "data.format_options.split_period=3"]
    sources = [
        "data.sources=[synthetic,tartanair]",
        "data.source_options={synthetic:{preset:tiny}}",
    ]  # tiny data
    cfg = compose_train([*base, *overrides, *sources, "logger=csv"])
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path)
    train(cfg)
    record = json.loads((tmp_path / "results.json").read_text())
    tiny, tartanair = record["sources"]["synthetic"], record["sources"]["tartanair"]
    assert tartanair["dataset"]["format"] == "tartanair" and tartanair["dataset"]["root"] == str(
        tartanair_root
    )
    assert tartanair["dataset"]["format_options"]["split_period"] == 3
    assert tiny["dataset"]["format"] == "airfisheye" and tiny["dataset"]["preset"] == "tiny"
    assert tiny["dataset"]["name"] != tartanair["dataset"]["name"]
    assert tartanair["dataset"]["camera"]["width"] == tiny["dataset"]["camera"]["width"] == 32
    for part in (tiny, tartanair):
        assert 0.0 <= part["metrics"]["pixel_acc"] <= 1.0 and part["dataset"]["frames"] > 0
