"""A trained model with what it takes to feed it and to draw its output, from a checkpoint or an ONNX file.

:func:`load_trained` is what ``airfisheye-predict`` runs on footage: the evaluation's predictors
(:class:`~airfisheye_bench.evaluation.predictors.CheckpointPredictor`,
:class:`~airfisheye_bench.evaluation.predictors.OnnxPredictor`) with the camera the model was trained for, the input
normalisation, the class names and colours (seg) and the depth range (depth, completion).

An ONNX model carries all of it in its metadata (:mod:`airfisheye_bench.runs.deployment`). A checkpoint carries the
model, its classes, palette and depth range; its camera is the one its run's data config serves
(:func:`run_datamodule`: the run's ``config.yaml``, and the dataset it names, whose calibration the camera is
resolved against), as for ``airfisheye-evaluate`` and ``airfisheye-export``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from omegaconf import DictConfig, OmegaConf

from airfisheye_bench.config_checks import check_common_values
from airfisheye_bench.errors import ConfigError, InputFileError
from airfisheye_bench.evaluation.perspective import perspective_predictor
from airfisheye_bench.evaluation.predictors import CheckpointPredictor, OnnxPredictor, Predictor
from airfisheye_bench.geometry.cameras import CameraModel, camera_from_dict
from airfisheye_bench.runs import resolve_checkpoint, run_config
from airfisheye_bench.runs.deployment import read_deployment_metadata
from airfisheye_bench.specs import get_task
from airfisheye_bench.tasks.checkpoint import load_task
from datamodules.config import apply_data_overrides, instantiate_datamodule

__all__ = ["TrainedModel", "load_trained", "run_datamodule", "through_views"]


@dataclass(frozen=True)
class TrainedModel:
    """A model ready to predict frames of its camera.

    Attributes:
        predictor: Called with a batch (``image`` normalised ``[B, 3, H, W]``, ``sparse_depth`` for completion,
            ``rays`` ``[B, 4, H, W]`` for a camera-aware model: :attr:`takes_rays`).
        task: ``seg``, ``depth`` or ``completion``.
        camera: The camera the model was trained for (its input size is the camera's).
        mean: Normalisation mean of ``rgb / 255``, RGB.
        std: Normalisation standard deviation, RGB.
        class_names: Training class names in id order (tasks with classes), else ``None``.
        palette: ``uint8 [N, 3]`` colours by class id (tasks with classes), else ``None``.
        max_depth: Far end of the depth range in metres (the colour map's too).
        path: The checkpoint or ONNX file.
    """

    predictor: Predictor
    task: str
    camera: CameraModel
    mean: tuple[float, float, float]
    std: tuple[float, float, float]
    class_names: list[str] | None
    palette: np.ndarray | None
    max_depth: float
    path: Path

    @property
    def inputs(self) -> tuple[str, ...]:
        """The model's inputs by name (``image``, then e.g. ``sparse_depth``; the ray map apart: :attr:`takes_rays`)."""
        return tuple(get_task(self.task).inputs)

    @property
    def takes_rays(self) -> bool:
        """Whether the predictor takes the ray map of :attr:`camera` as the batch's ``rays`` (a camera-aware model
        whose map is not baked into its file)."""
        return bool(getattr(self.predictor, "takes_rays", False))


def load_trained(
    path: str | Path, device: str = "auto", threads: int | None = None, tta: str | None = None
) -> TrainedModel:
    """The model of a run directory, a ``.ckpt`` file or an ``.onnx`` file (by its suffix), with its camera.

    Args:
        path: A run directory or checkpoint (:func:`~airfisheye_bench.runs.resolve_checkpoint`), or an ONNX model
            written by ``airfisheye-export``.
        device: Checkpoint inference: ``auto`` (cuda if available), ``cpu`` or ``cuda``.
        threads: ONNX Runtime intra-op threads (``None``: its default).
        tta: Test-time augmentation of the predictors (``None`` or ``flip``).

    Raises:
        MissingFileError: no such file or run directory.
        InputFileError: not a checkpoint or ONNX model of this project, or a checkpoint without its run's config.
        ConfigError: the run's data config is not one this model's camera can be found from.
    """
    path = Path(path).expanduser()
    if path.suffix.lower() == ".onnx":
        return _from_onnx(path, threads, tta)
    checkpoint = resolve_checkpoint(path)
    module = load_task(checkpoint)
    run = run_config(checkpoint)
    if run is None or "data" not in run:
        raise InputFileError(
            f"{checkpoint}: no config.yaml with a 'data' section in its run directory, so the camera the model was "
            "trained for is unknown; keep the checkpoint inside its run directory, or give its exported .onnx"
        )
    if run.data.get("sources"):
        raise InputFileError(
            f"{checkpoint}: its run was trained on several sources (data.sources={list(run.data.sources)}), each "
            "served with its own camera, so which one the footage has is unknown; give an .onnx exported for one"
        )
    datamodule = run_datamodule(apply_data_overrides(run.data, task=module.task))
    device = device if device != "auto" else ("cuda" if torch.cuda.is_available() else "cpu")
    classes = list(module.class_names) if get_task(module.task).uses_classes else None
    # The checkpoint's colours, else the dataset's (as the export's metadata).
    palette = (module.hparams.get("palette") or datamodule.palette[: len(classes)]) if classes else None
    return TrainedModel(
        predictor=CheckpointPredictor(module, checkpoint, device=device, tta=tta),
        task=module.task,
        camera=datamodule.camera,
        mean=tuple(datamodule.normalization["mean"]),
        std=tuple(datamodule.normalization["std"]),
        class_names=classes,
        palette=np.asarray(palette, np.uint8) if palette is not None else None,
        max_depth=float(module.max_depth),
        path=checkpoint,
    )


def through_views(
    model: TrainedModel, fisheye: CameraModel, views: Any, view_depth: str = "range"
) -> TrainedModel:
    """A perspective ``model`` run on images of ``fisheye`` through ``views`` (``views=``:
    :func:`~airfisheye_bench.evaluation.perspective.perspective_predictor`): its camera is then the fisheye, its
    predictor renders each frame into the views and resamples the outputs back. Views that leave some of the
    fisheye unseen are allowed here (those pixels get no prediction: 0, or 255 for labels)."""
    predictor = perspective_predictor(
        model.predictor,
        fisheye,
        model.camera,
        views,
        view_depth,
        what=str(model.path),
        require_coverage=False,
    )
    return replace(model, predictor=predictor, camera=fisheye)


def run_datamodule(data: DictConfig) -> Any:
    """The datamodule of a resolved ``data`` config (a run's, an ONNX model's or the evaluation's), for one process.

    ``data`` is checked (:func:`~airfisheye_bench.config_checks.check_common_values`) and its loader settings are
    set in place for a loop that makes its own loader (no workers).

    Raises:
        ConfigError: a value of the config, or several sources (each has its own dataset and camera).
    """
    check_common_values(OmegaConf.create({"data": data}))  # the run's values with the command line's on top
    # One dataset at a time: a run's per-source scores at the end of training are in its results.json.
    if data.get("sources"):
        raise ConfigError(
            f"data.sources={list(data.sources)}: evaluation scores one dataset; add data.sources=null with that "
            "source's data.root (and data.format) or data.preset (docs/design.md: More than one source)"
        )
    data.num_workers = 0  # the evaluation loop makes its own loader
    data.persistent_workers = False
    return instantiate_datamodule(data)


def _from_onnx(path: Path, threads: int | None, tta: str | None) -> TrainedModel:
    metadata = read_deployment_metadata(path)
    predictor = OnnxPredictor(path, threads=threads, tta=tta)
    classes = metadata.get("class_names")
    palette = metadata.get("palette")
    return TrainedModel(
        predictor=predictor,
        task=metadata["task"],
        camera=camera_from_dict(metadata["camera"]),
        mean=tuple(metadata["normalization"]["mean"]),
        std=tuple(metadata["normalization"]["std"]),
        class_names=list(classes) if classes is not None else None,
        palette=np.asarray(palette, np.uint8) if palette is not None else None,
        max_depth=float(metadata.get("max_depth", 120.0)),
        path=path,
    )
