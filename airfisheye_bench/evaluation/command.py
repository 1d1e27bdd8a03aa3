"""``python scripts/evaluate.py``: evaluate a checkpoint, an ONNX model or a prediction folder on a split.

Exactly one source is given:

- ``ckpt_path=`` a Lightning checkpoint or a run directory (its best checkpoint);
- ``onnx_path=`` a model written by ``scripts/export_onnx.py``;
- ``predictions=`` a folder of prediction files (see :mod:`airfisheye_bench.evaluation.submission`).

The data configuration is the one the model was trained with (the run's ``config.yaml``, or the ONNX metadata),
so the model sees the camera it expects; ``data.*`` overrides on the command line still apply on top. A
prediction folder is evaluated with the ``data`` group of ``configs/evaluate.yaml`` (synthetic ``quickstart`` by
default). ``tta=flip`` averages a checkpoint's or ONNX model's prediction with the mirrored prediction of the
mirrored input (:func:`~airfisheye_bench.evaluation.predictors.flip_tta`). The output folder receives
``results.json`` (the leaderboard format; ``model`` records the weights the model started from and the TTA) and
``panels/``; the table is printed.
"""

from __future__ import annotations

import contextlib
import json
import logging
from functools import partial
from pathlib import Path
from typing import Any

import torch
from omegaconf import DictConfig, OmegaConf, open_dict

from airfisheye_bench.config_checks import check_common_values
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.evaluation.evaluator import EvaluationResult, evaluate_predictions, format_results_table
from airfisheye_bench.evaluation.predictors import (
    CheckpointPredictor,
    FilePredictor,
    OnnxPredictor,
    Predictor,
)
from airfisheye_bench.evaluation.results import PRIMARY_METRIC, dataset_identity, write_results
from airfisheye_bench.evaluation.submission import SubmissionWriter
from airfisheye_bench.io.deployment import read_deployment_metadata
from airfisheye_bench.metrics import DEFAULT_DEPTH_EDGES_M
from airfisheye_bench.metrics.scorer import TaskScorer, task_metric
from airfisheye_bench.runs import resolve_checkpoint, run_config
from airfisheye_bench.tasks.checkpoint import load_task
from airfisheye_bench.viz import make_panel, save_png
from datamodules.config import apply_data_overrides, instantiate_datamodule, parse_data_overrides

log = logging.getLogger(__name__)

__all__ = ["evaluate"]

_SOURCES = ("ckpt_path", "onnx_path", "predictions")


def evaluate(cfg: DictConfig, data_overrides: list[str] | None = None) -> dict[str, Any]:
    """Evaluate the configured source and write ``results.json`` and panels to ``cfg.output_dir``.

    Args:
        cfg: The composed ``configs/evaluate.yaml``.
        data_overrides: ``data.key=value`` strings applied on top of a checkpoint's or ONNX model's own data
            configuration (the command line's ``data.*`` overrides).

    Returns:
        The ``results.json`` record.
    """
    given = [key for key in _SOURCES if cfg.get(key)]
    if len(given) != 1:
        raise ConfigError(
            f"give exactly one of ckpt_path=<.ckpt or run dir>, onnx_path=<.onnx>, predictions=<dir>; got {given or 'none'}"
        )
    source = given[0]
    if cfg.split not in ("val", "test"):
        raise ConfigError(f"split must be 'val' or 'test', got {cfg.split!r}")

    module, checkpoint, source_data = None, None, None
    task = cfg.task.name if cfg.get("task") else None
    if source == "ckpt_path":
        checkpoint = resolve_checkpoint(cfg.ckpt_path)
        module = load_task(checkpoint)
        run = run_config(checkpoint)
        source_data = run.data if run is not None else None
        task = _agree(task, module.task, f"checkpoint {checkpoint}")
    elif source == "onnx_path":
        metadata = read_deployment_metadata(cfg.onnx_path)
        source_data = OmegaConf.create(metadata["data_config"]) if metadata.get("data_config") else None
        task = _agree(task, metadata["task"], f"ONNX model {cfg.onnx_path}")
    elif task is None:
        raise ConfigError("predictions=DIR needs task=seg|depth|completion")
    if task not in PRIMARY_METRIC:
        raise ConfigError(f"task must be one of {sorted(PRIMARY_METRIC)}, got {task!r}")

    with open_dict(cfg):
        if not cfg.get("task"):
            cfg.task = {"name": task}
        cfg.data.task = task
    datamodule, data_config = _datamodule(cfg, task, source_data, data_overrides or [])
    dataset = datamodule.split_dataset(cfg.split)
    camera = datamodule.camera
    predictor = _predictor(cfg, source, task, module, checkpoint, dataset, camera)

    max_depth = float(data_config.get("max_depth", 120.0))
    if module is not None:
        factory = module.make_metric  # the checkpoint's own evaluation bounds
    else:
        class_names = datamodule.class_names if task == "seg" else None
        factory = partial(task_metric, task, class_names=class_names, max_depth=max_depth)
    scorer = TaskScorer(factory, depth_edges_m=None if task == "seg" else DEFAULT_DEPTH_EDGES_M)
    theta = torch.rad2deg(camera.theta_grid()).float()

    output_dir = Path(cfg.output_dir)
    writer = _prediction_writer(cfg, source, task)
    with writer or contextlib.nullcontext():
        result = evaluate_predictions(
            predictor,
            dataset,
            scorer,
            theta,
            batch_size=cfg.batch_size,
            num_workers=cfg.num_workers,
            num_panels=cfg.num_panels,
            palette=datamodule.palette if task == "seg" else None,
            max_depth=max_depth,
            on_batch=writer.add_batch if writer else None,
        )
    record = _write(cfg, output_dir, task, datamodule, data_config, predictor, result)
    print(format_results_table(task, result, PRIMARY_METRIC[task]))
    print(f"\n{result.num_frames} frames in {result.seconds:.1f} s; results: {output_dir / 'results.json'}")
    return record


def _agree(requested: str | None, found: str, what: str) -> str:
    if requested and requested != found:
        raise ConfigError(
            f"task={requested} was requested but {what} is a {found} model; drop task= or fix it"
        )
    return found


def _datamodule(
    cfg: DictConfig, task: str, source_data: DictConfig | None, overrides: list[str]
) -> tuple[Any, dict[str, Any]]:
    """The datamodule to evaluate on, and its configuration (recorded in ``results.json``)."""
    if source_data is not None:  # the model's own data config, command-line data.* on top
        data = apply_data_overrides(source_data, parse_data_overrides(overrides), task=task)
    else:  # configs/evaluate.yaml's data group, overrides already composed in by Hydra
        data = apply_data_overrides(cfg.data, task=task)
    check_common_values(OmegaConf.create({"data": data}))  # the run's values with the command line's on top
    data.num_workers = 0  # the evaluation loop makes its own loader (cfg.num_workers)
    data.persistent_workers = False
    return instantiate_datamodule(data), OmegaConf.to_container(data)


def _predictor(
    cfg: DictConfig, source: str, task: str, module, checkpoint: Path | None, dataset, camera
) -> Predictor:
    tta = cfg.get("tta")
    if source == "ckpt_path":
        device = cfg.device if cfg.device != "auto" else ("cuda" if torch.cuda.is_available() else "cpu")
        return CheckpointPredictor(module, checkpoint, device=device, tta=tta)
    if source == "onnx_path":
        predictor = OnnxPredictor(cfg.onnx_path, threads=cfg.get("threads"), tta=tta)
        size = predictor.fixed_size
        if size is not None and size != (camera.height, camera.width):
            raise ConfigError(
                f"ONNX model {cfg.onnx_path} takes {size[0]}x{size[1]} images but the data serves "
                f"{camera.height}x{camera.width}; drop the data.camera overrides (or export with dynamic_spatial=true)"
            )
        return predictor
    if tta is not None:
        raise ConfigError("tta= only applies to ckpt_path= or onnx_path= (prediction files are final)")
    return FilePredictor(
        cfg.predictions, task, list(dataset.sample_ids), (camera.height, camera.width), name=cfg.get("name")
    )


def _prediction_writer(cfg: DictConfig, source: str, task: str) -> SubmissionWriter | None:
    if not cfg.get("save_predictions"):
        return None
    if source == "predictions":
        raise ConfigError(
            "save_predictions= only applies to ckpt_path= or onnx_path= (predictions are files already)"
        )
    return SubmissionWriter(cfg.save_predictions, task, depth_format=cfg.prediction_format)


def _write(
    cfg: DictConfig,
    output_dir: Path,
    task: str,
    datamodule,
    data_config: dict[str, Any],
    predictor: Predictor,
    result: EvaluationResult,
) -> dict[str, Any]:
    panels = output_dir / "panels"
    for sample_id, tiles in result.panels:
        save_png(panels / f"{sample_id.replace('/', '_')}.png", make_panel([tiles]))
    identity = predictor.identity()
    if cfg.get("name"):
        identity["run_name"] = cfg.name  # the leaderboard's run label; "name" stays the architecture
    split_name = datamodule.split_names[("train", "val", "test").index(cfg.split)]
    path = write_results(
        output_dir / "results.json",
        task=task,
        split=split_name,
        metrics=result.metrics,
        breakdown=result.breakdown,
        dataset=dataset_identity(datamodule.dataset_root(), datamodule.split_dataset(cfg.split).spec.name),
        model=identity,
        config={
            # The task group's training settings (optimiser, model defaults) play no part in evaluation.
            "evaluation": {
                k: OmegaConf.to_container(v, resolve=True) if isinstance(v, DictConfig) else v
                for k, v in cfg.items()
                if k not in ("task", "model", "trainer", "data", "paths")
            },
            "data": data_config,
            "camera": datamodule.camera.to_dict(),
            "num_frames": result.num_frames,
            "seconds": round(result.seconds, 3),
        },
    )
    return json.loads(path.read_text())
