"""``airfisheye-predict``: a trained model on a folder of images, a video or panoramas, from its checkpoint or its
ONNX export; frames of another camera refused in one line (or resized when allowed); bad input refused with nothing
written."""

from __future__ import annotations

import json
import logging
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from airfisheye_bench.errors import ConfigError, InputFileError, MissingFileError
from airfisheye_bench.geometry import ideal_camera
from airfisheye_bench.geometry.cameras import camera_from_dict
from airfisheye_bench.io import DatasetReader, trajectory_of
from airfisheye_bench.io.calibration_files import save_camera
from airfisheye_bench.io.layout import calibration_beside
from airfisheye_bench.prediction.footage import open_footage, read_sparse
from airfisheye_bench.prediction.footage_inputs import frame_preparer
from airfisheye_bench.runs.deployment import read_deployment_metadata
from tests.helpers import calibration_fixtures as fx
from tests.helpers.commands import PREDICT, Outcome, assert_one_line_error, run_in_process

SIZE = 64  # the served size of the shared tiny runs


@pytest.fixture(scope="module")
def models(tiny_runs, tiny_exports) -> dict[tuple[str, str], Path]:
    """``(task, source) -> path``: the session's tiny seg and depth runs and their ONNX exports."""
    out = {}
    for task in ("seg", "depth"):
        out[task, "ckpt"] = tiny_runs(task)
        onnx, status, report = tiny_exports(task)
        assert status == 0, report
        out[task, "onnx"] = onnx
    return out


def _images(folder: Path, count: int = 3, size: tuple[int, int] = (SIZE, SIZE), seed: int = 0) -> Path:
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(count):
        Image.fromarray(rng.integers(0, 256, (size[1], size[0], 3), dtype=np.uint8)).save(
            folder / f"f{i}.png"
        )
    return folder


def _predict(*args: str) -> Outcome:
    return run_in_process(PREDICT, [*args, "progress=false"])


def _assert_nothing_written(parent: Path) -> None:
    """No output folder, and no hidden half-written one beside it."""
    assert not parent.exists() or not any(parent.iterdir()), sorted(parent.iterdir())


def _outside_lens() -> np.ndarray:
    return ~ideal_camera(SIZE, SIZE, fov_deg=190.0).valid_mask().numpy()


# ------------------------------------------------------------------------------------------ what is written
@pytest.mark.integration
@pytest.mark.parametrize("source", ["ckpt", "onnx"])
def test_a_folder_of_images_with_a_segmentation_model(source: str, models, tmp_path: Path) -> None:
    images, out = _images(tmp_path / "frames"), tmp_path / "out"
    outcome = _predict(f"ckpt_path={models['seg', source]}", f"input={images}", f"out={out}")
    assert outcome.returncode == 0, outcome.stderr[-3000:]
    assert "predicted 3 frame(s) with a seg model" in outcome.stdout
    names = ["f0", "f1", "f2"]
    assert sorted(p.stem for p in (out / "labels").iterdir()) == names
    record = json.loads((out / "predict.json").read_text())
    assert record["task"] == "seg" and record["frames"] == names and record["camera"]["width"] == SIZE
    classes = len(record["class_names"])
    for name in names:
        with Image.open(out / "labels" / f"{name}.png") as png:
            assert png.mode == "L" and png.size == (SIZE, SIZE)
            labels = np.asarray(png)
        assert (labels[_outside_lens()] == 255).all()  # no prediction outside the lens
        assert (labels[~_outside_lens()] < classes).all()
        with Image.open(out / "color" / f"{name}.png") as color:
            assert color.mode == "RGB" and color.size == (SIZE, SIZE)
        with Image.open(out / "preview" / f"{name}.png") as preview:  # input | prediction, titles, class key
            assert preview.width == 2 * SIZE + 2 and preview.height > SIZE
    assert not [p for p in out.parent.iterdir() if p.name.startswith(".")]  # the staging folder is gone


@pytest.mark.integration
def test_checkpoint_and_onnx_predict_the_same_depth(models, tmp_path: Path) -> None:
    images = _images(tmp_path / "frames", count=2)
    png, npy = tmp_path / "png", tmp_path / "npy"
    for source, out, fmt in (("ckpt", png, "png16"), ("onnx", npy, "npy")):
        outcome = _predict(
            f"ckpt_path={models['depth', source]}", f"input={images}", f"out={out}", f"depth_format={fmt}"
        )
        assert outcome.returncode == 0, outcome.stderr[-3000:]
    for name in ("f0", "f1"):
        with Image.open(png / "depth" / f"{name}.png") as file:
            assert file.mode.startswith("I;16") or file.mode == "I"
            from_png = np.asarray(file).astype(np.float64) / 256.0  # documented: 1/256 m
        from_npy = np.load(npy / "depth" / f"{name}.npy")
        assert from_npy.dtype == np.float32 and from_npy.shape == (SIZE, SIZE)
        assert (from_npy[_outside_lens()] == 0).all() and (from_npy[~_outside_lens()] > 0).all()
        # The PNG's quantisation (1/512 m) and the export's parity tolerance (1e-3 relative).
        np.testing.assert_allclose(from_png, from_npy, rtol=2e-3, atol=1 / 512 + 1e-4)
    assert json.loads((npy / "predict.json").read_text())["model"]["source"] == "onnx"


@pytest.mark.integration
def test_a_video(models, tmp_path: Path) -> None:
    import imageio.v3 as iio

    frames = np.random.default_rng(1).integers(0, 256, (5, SIZE, SIZE, 3), dtype=np.uint8)
    video = tmp_path / "clip.mp4"
    iio.imwrite(video, frames, fps=5, plugin="FFMPEG")
    out = tmp_path / "out"
    outcome = _predict(f"ckpt_path={models['depth', 'onnx']}", f"input={video}", f"out={out}", "batch_size=2")
    assert outcome.returncode == 0, outcome.stderr[-3000:]
    names = [f"frame_{i:06d}" for i in range(5)]
    assert sorted(p.stem for p in (out / "depth").iterdir()) == names
    assert sorted(p.stem for p in (out / "preview").iterdir()) == names
    assert json.loads((out / "predict.json").read_text())["frames"] == names


@pytest.mark.integration
def test_equirectangular_panoramas(models, tmp_path: Path) -> None:
    folder = tmp_path / "panoramas"
    folder.mkdir()
    pano = np.zeros((48, 96, 3), np.uint8)
    pano[:24] = (120, 170, 230)  # the upper hemisphere
    Image.fromarray(pano).save(folder / "pano.png")
    out = tmp_path / "out"
    args = [f"ckpt_path={models['seg', 'onnx']}", f"input={folder}", f"out={out}"]
    refused = _predict(*args)  # a 2:1 frame read as a fisheye: refused, with the hint
    assert "input_format=erp" in assert_one_line_error(refused, "pano", "96x48", "equidistant 64x64")
    outcome = _predict(*args, "input_format=erp", "erp_pitch_deg=20")
    assert outcome.returncode == 0, outcome.stderr[-3000:]
    with Image.open(out / "labels" / "pano.png") as png:
        assert png.size == (SIZE, SIZE) and (np.asarray(png)[_outside_lens()] == 255).all()
    record = json.loads((out / "predict.json").read_text())
    assert record["input_format"] == "erp" and record["erp_pitch_deg"] == 20.0


def test_a_panorama_is_rendered_where_the_view_looks(tmp_path: Path) -> None:
    camera = ideal_camera(SIZE, SIZE, fov_deg=190.0)
    folder = tmp_path / "p"
    folder.mkdir()
    pano = np.zeros((64, 128, 3), np.uint8)
    pano[:32] = 255  # the upper hemisphere white, the lower black
    Image.fromarray(pano).save(folder / "pano.png")
    footage = open_footage(folder)
    centre = (SIZE // 2, SIZE // 2)
    level = frame_preparer(camera, footage, "erp")(pano)
    assert level[4, SIZE // 2].min() == 255 and level[-5, SIZE // 2].max() == 0  # sky up, ground down
    assert level[centre[0] - 6, centre[1]].min() == 255  # the horizon through the middle
    down = frame_preparer(camera, footage, "erp", pitch_deg=60.0)(pano)
    assert down[centre].max() == 0 and down[centre[0] - 6, centre[1]].max() == 0  # looking down: ground
    assert down[4, SIZE // 2].min() == 255  # the horizon 60 deg up, still in the 190 deg view
    assert (down[_outside_lens()] == 0).all()


@pytest.fixture(scope="module")
def completion_export(tiny_exports) -> tuple[Path, int, str]:
    """The session's ONNX export of the tiny completion run: ``(path, exit status, printed report)``."""
    return tiny_exports("completion")


@pytest.mark.integration
def test_completion_needs_its_sparse_maps(completion_export: tuple[Path, int, str], tmp_path: Path) -> None:
    onnx, status, report = completion_export
    assert status == 0, report
    images, sparse = _images(tmp_path / "frames", count=2), tmp_path / "sparse"
    sparse.mkdir()
    args = [f"ckpt_path={onnx}", f"input={images}", f"out={tmp_path / 'out'}"]
    assert_one_line_error(_predict(*args), "completion model", "sparse=<folder>")
    depth = np.zeros((SIZE, SIZE), np.float32)
    depth[::7, ::5] = 20.0
    np.save(sparse / "f0.npy", depth)
    Image.fromarray(np.round(depth * 256).astype(np.uint16)).save(sparse / "f1.png")  # 16-bit, range * 256
    outcome = _predict(*args, f"sparse={sparse}")
    assert outcome.returncode == 0, outcome.stderr[-3000:]
    with Image.open(tmp_path / "out" / "preview" / "f1.png") as preview:  # input | sparse input | prediction
        assert preview.width == 3 * SIZE + 4
    assert sorted(p.name for p in (tmp_path / "out" / "depth").iterdir()) == ["f0.png", "f1.png"]
    (sparse / "f1.png").unlink()
    missing = _predict(*args[:2], f"out={tmp_path / 'again'}", f"sparse={sparse}")
    assert_one_line_error(missing, "f1.png or f1.npy", "frame f1")
    assert not (tmp_path / "again").exists()


# ------------------------------------------------------------------------------------------------- camera
@pytest.mark.integration
def test_frames_of_another_size_are_refused_or_resized(models, tmp_path: Path, caplog) -> None:
    images = _images(tmp_path / "frames", count=2, size=(96, 96))
    out = tmp_path / "outs" / "out"
    args = [f"ckpt_path={models['seg', 'onnx']}", f"input={images}", f"out={out}"]
    line = assert_one_line_error(
        _predict(*args), "f0", "96x96", "equidistant 64x64", "allow_camera_mismatch=true"
    )
    assert "camera=" in line
    _assert_nothing_written(tmp_path / "outs")

    allowed = _predict(*args, "allow_camera_mismatch=true")
    assert allowed.returncode == 0, allowed.stderr[-3000:]
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING and "96x96" in r.getMessage()]
    assert len(warnings) == 1  # warned once, for 2 frames
    assert "2 resized" in allowed.stdout
    with Image.open(out / "labels" / "f1.png") as png:
        assert png.size == (SIZE, SIZE)
    assert json.loads((out / "predict.json").read_text())["resized_frames"] == 2


@pytest.mark.integration
def test_the_footage_lens_is_checked_against_the_model_camera(models, tmp_path: Path, caplog) -> None:
    onnx = models["seg", "onnx"]
    model_camera = camera_from_dict(read_deployment_metadata(onnx)["camera"])
    # The model's lens at twice the size: the same lens, so its frames are resized without a word.
    same = save_camera(model_camera.resized(2 * SIZE, 2 * SIZE), tmp_path / "same.yaml")
    images = _images(tmp_path / "frames", count=1, size=(2 * SIZE, 2 * SIZE))
    outcome = _predict(f"ckpt_path={onnx}", f"input={images}", f"out={tmp_path / 'a'}", f"camera={same}")
    assert outcome.returncode == 0, outcome.stderr[-3000:]
    ours = [
        r for r in caplog.records if r.name.startswith("airfisheye_bench") and r.levelno >= logging.WARNING
    ]
    assert not ours and "1 resized" in outcome.stdout

    other = fx.write_kitti360(tmp_path / "image_02.yaml")  # a MEI lens, not the model's equidistant one
    refused = _predict(f"ckpt_path={onnx}", f"input={images}", f"out={tmp_path / 'b'}", f"camera={other}")
    assert_one_line_error(refused, "camera=", "image_02.yaml", "unified", "equidistant 64x64")
    assert not (tmp_path / "b").exists()


# ---------------------------------------------------------------------------------------------- bad input
@pytest.mark.integration
@pytest.mark.parametrize("case", ["missing", "empty", "garbage", "truncated", "not_a_video"])
def test_bad_input_is_one_line_and_writes_nothing(case: str, models, tmp_path: Path) -> None:
    folder = tmp_path / "frames"
    if case == "missing":
        source, named = folder, "does not exist"
    elif case == "empty":
        folder.mkdir()
        (folder / "notes.txt").write_text("no frames here")
        source, named = folder, "no images"
    elif case == "not_a_video":
        source, named = tmp_path / "clip.mp4", "clip.mp4"
        source.write_bytes(b"not a video at all")
    else:
        _images(folder, count=2)
        broken = folder / "f1.png"
        data = broken.read_bytes()
        broken.write_bytes(b"not an image" if case == "garbage" else data[: len(data) // 3])
        source, named = folder, "f1.png"
    outs = tmp_path / "outs"
    outcome = _predict(f"ckpt_path={models['seg', 'onnx']}", f"input={source}", f"out={outs / 'new' / 'out'}")
    assert_one_line_error(outcome, named)
    _assert_nothing_written(outs)


@pytest.mark.integration
def test_an_existing_out_and_a_missing_model_are_refused(models, tmp_path: Path) -> None:
    images = _images(tmp_path / "frames", count=1)
    (tmp_path / "out").mkdir()
    assert_one_line_error(
        _predict(f"ckpt_path={models['seg', 'onnx']}", f"input={images}", f"out={tmp_path / 'out'}"),
        "out=",
        "already exists",
    )
    missing = tmp_path / "nowhere.onnx"
    assert_one_line_error(
        _predict(f"ckpt_path={missing}", f"input={images}", f"out={tmp_path / 'x'}"), "nowhere.onnx"
    )
    assert not (tmp_path / "x").exists()


@pytest.mark.integration
def test_sparse_is_refused_for_a_model_without_lidar_input(models, tmp_path: Path) -> None:
    images = _images(tmp_path / "frames", count=1)
    outcome = _predict(
        f"ckpt_path={models['depth', 'onnx']}", f"input={images}", f"sparse={images}", f"out={tmp_path / 'o'}"
    )
    assert_one_line_error(outcome, "sparse=", "completion")


def test_video_without_its_extra_names_the_extra(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    video = tmp_path / "clip.mp4"
    video.write_bytes(b"")
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # find_spec answers None: not installed
    with pytest.raises(ConfigError, match=r"imageio_ffmpeg.*\.\[video\]"):
        open_footage(video)


def test_frames_with_one_name_are_refused(tmp_path: Path) -> None:
    _images(tmp_path, count=1)
    Image.new("RGB", (4, 4)).save(tmp_path / "f0.jpg")
    with pytest.raises(InputFileError, match=r"f0\.jpg and f0\.png are one frame name"):
        open_footage(tmp_path)


def test_sparse_maps_are_read_in_metres(tmp_path: Path) -> None:
    depth = np.zeros((4, 6), np.float32)
    depth[1, 2] = 12.5
    np.save(tmp_path / "a.npy", depth)
    Image.fromarray(np.round(depth * 256).astype(np.uint16)).save(tmp_path / "b.png")
    for name in ("a", "b"):
        sparse = read_sparse(tmp_path, name, (4, 6))
        assert sparse.shape == (1, 4, 6) and torch.equal(sparse[0], torch.from_numpy(depth))
    with pytest.raises(InputFileError, match=r"expected \(5, 6\)"):
        read_sparse(tmp_path, "a", (5, 6))
    with pytest.raises(MissingFileError, match=r"no c\.png or c\.npy for frame c"):
        read_sparse(tmp_path, "c", (4, 6))


def test_frames_of_a_known_dataset_are_served_with_its_own_lens(tiny_dataset: Path, tmp_path: Path) -> None:
    """The generated data's own frames need no camera=: the calib.yaml of their trajectory is the lens."""
    reader = DatasetReader(tiny_dataset)
    sample = reader.split("val")[0]
    frames = reader.layout.fisheye(sample, "rgb").parent
    lens = reader.calib(sample).fisheye_camera()
    model_camera = lens.resized(lens.width // 2, lens.height // 2)  # the quick start's smaller size
    assert calibration_beside(frames) == reader.layout.calib(trajectory_of(sample))
    prepare = frame_preparer(model_camera, open_footage(frames))
    served = prepare(np.zeros((lens.height, lens.width, 3), np.uint8))
    assert served.shape == (model_camera.height, model_camera.width, 3) and prepare.resized == 1

    alone = tmp_path / "frames"  # the same frames outside any dataset: the model's lens, so its size
    shutil.copytree(frames, alone)
    assert calibration_beside(alone) is None
    with pytest.raises(ConfigError, match=r"give camera=<its calibration file>"):
        frame_preparer(model_camera, open_footage(alone))
