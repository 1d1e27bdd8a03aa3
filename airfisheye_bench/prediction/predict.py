"""``airfisheye-predict``: a trained model run on a user's own footage, without labels.

``airfisheye-predict ckpt_path=<run dir | .ckpt | .onnx> input=<folder of images | video> [out=DIR]`` loads the
model the way evaluation does (:func:`~airfisheye_bench.evaluation.trained.load_trained`), checks that it can
serve every frame, predicts them in batches and writes, per frame ``<name>`` (docs/design.md, "Predicting on
footage"):

- ``labels/<name>.png`` (seg): 8-bit class ids of the model's classes, 255 outside the lens;
- ``depth/<name>.png`` (depth, completion): 16-bit ``round(range * 256)`` (1/256 m, as KITTI's depth maps; up to
  256 m, 0 = no prediction), or ``depth/<name>.npy`` (float32 range in metres) with ``depth_format=npy``;
- ``color/<name>.png``: the prediction colourised (class colours, or range on the log colour map of the panels);
- ``preview/<name>.png``: the model's input beside the colourised prediction, titled, with the class key or the
  range colour bar;

and ``predict.json`` (the model, its camera, the input and the frames). Everything is written into a hidden
sibling of ``out``, renamed to ``out`` when the last frame is done: a failure leaves nothing behind.

**Camera.** A model predicts the camera it was trained for (its ``camera``: image size and lens). A frame of
another size is refused with one line naming both, before the first prediction; ``camera=<calibration file>``
states the footage's lens, which must then be the model's at the footage's size (the frames are resized to the
model's: the same lens, scaled). ``allow_camera_mismatch=true`` predicts anyway, resizing every frame to the
model's size (warned once). ``input_format=erp`` reads equirectangular panoramas and renders each into the model's
lens first (``erp_yaw_deg``, ``erp_pitch_deg``: where it looks). Pixels outside the model's lens are black in the
input, as in training, and carry no prediction (:mod:`~airfisheye_bench.prediction.footage_inputs`).

**A perspective model on fisheye footage** (``views=cube``, or a list of ``[yaw, pitch]`` views; a model trained with
``data.camera.model=pinhole``): each frame is rendered into the views at the model's camera and the outputs are
resampled back (:func:`~airfisheye_bench.evaluation.trained.through_views`; ``view_depth=z`` for a model whose depth is
z along its axis). The footage's fisheye lens is then needed: ``camera=<calibration file>``, or the ``calib.yaml`` of
the dataset the frames belong to; the frames are predicted at that lens's size, and ``predict.json`` records the
views.

**Completion** needs the LiDAR: ``sparse=<folder>`` of one range map per frame, named as the frame, in the model's
camera and size (``<name>.npy`` in metres or 16-bit ``<name>.png`` of range * 256); without it a completion model is
refused: images alone do not give its input.

**Camera-aware models** (``model.camera_input=rays``) get the ray map of the model's camera with every frame
(:func:`~airfisheye_bench.geometry.ray_maps.ray_map`: the lens the frames are prepared for); an ONNX file whose map
is baked in needs nothing beside the image.
"""

from __future__ import annotations

import contextlib
import json
import logging
import shutil
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from airfisheye_bench.atomic import atomic_write_text, check_writable
from airfisheye_bench.errors import ConfigError, MissingFileError, OutputExistsError
from airfisheye_bench.evaluation.predictors import TTA_MODES
from airfisheye_bench.evaluation.submission import write_prediction
from airfisheye_bench.evaluation.trained import TrainedModel, load_trained, through_views
from airfisheye_bench.geometry.cameras import CameraModel
from airfisheye_bench.geometry.perspective_views import DEPTH_CONVENTIONS, views_problem
from airfisheye_bench.geometry.ray_maps import ray_map
from airfisheye_bench.io.calibration_files import load_camera
from airfisheye_bench.io.layout import calibration_beside
from airfisheye_bench.io.progress_report import ProgressReport
from airfisheye_bench.prediction.footage import open_footage, read_sparse
from airfisheye_bench.prediction.footage_inputs import INPUT_FORMATS, frame_preparer
from airfisheye_bench.specs import DEPTH_PNG_SCALE, get_task
from airfisheye_bench.viz import (
    class_legend,
    colorize_depth,
    colorize_labels,
    depth_colorbar,
    make_panel,
    save_png,
)

__all__ = ["DEPTH_FORMATS", "INPUT_FORMATS", "PredictReport", "predict_footage"]

log = logging.getLogger(__name__)

#: ``depth_format`` -> the suffix of a depth prediction file.
DEPTH_FORMATS = {"png16": ".png", "npy": ".npy"}
#: Label of pixels without a prediction (outside the lens), as the datasets' ignore label.
NO_LABEL = 255


@dataclass(frozen=True)
class PredictReport:
    """What ``airfisheye-predict`` did.

    Attributes:
        out: The folder written.
        task: The model's task.
        frames: Frames predicted.
        resized: Frames resized to the model's size.
        seconds: Wall time of the predictions and writes.
    """

    out: Path
    task: str
    frames: int
    resized: int
    seconds: float

    def summary(self) -> str:
        """One line: frames, time, where."""
        resized = f", {self.resized} resized to the model's size" if self.resized else ""
        return (
            f"predicted {self.frames} frame(s) with a {self.task} model in {self.seconds:.1f} s{resized}: "
            f"{self.out}"
        )


def predict_footage(
    ckpt_path: str | Path,
    input: str | Path,
    out: str | Path | None = None,
    input_format: str = "fisheye",
    camera: str | None = None,
    camera_name: str | None = None,
    allow_camera_mismatch: bool = False,
    erp_yaw_deg: float = 0.0,
    erp_pitch_deg: float = 0.0,
    sparse: str | Path | None = None,
    depth_format: str = "png16",
    batch_size: int = 4,
    device: str = "auto",
    threads: int | None = None,
    tta: str | None = None,
    progress: bool = True,
    views: Any = None,
    view_depth: str = "range",
) -> PredictReport:
    """Predict every frame of ``input`` with the model of ``ckpt_path`` and write the outputs into ``out``.

    Args:
        ckpt_path: A run directory, a ``.ckpt`` file or an ``.onnx`` model of ``airfisheye-export``.
        input: A folder of images or a video file (:func:`~airfisheye_bench.prediction.footage.open_footage`).
        out: The folder to write; must not exist (``None``: ``predictions/<input stem>`` in the working folder).
        input_format: ``fisheye`` or ``erp`` (equirectangular panoramas, re-rendered into the model's lens).
        camera: A calibration file of the footage's lens (``None``: taken to be the model's, at its size).
        camera_name: Which camera of a calibration file that holds several.
        allow_camera_mismatch: Predict frames the model's camera cannot serve, resized to its size.
        erp_yaw_deg: ``erp``: the model's camera looks this far left of the panorama's centre (degrees).
        erp_pitch_deg: ``erp``: and this far down (degrees).
        sparse: Completion: the folder of the frames' sparse range maps.
        depth_format: ``png16`` (``round(range * 256)``) or ``npy`` (float32 metres).
        batch_size: Frames per model call.
        device: Checkpoint inference: ``auto``, ``cpu`` or ``cuda``.
        threads: ONNX Runtime intra-op threads (``None``: its default).
        tta: ``None`` or ``flip`` (:func:`~airfisheye_bench.evaluation.predictors.flip_tta`).
        progress: Show a progress bar (in a terminal; log lines otherwise).
        views: A perspective model on fisheye footage: ``cube`` or a list of ``[yaw, pitch(, roll)]`` (degrees).
        view_depth: With ``views``: ``range`` (this project's models) or ``z`` (depth along the view's axis).

    Raises:
        UserError: a bad option, a missing, empty or unreadable input, a frame of another camera (without
            ``allow_camera_mismatch``), a completion model without ``sparse``, or an existing ``out``; nothing is
            written then.
    """
    _check_options(input_format, depth_format, batch_size, tta, device)
    _check_views(views, view_depth)
    source = Path(input).expanduser()
    out = Path(out).expanduser() if out is not None else Path("predictions") / (source.stem or source.name)
    if out.exists():
        raise OutputExistsError(f"out={out} already exists; choose a new folder for the predictions")
    check_writable(out / "predict.json", "out")
    footage = open_footage(source)
    sparse_dir = Path(sparse).expanduser() if sparse is not None else None
    if sparse_dir is not None and not sparse_dir.is_dir():
        raise MissingFileError(
            f"sparse={sparse_dir} is not a folder; give the folder of the frames' range maps"
        )
    model = load_trained(ckpt_path, device=device, threads=threads, tta=tta)
    if views is not None:
        if input_format != "fisheye":
            raise ConfigError(
                "views= renders fisheye frames into a perspective model's views; panoramas (input_format=erp) are "
                "rendered into the model's camera directly: drop views="
            )
        lens_file = camera or _beside(footage)
        model = through_views(model, _footage_lens(lens_file, camera_name), views, view_depth)
        camera = lens_file
    _check_inputs(model, sparse_dir)
    prepare = frame_preparer(
        model.camera,
        footage,
        input_format,
        camera,
        camera_name,
        allow_camera_mismatch,
        erp_yaw_deg,
        erp_pitch_deg,
    )

    started = time.monotonic()
    rays = ray_map(model.camera)[None] if model.takes_rays else None
    writer = _Writer(model, out, DEPTH_FORMATS[depth_format])
    names: list[str] = []
    with writer, ProgressReport(footage.count, "predict", "frame", progress, logger=log) as bar:
        for chunk in _batches(footage.frames(), batch_size):
            images = [prepare(rgb) for _, rgb in chunk]
            batch = {"image": torch.stack([_normalise(model, image) for image in images])}
            if "sparse_depth" in model.inputs:
                shape = (model.camera.height, model.camera.width)
                assert sparse_dir is not None  # _check_inputs
                sparse_maps = torch.stack([read_sparse(sparse_dir, name, shape) for name, _ in chunk])
                # As served in training: no LiDAR point outside the lens.
                batch["sparse_depth"] = sparse_maps.masked_fill(~model.camera.valid_mask(), 0.0)
            if (
                model.takes_rays
            ):  # a camera-aware model: the ray map of the camera the frames are prepared for
                batch["rays"] = rays.expand(len(chunk), -1, -1, -1)
            predictions = model.predictor(batch).cpu()
            for i, (name, _) in enumerate(chunk):
                sparse_map = batch["sparse_depth"][i, 0] if "sparse_depth" in batch else None
                writer.add(name, images[i], predictions[i], sparse_map)
                names.append(name)
            bar.update(len(chunk))
        writer.finish(
            {
                "input": str(footage.path),
                "input_format": input_format,
                **(
                    {"erp_yaw_deg": erp_yaw_deg, "erp_pitch_deg": erp_pitch_deg}
                    if input_format == "erp"
                    else {}
                ),
                "footage_camera": camera,
                **({"views": views, "view_depth": view_depth} if views is not None else {}),
                "allow_camera_mismatch": allow_camera_mismatch,
                "resized_frames": prepare.resized,
                "sparse": str(sparse_dir) if sparse_dir is not None else None,
                "depth_format": depth_format,
                "frames": names,
            }
        )
    return PredictReport(out, model.task, len(names), prepare.resized, time.monotonic() - started)


# ------------------------------------------------------------------------------------------------ checks
def _check_options(
    input_format: str, depth_format: str, batch_size: int, tta: str | None, device: str
) -> None:
    if input_format not in INPUT_FORMATS:
        raise ConfigError(f"input_format={input_format}: expected one of {', '.join(INPUT_FORMATS)}")
    if depth_format not in DEPTH_FORMATS:
        raise ConfigError(f"depth_format={depth_format}: expected one of {', '.join(DEPTH_FORMATS)}")
    if batch_size < 1:
        raise ConfigError(f"batch_size={batch_size}: expected an integer >= 1")
    if tta not in TTA_MODES:
        raise ConfigError(f"tta={tta}: expected null or flip")
    if device not in ("auto", "cpu", "cuda"):
        raise ConfigError(f"device={device}: expected one of auto, cpu, cuda")


def _beside(footage) -> str:
    """The calibration of the dataset the frames belong to, which ``views=`` needs without ``camera=``."""
    found = calibration_beside(footage.path)
    if found is None:
        raise ConfigError(
            "views= renders the footage's fisheye frames into the model's views, so it needs their lens: give "
            "camera=<its calibration file>"
        )
    return str(found)


def _footage_lens(lens_file: str, lens_name: str | None) -> CameraModel:
    try:
        return load_camera(lens_file, lens_name, option="camera_name")
    except FileNotFoundError:
        raise MissingFileError(f"camera={lens_file}: no such calibration file") from None
    except ValueError as err:
        raise ConfigError(f"camera={lens_file}: {err}") from None


def _check_views(views: Any, view_depth: str) -> None:
    if views is not None and (problem := views_problem(views)) is not None:
        raise ConfigError(f"views={views!r}: {problem}")
    if view_depth not in DEPTH_CONVENTIONS:
        raise ConfigError(f"view_depth={view_depth}: expected one of {', '.join(DEPTH_CONVENTIONS)}")


def _check_inputs(model: TrainedModel, sparse: Path | None) -> None:
    needs_sparse = "sparse_depth" in model.inputs
    if needs_sparse and sparse is None:
        raise ConfigError(
            f"{model.path} is a {model.task} model, which takes a LiDAR range map beside each image: give "
            "sparse=<folder> of <frame>.npy (metres) or 16-bit <frame>.png (range * 256) maps in the model's camera"
        )
    if sparse is not None and not needs_sparse:
        raise ConfigError(
            f"sparse= is the LiDAR input of completion models; {model.path} is a {model.task} model"
        )


# --------------------------------------------------------------------------------------- frames to inputs
def _normalise(model: TrainedModel, rgb: np.ndarray) -> torch.Tensor:
    """``uint8 [H, W, 3]`` -> ``float32 [3, H, W]``, ``(rgb / 255 - mean) / std``."""
    image = torch.from_numpy(rgb).permute(2, 0, 1).float().div_(255.0)
    mean = torch.tensor(model.mean).view(3, 1, 1)
    std = torch.tensor(model.std).view(3, 1, 1)
    return image.sub_(mean).div_(std)


def _batches(frames: Iterator[tuple[str, np.ndarray]], size: int) -> Iterator[list[tuple[str, np.ndarray]]]:
    chunk: list[tuple[str, np.ndarray]] = []
    for frame in frames:
        chunk.append(frame)
        if len(chunk) == size:
            yield chunk
            chunk = []
    if chunk:
        yield chunk


# ------------------------------------------------------------------------------------------------ outputs
class _Writer:
    """Writes the outputs of each frame into a hidden sibling of ``out``, renamed to ``out`` by :meth:`finish`.

    Leaving the ``with`` block by an exception removes everything written.
    """

    def __init__(self, model: TrainedModel, out: Path, depth_suffix: str) -> None:
        self.model = model
        self.out = out
        self.labels = get_task(model.task).uses_classes
        self.suffix = ".png" if self.labels else depth_suffix
        self.folder = "labels" if self.labels else "depth"
        self.outside = ~model.camera.valid_mask()
        self._legends: dict[int, np.ndarray] = {}
        self._tmp: Path | None = None
        self._made: list[Path] = []

    def __enter__(self) -> _Writer:
        self._made = [p for p in self.out.parents if not p.exists()]  # removed again on failure
        self.out.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = Path(tempfile.mkdtemp(prefix=f".{self.out.name}.", dir=self.out.parent))
        return self

    def add(
        self, name: str, image: np.ndarray, prediction: torch.Tensor, sparse: torch.Tensor | None
    ) -> None:
        assert self._tmp is not None
        if self.labels:
            prediction = prediction.masked_fill(self.outside, NO_LABEL)
            color = colorize_labels(prediction, self.model.palette)
        else:
            prediction = prediction.masked_fill(self.outside, 0.0)
            color = colorize_depth(prediction, self.model.max_depth)
        write_prediction(self._tmp / self.folder / f"{name}{self.suffix}", prediction, self.model.task)
        save_png(self._tmp / "color" / f"{name}.png", color)
        tiles = [image]
        if sparse is not None:
            tiles.append(colorize_depth(sparse, self.model.max_depth))
        tiles.append(color)
        titles = ["input", *(["sparse input"] if sparse is not None else []), "prediction"]
        panel = make_panel([tiles], titles=titles, legends=[self._legend(len(tiles))])
        save_png(self._tmp / "preview" / f"{name}.png", panel)

    def _legend(self, tiles: int) -> np.ndarray:
        """The class key or the range colour bar under a preview of ``tiles`` tiles (drawn once per width)."""
        if tiles not in self._legends:
            width = tiles * (self.model.camera.width + 2) - 2  # make_panel's gap of 2
            if self.labels:
                names = self.model.class_names or []
                classes = list(zip(names, self.model.palette.tolist(), strict=False))
                self._legends[tiles] = class_legend(width, classes)
            else:
                self._legends[tiles] = depth_colorbar(width, self.model.max_depth)
        return self._legends[tiles]

    def finish(self, record: dict[str, Any]) -> None:
        """Write ``predict.json`` and publish the folder."""
        assert self._tmp is not None
        identity = self.model.predictor.identity()
        meta = {
            "task": self.model.task,
            "model": identity,
            "camera": self.model.camera.to_dict(),
            "outputs": {
                self.folder: (
                    "class ids (8-bit PNG), 255 outside the lens"
                    if self.labels
                    else (
                        f"range, 16-bit PNG of round(metres * {DEPTH_PNG_SCALE:g}), 0 = none"
                        if self.suffix == ".png"
                        else "range in metres, float32 .npy, 0 = none"
                    )
                ),
                "color": "the prediction colourised",
                "preview": "input | prediction (completion: input | sparse input | prediction)",
            },
            **({"class_names": self.model.class_names} if self.labels else {}),
            **record,
        }
        atomic_write_text(self._tmp / "predict.json", json.dumps(meta, indent=2, default=str) + "\n")
        self._tmp.rename(self.out)
        self._tmp = None

    def __exit__(self, exc_type, exc, tb) -> None:
        if self._tmp is None:
            return
        shutil.rmtree(self._tmp, ignore_errors=True)
        self._tmp = None
        for folder in self._made:  # deepest first; only the empty folders this run made
            with contextlib.suppress(OSError):
                folder.rmdir()
