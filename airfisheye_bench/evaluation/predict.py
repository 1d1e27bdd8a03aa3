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
model's size (warned once). Pixels outside the model's lens are zeroed in the input, as in training, and carry no
prediction.

**Completion** needs the LiDAR: ``sparse=<folder>`` of one range map per frame, named as the frame, in the model's
camera and size (``<name>.npy`` in metres or 16-bit ``<name>.png`` of range * 256); without it a completion model is
refused: images alone do not give its input.
"""

from __future__ import annotations

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
from PIL import Image
from tqdm.auto import tqdm

from airfisheye_bench.atomic import atomic_write_text, check_writable
from airfisheye_bench.errors import ConfigError, MissingFileError, OutputExistsError
from airfisheye_bench.evaluation.footage import Footage, open_footage, read_sparse
from airfisheye_bench.evaluation.predictors import TTA_MODES
from airfisheye_bench.evaluation.submission import write_prediction
from airfisheye_bench.evaluation.trained import TrainedModel, load_trained
from airfisheye_bench.geometry.cameras import CameraModel
from airfisheye_bench.io.calibration_files import camera_label, camera_mismatch, load_camera
from airfisheye_bench.progress import console_is_terminal, progress_line
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
#: ``input_format``: fisheye frames (of the model's lens) or equirectangular panoramas.
INPUT_FORMATS = ("fisheye", "erp")
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
    sparse: str | Path | None = None,
    depth_format: str = "png16",
    batch_size: int = 4,
    device: str = "auto",
    threads: int | None = None,
    tta: str | None = None,
    progress: bool = True,
) -> PredictReport:
    """Predict every frame of ``input`` with the model of ``ckpt_path`` and write the outputs into ``out``.

    Args:
        ckpt_path: A run directory, a ``.ckpt`` file or an ``.onnx`` model of ``airfisheye-export``.
        input: A folder of images or a video file (:func:`~airfisheye_bench.evaluation.footage.open_footage`).
        out: The folder to write; must not exist (``None``: ``predictions/<input name>`` in the working folder).
        input_format: ``fisheye`` or ``erp`` (equirectangular panoramas, re-rendered into the model's lens).
        camera: A calibration file of the footage's lens (``None``: taken to be the model's, at its size).
        camera_name: Which camera of a calibration file that holds several.
        allow_camera_mismatch: Predict frames the model's camera cannot serve, resized to its size.
        sparse: Completion: the folder of the frames' sparse range maps.
        depth_format: ``png16`` (``round(range * 256)``) or ``npy`` (float32 metres).
        batch_size: Frames per model call.
        device: Checkpoint inference: ``auto``, ``cpu`` or ``cuda``.
        threads: ONNX Runtime intra-op threads (``None``: its default).
        tta: ``None`` or ``flip`` (:func:`~airfisheye_bench.evaluation.predictors.flip_tta`).
        progress: Show a progress bar (in a terminal; log lines otherwise).

    Raises:
        UserError: a bad option, a missing, empty or unreadable input, a frame of another camera (without
            ``allow_camera_mismatch``), a completion model without ``sparse``, or an existing ``out``; nothing is
            written then.
    """
    _check_options(input_format, depth_format, batch_size, tta, device, camera)
    out = Path(out).expanduser() if out is not None else Path("predictions") / Path(input).expanduser().name
    if out.exists():
        raise OutputExistsError(f"out={out} already exists; choose a new folder for the predictions")
    check_writable(out / "predict.json", "out")
    footage = open_footage(input)
    sparse_dir = Path(sparse).expanduser() if sparse is not None else None
    if sparse_dir is not None and not sparse_dir.is_dir():
        raise MissingFileError(
            f"sparse={sparse_dir} is not a folder; give the folder of the frames' range maps"
        )
    model = load_trained(ckpt_path, device=device, threads=threads, tta=tta)
    _check_inputs(model, sparse_dir)
    prepare = _preparer(model, footage, input_format, camera, camera_name, allow_camera_mismatch)

    started = time.monotonic()
    writer = _Writer(model, out, DEPTH_FORMATS[depth_format])
    names: list[str] = []
    with writer:
        bar = _Progress(footage.count, progress)
        for chunk in _batches(footage.frames(), batch_size):
            images = [prepare(name, rgb) for name, rgb in chunk]
            batch = {"image": torch.stack([_normalise(model, image) for image in images])}
            if "sparse_depth" in model.inputs:
                shape = (model.camera.height, model.camera.width)
                assert sparse_dir is not None  # _check_inputs
                batch["sparse_depth"] = torch.stack(
                    [read_sparse(sparse_dir, name, shape) for name, _ in chunk]
                )
            predictions = model.predictor(batch).cpu()
            for i, (name, _) in enumerate(chunk):
                sparse_map = batch["sparse_depth"][i, 0] if "sparse_depth" in batch else None
                writer.add(name, images[i], predictions[i], sparse_map)
                names.append(name)
            bar.update(len(chunk))
        bar.close()
        writer.finish(
            {
                "input": str(footage.path),
                "input_format": input_format,
                "footage_camera": camera,
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
    input_format: str, depth_format: str, batch_size: int, tta: str | None, device: str, camera: str | None
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
    if camera is not None and input_format == "erp":
        raise ConfigError(
            "camera= is the lens of fisheye footage; an equirectangular panorama (input_format=erp) has none, drop it"
        )


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
class _Preparer:
    """Turns a frame into the model's input image (``uint8 [H, W, 3]`` of the model's camera), counting resizes."""

    def __init__(self, model: TrainedModel) -> None:
        self.size = (model.camera.width, model.camera.height)
        self.outside = ~model.camera.valid_mask().numpy()
        self.resized = 0

    def __call__(self, name: str, rgb: np.ndarray) -> np.ndarray:
        if (rgb.shape[1], rgb.shape[0]) != self.size:
            rgb = np.asarray(Image.fromarray(rgb).resize(self.size, Image.Resampling.BILINEAR))
            self.resized += 1
        rgb = rgb.copy()
        rgb[self.outside] = 0  # the served images are black outside the lens
        return rgb


def _preparer(
    model: TrainedModel,
    footage: Footage,
    input_format: str,
    camera: str | None,
    camera_name: str | None,
    allow: bool,
) -> _Preparer:
    """Check that the model's camera serves every frame (headers only) and return the frame preparer."""
    if input_format == "erp":
        raise ConfigError(
            "input_format=erp: equirectangular panoramas are not supported yet; render them into the model's "
            f"lens ({camera_label(model.camera)}) first"
        )
    problem = _camera_problem(model.camera, footage, camera, camera_name)
    if problem is not None:
        message, fix = problem
        if not allow:
            raise ConfigError(f"{message}; {fix}")
        log.warning(
            "%s (allow_camera_mismatch=true: frames are resized to %dx%d, the model's size)",
            message,
            model.camera.width,
            model.camera.height,
        )
    return _Preparer(model)


def _camera_problem(
    model_camera: CameraModel, footage: Footage, camera: str | None, camera_name: str | None
) -> tuple[str, str] | None:
    """The first reason the model's camera cannot serve the footage, and how to fix it; ``None`` when it can.

    Without ``camera`` the footage is taken to be of the model's lens: its frames must be the model's size. With
    ``camera`` the frames must be that lens's size, and the lens, scaled to the model's size, the model's camera.
    """
    size = (model_camera.width, model_camera.height)
    resize = f"allow_camera_mismatch=true to predict anyway (frames resized to {size[0]}x{size[1]})"
    lens = None
    if camera is not None:
        try:
            lens = load_camera(camera, camera_name, option="camera_name")
        except FileNotFoundError:
            raise MissingFileError(f"camera={camera}: no such calibration file") from None
        except ValueError as err:
            raise ConfigError(f"camera={camera}: {err}") from None
        mismatch = camera_mismatch(model_camera, _scaled(lens, size))
        if mismatch is not None:
            return (f"camera={camera} is not the lens the model was trained for: {mismatch}", resize)
    expected = (lens.width, lens.height) if lens is not None else size
    owner = f"camera={camera}" if lens is not None else f"the model's camera ({camera_label(model_camera)})"
    for name, (width, height) in footage.sizes():
        if (width, height) != expected:
            panorama = (
                " (a 2:1 frame: an equirectangular panorama? input_format=erp)" if width == 2 * height else ""
            )
            fix = (
                resize
                if lens is not None
                else f"give camera=<its calibration file> if it is this lens at another size, or {resize}"
            )
            return (
                f"input frame {name} is {width}x{height} but {owner} takes {expected[0]}x{expected[1]} images"
                f"{panorama}",
                fix,
            )
    return None


def _scaled(lens: CameraModel, size: tuple[int, int]) -> CameraModel:
    """``lens`` seen at ``size`` when its aspect ratio allows, else ``lens`` (which then differs in size)."""
    if lens.width * size[1] != lens.height * size[0]:
        return lens
    return lens.resized(*size)


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
        self.legend = self._legend()
        self._tmp: Path | None = None

    def __enter__(self) -> _Writer:
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
        panel = make_panel([tiles], titles=titles, legends=[self.legend(len(tiles))])
        save_png(self._tmp / "preview" / f"{name}.png", panel)

    def _legend(self):
        width_of = lambda tiles: tiles * (self.model.camera.width + 2) - 2  # noqa: E731  (make_panel's gap)
        if self.labels:
            classes = list(zip(self.model.class_names or [], self.model.palette.tolist(), strict=False))
            return lambda tiles: class_legend(width_of(tiles), classes)
        return lambda tiles: depth_colorbar(width_of(tiles), self.model.max_depth)

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
                "preview": "input | prediction",
            },
            **({"class_names": self.model.class_names} if self.labels else {}),
            **record,
        }
        atomic_write_text(self._tmp / "predict.json", json.dumps(meta, indent=2, default=str) + "\n")
        self._tmp.rename(self.out)
        self._tmp = None

    def __exit__(self, exc_type, exc, tb) -> None:
        if self._tmp is not None:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None


class _Progress:
    """A progress bar in a terminal; otherwise a log line at every tenth of the frames (``progress.py``'s rule)."""

    def __init__(self, total: int | None, enabled: bool) -> None:
        self.total, self.enabled, self.done = total, enabled, 0
        self.started = time.monotonic()
        self.bar = None
        if enabled and console_is_terminal():
            self.bar = tqdm(total=total, desc="predict", unit="frame", dynamic_ncols=True)
        self.step = max(1, (total or 10) // 10)

    def update(self, n: int) -> None:
        before, self.done = self.done, self.done + n
        if self.bar is not None:
            self.bar.update(n)
        elif self.enabled and before // self.step != self.done // self.step:
            seconds = time.monotonic() - self.started
            where = f"predict frame {self.done}/{self.total or '?'}"
            log.info(progress_line(where, {"frames/s": self.done / max(seconds, 1e-9)}, seconds))

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
