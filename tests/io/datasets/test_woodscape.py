"""``data.format=woodscape``: a fixture in WoodScape's own layout read into the project's conventions."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from omegaconf import open_dict
from PIL import Image

from airfisheye_bench.io.datasets import open_dataset
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.training import train
from datamodules.dataset import AirFisheyeDataset, CameraConfig
from tests.helpers.commands import TRAIN, assert_one_line_error, run_in_process
from tests.helpers.configs import compose_train
from tests.helpers.runs import tiny_run_overrides
from tests.helpers.woodscape_fixture import (
    HEIGHT,
    TRAIN_IDS,
    VAL_IDS,
    WIDTH,
    calibration,
    label_of,
    rgb_of,
    write_woodscape,
)


@pytest.fixture(scope="module")
def woodscape(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Read-only: copy it before damaging it."""
    return write_woodscape(tmp_path_factory.mktemp("woodscape") / "woodscape")


@pytest.fixture
def copy(woodscape: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(woodscape, tmp_path / "woodscape"))


def test_splits_are_the_devkits(woodscape: Path) -> None:
    source = open_dataset(woodscape, "woodscape")
    assert source.split_names == ["train", "val"]
    assert source.split("train") == sorted(TRAIN_IDS)
    assert source.split("val") == list(VAL_IDS)  # omnidet/data/val.txt's order
    front = open_dataset(woodscape, "woodscape", {"views": ["FV", "RV"]})
    assert front.split("train") == ["00000_FV", "00001_FV", "00028_RV"]
    assert front.split("val") == ["00020_FV", "00175_RV"]
    with pytest.raises(ValueError, match="views"):
        open_dataset(woodscape, "woodscape", {"views": ["FRONT"]})


def test_split_lists_of_ones_own(woodscape: Path, tmp_path: Path) -> None:
    (tmp_path / "train.txt").write_text("00000_FV.png\n00020_FV.png\n")
    (tmp_path / "val.txt").write_text("00001_FV.png\n")
    (tmp_path / "test.txt").write_text("00175_RV.png\n")
    source = open_dataset(woodscape, "woodscape", {"split_lists": str(tmp_path)})
    assert source.split_names == ["train", "val", "test"]
    assert source.split("train") == ["00000_FV", "00020_FV"] and source.split("test") == ["00175_RV"]
    (tmp_path / "val.txt").write_text("00001_FV\nnot-an-id.png\n")
    with pytest.raises(DatasetFormatError, match=r"val\.txt: key 'line 2'"):
        open_dataset(woodscape, "woodscape", {"split_lists": str(tmp_path)}).split("val")


def test_pixels_land_where_the_files_have_them(woodscape: Path) -> None:
    source = open_dataset(woodscape, "woodscape")
    index = (TRAIN_IDS + VAL_IDS).index("00165_MVL")
    rgb, seg = source.fisheye("00165_MVL", "rgb"), source.fisheye("00165_MVL", "seg")
    # crop_to_4x3: 128x98 -> 128x96, file row 0 dropped, so file row 1 is served row 0.
    assert rgb.shape == (96, 128, 3) and seg.shape == (96, 128)
    assert rgb[0, 0].tolist() == [index, 1, 2] and rgb[5, 7].tolist() == [14, 12, 40 + index]
    assert seg[0, :4].tolist() == [index % 10] * 4 and seg[10, 13 * 3 + 1] == 3
    whole = open_dataset(woodscape, "woodscape", {"crop_to_4x3": False})
    assert np.array_equal(whole.fisheye("00165_MVL", "seg"), label_of(index))
    assert np.array_equal(whole.fisheye("00165_MVL", "rgb"), rgb_of(index))


def test_calibration_follows_the_devkit(woodscape: Path) -> None:
    source = open_dataset(woodscape, "woodscape")
    camera = source.calib("00165_MVL").camera
    intr = calibration("MVL")["intrinsic"]
    # calibration_readme.txt: u = u' + cx_offset + width / 2 - 0.5 (pixel centres at integers), v likewise;
    # the 4:3 crop moves the principal point up by the one row dropped on top.
    assert camera["model"] == "radial_poly" and (camera["width"], camera["height"]) == (128, 96)
    assert camera["cx"] == pytest.approx(intr["cx_offset"] + 64 - 0.5)
    assert camera["cy"] == pytest.approx(intr["cy_offset"] + 49 - 0.5 - 1)
    assert camera["k1"] == pytest.approx(intr["k1"])
    # front.json's extrinsic is the front camera's pose in the vehicle frame (ISO 8855: x forward, y left, z up):
    # its optical axis points forward and some 23 degrees down, its x axis (image right) to the vehicle's right.
    pose = source.calib("00020_FV").T_body_cam
    assert pose[:3, 3].tolist() == pytest.approx([3.7484, 0.0, 0.66017])
    axis, right = pose[:3, 2], pose[:3, 0]
    assert axis[0] > 0.9 and np.degrees(np.arcsin(-axis[2])) == pytest.approx(23.4, abs=0.5)
    assert right[1] < -0.99


def test_benchmark_classes(woodscape: Path) -> None:
    source = open_dataset(woodscape, "woodscape", {"classes": "benchmark"})
    lut = source.spec.label_lut()
    names = [c.name for c in source.spec.train_classes]
    assert source.spec.num_train_classes == 13
    # void, road, lanemarks, curb, person, rider, vehicles, bicycle, motorcycle, traffic_sign
    expected = [None, "road", "road", "sidewalk", None, None, "vehicle", None, None, "pole"]
    assert [names[t] if t != 255 else None for t in lut[:10]] == expected
    dataset = open_dataset(woodscape, "woodscape")
    assert dataset.spec.num_train_classes == 10 and dataset.spec.label_lut()[:10].tolist() == list(range(10))


def test_a_camera_beyond_the_tolerance_is_refused(copy: Path) -> None:
    doc = calibration("RV")
    doc["intrinsic"]["cx_offset"] += 6.0  # 6 px of a 128 px width: more than 2 %
    (copy / "calibration" / "00028_RV.json").write_text(json.dumps(doc))
    with pytest.raises(DatasetFormatError, match=r"00028_RV\.json: its camera puts pixels up to 6\.\d px"):
        open_dataset(copy, "woodscape").split("train")
    assert open_dataset(copy, "woodscape", {"calib_tolerance": 0.1}).split("train")
    assert open_dataset(copy, "woodscape", {"views": ["FV"]}).split("train")


def test_bad_files_are_named(copy: Path) -> None:
    source = open_dataset(copy, "woodscape")
    (copy / "semantic_annotations" / "gtLabels" / "00001_FV.png").unlink()
    with pytest.raises(DatasetFormatError, match=r"gtLabels/00001_FV\.png: file does not exist"):
        source.fisheye("00001_FV", "seg")
    Image.fromarray(np.zeros((HEIGHT, WIDTH + 2, 3), np.uint8)).save(copy / "rgb_images" / "00000_FV.png")
    with pytest.raises(
        DatasetFormatError, match=r"00000_FV\.png: image is 130x98, its 00000_FV\.json says 128x98"
    ):
        source.fisheye("00000_FV", "rgb")
    (copy / "calibration" / "00044_MVR.json").unlink()
    with pytest.raises(DatasetFormatError, match=r"00044_MVR\.json: missing"):
        source.calib("00044_MVR")
    shutil.rmtree(copy / "calibration")
    with pytest.raises(DatasetFormatError, match="no calibration folder"):
        open_dataset(copy, "woodscape")


def test_the_download_layouts_of_the_calibration(tmp_path: Path) -> None:
    root = write_woodscape(tmp_path / "ws", calib_dir="calibration_data/calibration")
    assert open_dataset(root, "woodscape").calib("00000_FV").camera["width"] == WIDTH


def test_depth_and_completion_are_refused_in_one_line(woodscape: Path) -> None:
    for task in ("depth", "completion"):
        with pytest.raises(ValueError, match=r"^WoodScape released no LiDAR .*#82\); task=\w+ needs it$"):
            AirFisheyeDataset.from_root(woodscape, "train", task, source="fisheye", format="woodscape")


def test_the_dataset_serves_labels_at_the_training_size(woodscape: Path) -> None:
    ds = AirFisheyeDataset.from_root(
        woodscape, "val", "seg", source="fisheye", camera=CameraConfig(size=64), format="woodscape"
    )
    sample = ds[0]
    assert sample["image"].shape == (3, 48, 64) and sample["label"].shape == (48, 64)
    assert set(sample["label"].unique().tolist()) <= set(range(10))
    assert ds.camera.width == 64 and ds.camera.height == 48


@pytest.mark.integration
def test_an_empty_folder_is_one_line(tmp_path: Path) -> None:
    """The folders of a WoodScape root without a file in them: one line naming the root, the split and the images."""
    root = tmp_path / "woodscape"
    for folder in ("rgb_images", "semantic_annotations/gtLabels", "calibration"):
        (root / folder).mkdir(parents=True)
    outcome = run_in_process(
        TRAIN,
        [
            "task=seg",
            "data=woodscape",
            f"data.root={root}",
            "trainer=debug",
            f"hydra.run.dir={tmp_path / 'run'}",
        ],
    )
    assert_one_line_error(outcome, str(root), "split 'train' is empty", "rgb_images/<id>_<CAM>.png")


@pytest.mark.integration
def test_a_download_without_the_validation_images_is_one_line(copy: Path, tmp_path: Path) -> None:
    for sid in VAL_IDS:
        (copy / "rgb_images" / f"{sid}.png").unlink()
    outcome = run_in_process(
        TRAIN,
        [
            "task=seg",
            "data=woodscape",
            f"data.root={copy}",
            "trainer=debug",
            f"hydra.run.dir={tmp_path / 'run'}",
        ],
    )
    assert_one_line_error(outcome, str(copy), "split 'val' is empty", "validation list", "split_lists")


@pytest.mark.integration
def test_train_seg_end_to_end(woodscape: Path, tmp_path: Path) -> None:
    overrides = [*tiny_run_overrides("seg", woodscape), "data=woodscape", "logger=csv"]
    cfg = compose_train(overrides)
    with open_dict(cfg):
        cfg.paths.output_dir = str(tmp_path)
    results = train(cfg)
    record = json.loads((tmp_path / "results.json").read_text())
    assert record["task"] == "seg" and record["split"] == "val"
    assert record["metrics"]["mIoU"] == pytest.approx(results["metrics"]["mIoU"])
    assert {f"IoU/{name}" for name in ("void", "road", "traffic_sign")} <= set(record["metrics"])
    assert record["config"]["camera"]["model"] == "radial_poly" and record["config"]["camera"]["height"] == 48
