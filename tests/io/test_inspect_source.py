"""``airfisheye-inspect root=DIR format=<name>``: any dataset source, its splits counted, its damage named."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from airfisheye_bench.cli import inspect
from airfisheye_bench.dataset_tools.inspect_source import inspect_source
from airfisheye_bench.errors import ConfigError
from tests.helpers.commands import exit_status
from tests.helpers.woodscape_fixture import HEIGHT, TRAIN_IDS, VAL_IDS, WIDTH, write_woodscape


@pytest.fixture
def woodscape(tmp_path: Path) -> Path:
    return write_woodscape(tmp_path / "woodscape")


def test_a_good_dataset_is_counted_per_split(woodscape: Path, capsys: pytest.CaptureFixture) -> None:
    for deep in (False, True):
        report = inspect_source(woodscape, "woodscape", deep=deep)
        assert report.ok, report.summary()
        assert report.splits == {"train": len(TRAIN_IDS), "val": len(VAL_IDS)} and report.samples == 10
        assert report.files == 10 * 3  # calibration, rgb, seg of each image
    front = inspect_source(woodscape, "woodscape", {"views": ["FV"]}, deep=True)
    assert front.splits == {"train": 2, "val": 1}
    assert inspect([f"root={woodscape}", "format=woodscape", "format_options={views:[FV,RV]}"]) == 0
    assert "splits: train 3, val 2" in capsys.readouterr().out


def test_a_broken_dataset_names_each_file(woodscape: Path) -> None:
    missing = woodscape / "semantic_annotations" / "gtLabels" / "00001_FV.png"
    missing.unlink()
    resized = woodscape / "rgb_images" / "00028_RV.png"
    Image.fromarray(np.zeros((HEIGHT - 10, WIDTH, 3), np.uint8)).save(resized)
    corrupt = woodscape / "rgb_images" / "00044_MVR.png"
    corrupt.write_bytes(b"\x89PNG garbage")
    unknown = woodscape / "semantic_annotations" / "gtLabels" / "00020_FV.png"
    label = np.zeros((HEIGHT, WIDTH), np.uint8)
    label[5, 5] = 42
    Image.fromarray(label, "L").save(unknown)
    no_calib = woodscape / "calibration" / "00175_RV.json"
    no_calib.unlink()

    shallow = inspect_source(woodscape, "woodscape")
    deep = inspect_source(woodscape, "woodscape", deep=True)
    for report in (shallow, deep):
        assert report.splits == {"train": 6, "val": 4}
        problems = dict(report.problems)
        assert problems[str(missing)].startswith(("missing", "file does not exist"))
        assert str(corrupt) in problems and str(no_calib) in problems
    # Sizes and label values are read in deep mode only (a source may crop what it serves).
    assert str(resized) not in dict(shallow.problems) and str(unknown) not in dict(shallow.problems)
    assert "image is 128x88, its 00028_RV.json says 128x98" in dict(deep.problems)[str(resized)]
    assert dict(deep.problems)[str(unknown)] == "label ids [42] are not classes of the dataset"
    assert len(deep.problems) == 5, deep.summary()
    assert inspect([f"root={woodscape}", "format=woodscape", "deep=true"]) == 1


def test_a_split_the_source_refuses_is_reported(woodscape: Path) -> None:
    path = woodscape / "calibration" / "00140_MVL.json"
    doc = json.loads(path.read_text())
    doc["intrinsic"]["cx_offset"] += 10.0
    path.write_text(json.dumps(doc))
    report = inspect_source(woodscape, "woodscape")
    assert report.splits == {"val": 4}
    assert report.problems[0][0] == str(path) and "calib_tolerance" in report.problems[0][1]


def test_the_commands_mistakes_are_user_errors(woodscape: Path, tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="format='nope'"):
        inspect_source(woodscape, "nope")
    with pytest.raises(ConfigError, match="unknown keys"):
        inspect_source(woodscape, "woodscape", {"view": ["FV"]})
    assert exit_status(inspect, [f"root={woodscape}", "format=woodscape", "format_options={views:[XX]}"]) == 2
    assert exit_status(inspect, [f"root={woodscape}", "format=woodscape", "format_options=FV"]) == 2
    report = inspect_source(tmp_path / "nowhere", "woodscape")
    assert not report.ok and "not a folder" in report.problems[0][1]
    empty = tmp_path / "empty"
    empty.mkdir()
    assert "rgb_images" in inspect_source(empty, "woodscape").problems[0][0]
