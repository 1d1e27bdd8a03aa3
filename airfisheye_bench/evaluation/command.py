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
``results.json`` (the leaderboard format; ``model`` records what was evaluated, the training run, the weights
the model started from and the TTA) and ``panels/`` (frames spread over the split, titled columns, depth colour
bars in metres); the table is printed and written to the command's log (``evaluate.log``).

``views=cube`` (or a list of ``[yaw, pitch]`` views) scores a perspective model (one trained with
``data.camera.model=pinhole``) on the fisheye: the data config is the model's with the camera group back to the
release's lens at the model's size (``data.camera.*`` on top), each fisheye image is rendered into the views at the
model's own camera, and the outputs are resampled back (:mod:`~airfisheye_bench.evaluation.perspective`;
``view_depth=z`` for a model whose depth is z along its axis). ``results.json`` records the views under
``model.views``. Without ``views=`` such a model is scored on its own views, as any model on its own camera.
"""

from __future__ import annotations

import contextlib
import json
import logging
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import torch
from omegaconf import DictConfig, ListConfig, OmegaConf, open_dict

from airfisheye_bench.config_checks import ValueRule, check_common_values
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.evaluation.cross_lens import (
    TestLens,
    cross_lens_gap,
    largest_changes,
    lens_data_config,
    parse_test_lenses,
    robustness_lenses,
)
from airfisheye_bench.evaluation.evaluator import EvaluationResult, evaluate_predictions
from airfisheye_bench.evaluation.perspective import perspective_predictor
from airfisheye_bench.evaluation.predictors import (
    TTA_MODES,
    CheckpointPredictor,
    FilePredictor,
    OnnxPredictor,
    Predictor,
)
from airfisheye_bench.evaluation.submission import DEPTH_FORMATS, SubmissionWriter
from airfisheye_bench.evaluation.trained import run_datamodule
from airfisheye_bench.geometry.cameras import CameraModel, camera_from_dict
from airfisheye_bench.geometry.perspective_views import DEPTH_CONVENTIONS, views_problem
from airfisheye_bench.io.calibration_files import camera_mismatch
from airfisheye_bench.io.layout import trajectory_of
from airfisheye_bench.metrics import DEFAULT_DEPTH_EDGES_M, DEFAULT_RING_EDGES_DEG, ring_edges_for
from airfisheye_bench.metrics.scorer import TaskScorer
from airfisheye_bench.runs import checkpoint_run_name, resolve_checkpoint, run_config, run_directory
from airfisheye_bench.runs.deployment import read_deployment_metadata
from airfisheye_bench.runs.results import dataset_identity, format_results_table, write_results
from airfisheye_bench.specs import UnknownTaskError, get_task, task_names
from airfisheye_bench.sweeps import run_sweep_overrides
from airfisheye_bench.tasks.checkpoint import load_task
from airfisheye_bench.tracking import log_to_run, resolve_run
from airfisheye_bench.viz import save_png, task_panel
from datamodules.config import apply_data_overrides, parse_data_overrides
from datamodules.coverage import input_coverage

log = logging.getLogger(__name__)

__all__ = ["evaluate"]

_SOURCES = ("ckpt_path", "onnx_path", "predictions")
SPLITS = ("val", "test")
DEVICES = ("auto", "cpu", "cuda")

EVALUATE_RULES: dict[str, ValueRule] = {
    "split": ValueRule("choice", choices=SPLITS),
    "device": ValueRule("choice", choices=DEVICES, hint="checkpoint inference; auto: cuda if available"),
    "tta": ValueRule("choice", choices=[m for m in TTA_MODES if m], nullable=True, hint="null: none"),
    "prediction_format": ValueRule("choice", choices=DEPTH_FORMATS, hint="of saved depth predictions"),
    "num_panels": ValueRule("int", minimum=0),
    "threads": ValueRule("int", minimum=1, nullable=True, hint="null: ONNX Runtime's default"),
    "allow_camera_mismatch": ValueRule("bool", hint="score an ONNX model on data served with another camera"),
    "robustness": ValueRule(
        "bool", hint="score the trained lens with its intrinsics perturbed (cross_lens.py)"
    ),
    "views": ValueRule(
        "custom", check=views_problem, nullable=True, hint="a perspective model through views of the fisheye"
    ),
    "view_depth": ValueRule(
        "choice", choices=DEPTH_CONVENTIONS, hint="what the views' depth output measures"
    ),
}
"""``evaluate.yaml``'s own options (the common keys are :data:`airfisheye_bench.config_checks.RULES`)."""


def evaluate(
    cfg: DictConfig,
    data_overrides: list[str] | None = None,
    before_writing: Callable[[], None] | None = None,
) -> dict[str, Any]:
    """Evaluate the configured source and write ``results.json`` and panels to ``cfg.output_dir``.

    Args:
        cfg: The composed ``configs/evaluate.yaml``.
        data_overrides: ``data.key=value`` strings applied on top of a checkpoint's or ONNX model's own data
            configuration (the command line's ``data.*`` overrides).
        before_writing: Called once the evaluation succeeded, before anything is written to ``cfg.output_dir``
            (the command opens its ``evaluate.log`` there: a refused or failed evaluation writes nothing).

    Returns:
        The ``results.json`` record.
    """
    check_common_values(cfg, EVALUATE_RULES)
    given = [key for key in _SOURCES if cfg.get(key)]
    if len(given) != 1:
        raise ConfigError(
            f"give exactly one of ckpt_path=<.ckpt or run dir>, onnx_path=<.onnx>, predictions=<dir>; got {given or 'none'}"
        )
    source = given[0]
    tests = _test_lenses(cfg, source)

    module, checkpoint, source_data = None, None, None
    camera_input = None  # what the evaluated model takes of the camera (None: no model, prediction files)
    task = cfg.task.name if cfg.get("task") else None
    if source == "ckpt_path":
        checkpoint = resolve_checkpoint(cfg.ckpt_path)
        module = load_task(checkpoint)
        run = run_config(checkpoint)
        source_data = run.data if run is not None else None
        task = _agree(task, module.task, f"checkpoint {checkpoint}")
        camera_input = module.camera_input
    elif source == "onnx_path":
        metadata = read_deployment_metadata(cfg.onnx_path)
        source_data = OmegaConf.create(metadata["data_config"]) if metadata.get("data_config") else None
        task = _agree(task, metadata["task"], f"ONNX model {cfg.onnx_path}")
        camera_input = "rays" if "rays" in metadata["inputs"] else "none"  # a baked ray map needs none
    elif task is None:
        raise ConfigError(f"predictions=DIR needs task={'|'.join(task_names())}")
    try:
        spec = get_task(task)
    except UnknownTaskError as err:
        raise ConfigError(f"task: {err}") from None

    with open_dict(cfg):
        if not cfg.get("task"):
            cfg.task = {"name": task}
        cfg.data.task = task
    views = cfg.get("views")
    model_camera = None
    if views is not None:  # a perspective model on the fisheye: its own camera, the fisheye served instead
        if source == "predictions":
            raise ConfigError("views= runs a perspective model on the fisheye: give ckpt_path= or onnx_path=")
        views = OmegaConf.to_container(views) if isinstance(views, ListConfig) else views
        model_camera = (
            camera_from_dict(metadata["camera"])
            if source == "onnx_path"
            else _checkpoint_camera(checkpoint, source_data, task)
        )
        source_data = fisheye_data(source_data)
    datamodule, data_config = _datamodule(cfg, task, source_data, data_overrides or [], camera_input)
    camera = datamodule.camera
    inner = _predictor(
        cfg, source, task, module, checkpoint, datamodule.split_dataset(cfg.split), model_camera or camera
    )
    what = f"ONNX model {cfg.onnx_path}" if source == "onnx_path" else f"checkpoint {checkpoint}"

    def predictor_for(served: CameraModel) -> Predictor:
        """The model on data served through ``served``: through perspective views of it with ``views=``."""
        if views is None:
            return inner
        return perspective_predictor(inner, served, model_camera, views, cfg.view_depth, what)

    predictor = predictor_for(camera)
    if views is None and source == "onnx_path":  # after the image-size check, which no flag can waive
        _check_camera(cfg, metadata["camera"], camera)

    max_depth = float(data_config.get("max_depth", 120.0))
    if module is not None:
        factory = module.make_metric  # the checkpoint's own evaluation bounds
    else:
        class_names = datamodule.class_names if spec.uses_classes else None
        factory = partial(spec.make_metric, class_names=class_names, max_depth=max_depth)
    rings = module.hparams.ring_edges_deg if module is not None else DEFAULT_RING_EDGES_DEG
    score = partial(
        _score, cfg, predictor_for, factory, rings, spec, max_depth=max_depth, grouped=bool(tests)
    )

    output_dir = Path(cfg.output_dir)
    writer = _prediction_writer(cfg, source, task)
    with writer or contextlib.nullcontext():
        result = score(datamodule, num_panels=cfg.num_panels, on_batch=writer.add_batch if writer else None)
    cross_lens = (
        _cross_lens(cfg, tests, task, spec, score, data_config, datamodule, result, model_camera)
        if tests
        else None
    )
    if before_writing is not None:
        before_writing()
    record = _write(cfg, output_dir, task, datamodule, data_config, predictor, result, cross_lens)
    summary = "\n".join(
        [
            format_results_table(task, result.metrics, result.breakdown, spec.primary_metric),
            f"\n{result.num_frames} frames in {result.seconds:.1f} s; results: {output_dir / 'results.json'}",
        ]
    )
    print(summary)
    _to_log_files(summary)
    if cfg.get("mlflow_run"):
        _log_to_mlflow(cfg, output_dir, record)
    return record


def _log_to_mlflow(cfg: DictConfig, output_dir: Path, record: dict[str, Any]) -> None:
    """Log the scores, ``results.json`` and panels to the MLflow run ``mlflow_run=`` names (``auto``: the one the
    evaluated weights were trained in), under ``evaluate/<what>/<split>/``: ``<what>`` is ``name=``, else
    ``checkpoint`` or the ONNX file's stem, with ``_flip`` for flip TTA."""
    model = record["model"]
    source = model.get("checkpoint") or model.get("source_checkpoint")
    uri, run_id = resolve_run(
        str(cfg.mlflow_run), run_directory(source) if source else None, cfg.get("mlflow_tracking_uri")
    )
    what = cfg.get("name") or (Path(cfg.onnx_path).stem if cfg.get("onnx_path") else str(model.get("source")))
    prefix = f"evaluate/{what}{'_' + cfg.tta if cfg.get('tta') else ''}/{cfg.split}"
    artifacts = {f"{prefix}/results.json": output_dir / "results.json"}
    if (output_dir / "panels").is_dir():
        artifacts[f"{prefix}/panels"] = output_dir / "panels"
    metrics = {f"{prefix}/{key}": value for key, value in record["metrics"].items()}
    log_to_run(uri, run_id, metrics=metrics, artifacts=artifacts)
    log.info("logged to MLflow run %s (%s) under %s/", run_id, uri, prefix)


def _to_log_files(text: str) -> None:
    """Write the printed table to the command's log files (Hydra's ``evaluate.log``), not to the console again."""
    record = log.makeRecord(log.name, logging.INFO, __file__, 0, text, None, None)
    for handler in logging.getLogger().handlers:
        if isinstance(handler, logging.FileHandler):
            handler.handle(record)


def _agree(requested: str | None, found: str, what: str) -> str:
    if requested and requested != found:
        raise ConfigError(
            f"task={requested} was requested but {what} is a {found} model; drop task= or fix it"
        )
    return found


def _datamodule(
    cfg: DictConfig,
    task: str,
    source_data: DictConfig | None,
    overrides: list[str],
    camera_input: str | None = None,
) -> tuple[Any, dict[str, Any]]:
    """The datamodule to evaluate on, and its configuration (recorded in ``results.json``); it serves the ray map
    of each frame's lens when the model takes it (``camera_input``, the model's: not a data config's)."""
    if source_data is not None:  # the model's own data config, command-line data.* on top
        data = apply_data_overrides(source_data, parse_data_overrides(overrides), task=task)
    else:  # configs/evaluate.yaml's data group, overrides already composed in by Hydra
        data = apply_data_overrides(cfg.data, task=task)
    if camera_input is not None:
        data.camera_input = camera_input
    datamodule = run_datamodule(data)
    return datamodule, OmegaConf.to_container(data)


def _checkpoint_camera(checkpoint: Path, run_data: DictConfig | None, task: str) -> CameraModel:
    """The camera a checkpoint was trained for: what its run's data config serves."""
    if run_data is None:
        raise ConfigError(
            f"views= needs the camera {checkpoint} was trained for, from its run's config.yaml: keep the checkpoint "
            "inside its run directory, or give its exported .onnx"
        )
    return run_datamodule(apply_data_overrides(run_data, task=task)).camera


def fisheye_data(model_data: DictConfig | None) -> DictConfig | None:
    """A perspective model's data config serving the dataset's fisheye instead of its views: the camera group back
    to its defaults (the release's lens) at the model's image size; ``data.camera.*`` on the command line apply on
    top. ``None`` stays ``None`` (the evaluation's own data group)."""
    if model_data is None:
        return None
    data = OmegaConf.create(OmegaConf.to_container(model_data, resolve=True))
    data.camera = {"size": model_data.get("camera", {}).get("size")}
    return data


def _check_camera(cfg: DictConfig, model_camera: dict[str, Any], served) -> None:
    """Refuse to score an ONNX model on data served with another camera than the one it was exported for."""
    mismatch = camera_mismatch(model_camera, served)
    if mismatch is None:
        return
    message = f"ONNX model {cfg.onnx_path} was exported for another camera than the data serves: {mismatch}"
    if cfg.get("allow_camera_mismatch"):
        log.warning("%s (allow_camera_mismatch=true: scoring anyway)", message)
        return
    raise ConfigError(
        f"{message}; drop the data.camera overrides, or pass allow_camera_mismatch=true to score it anyway"
    )


def _predictor(
    cfg: DictConfig, source: str, task: str, module, checkpoint: Path | None, dataset, camera
) -> Predictor:
    """The predictor of the source; ``camera`` is what the model is fed (the served one, or its views')."""
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


def _run_name(identity: dict[str, Any]) -> str:
    """The training run of the evaluated weights (an ONNX model's source checkpoint), else the file's name."""
    checkpoint = identity.get("checkpoint") or identity.get("source_checkpoint")
    if checkpoint:
        return checkpoint_run_name(checkpoint)
    return Path(identity.get("onnx") or identity.get("predictions") or "unnamed").name


def _sweep_overrides(identity: dict[str, Any]) -> list[str]:
    """What a multirun's sweep chose for the training run of the evaluated weights, when that run is here."""
    checkpoint = identity.get("checkpoint") or identity.get("source_checkpoint")
    run = run_directory(checkpoint) if checkpoint else None
    return run_sweep_overrides(run) if run is not None else []


def _write(
    cfg: DictConfig,
    output_dir: Path,
    task: str,
    datamodule,
    data_config: dict[str, Any],
    predictor: Predictor,
    result: EvaluationResult,
    cross_lens: dict[str, Any] | None = None,
) -> dict[str, Any]:
    panels = output_dir / "panels"
    max_depth = float(data_config.get("max_depth", 120.0))  # the depth colour bar's far end, as the tiles
    classes = []  # segmentation: the key of the label colours
    if get_task(task).uses_classes:
        names = list(datamodule.class_names)
        classes = list(zip(names, np.asarray(datamodule.palette)[: len(names)].tolist(), strict=True))
    for sample_id, tiles in result.panels:
        panel = task_panel(task, [tiles], max_depth=max_depth, classes=classes)
        save_png(panels / f"{sample_id.replace('/', '_')}.png", panel)
    identity = predictor.identity()
    # The leaderboard's run label ("name" stays the architecture): the name given, else the training run.
    identity["run_name"] = cfg.get("name") or _run_name(identity)
    if chosen := _sweep_overrides(identity):  # the weights come from a job of a sweep: what it chose
        identity["sweep_overrides"] = chosen
    split_name = datamodule.split_names[("train", "val", "test").index(cfg.split)]
    path = write_results(
        output_dir / "results.json",
        task=task,
        split=split_name,
        metrics=result.metrics,
        breakdown=result.breakdown,
        dataset=dataset_identity(datamodule.dataset_root(), datamodule.split_dataset(cfg.split).spec.name),
        sparse_coverage=input_coverage(datamodule.split_dataset(cfg.split), task),
        model=identity,
        config={
            # The task group's training settings (optimiser, model defaults) play no part in evaluation.
            "evaluation": {
                k: OmegaConf.to_container(v, resolve=True) if isinstance(v, DictConfig | ListConfig) else v
                for k, v in cfg.items()
                if k not in ("task", "model", "trainer", "data", "paths")
            },
            "data": data_config,
            "camera": datamodule.camera.to_dict(),
            "num_frames": result.num_frames,
            "seconds": round(result.seconds, 3),
        },
        cross_lens=cross_lens,
    )
    return json.loads(path.read_text())


def _test_lenses(cfg: DictConfig, source: str) -> list[TestLens]:
    """``lenses=`` and ``robustness=true`` as test lenses (the robustness row's are added once the trained lens is
    known): ``[]`` for a plain evaluation."""
    try:
        tests = parse_test_lenses(cfg.get("lenses"))
    except ValueError as err:
        raise ConfigError(str(err)) from None
    if cfg.get("robustness") and not any(lens.trained for lens in tests):
        tests.insert(0, TestLens("trained"))
    if tests and source == "predictions":
        raise ConfigError(
            "lenses= / robustness=true score a model on other lenses: they need ckpt_path= or onnx_path= "
            "(prediction files were made for one lens)"
        )
    return tests


def _score(
    cfg: DictConfig,
    predictor_for: Callable[[CameraModel], Predictor],
    factory: Callable[[], Any],
    rings: Any,
    spec: Any,
    datamodule: Any,
    num_panels: int = 0,
    on_batch: Callable[[dict, torch.Tensor], None] | None = None,
    max_depth: float = 120.0,
    grouped: bool = False,
) -> EvaluationResult:
    """Score the model (``predictor_for`` its camera) on the split of ``datamodule``, through its camera (and per
    flight, ``grouped``)."""
    camera = datamodule.camera
    scorer = TaskScorer(
        factory,
        ring_edges_deg=ring_edges_for(camera.coverage_deg, rings),
        depth_edges_m=DEFAULT_DEPTH_EDGES_M if spec.depth_breakdown else None,
    )
    return evaluate_predictions(
        predictor_for(camera),
        datamodule.split_dataset(cfg.split),
        scorer,
        torch.rad2deg(camera.theta_grid()).float(),
        batch_size=cfg.batch_size,
        num_workers=cfg.num_workers,
        num_panels=num_panels,
        palette=datamodule.palette if spec.uses_classes else None,
        max_depth=max_depth,
        on_batch=on_batch,
        group_of=_flight if grouped else None,
        group_metric=factory if grouped else None,
    )


def _flight(sample_id: str) -> str:
    """The flight (trajectory) of a sample: the unit of a cross-lens study's intervals."""
    try:
        return trajectory_of(sample_id)
    except ValueError:  # another dataset's ids: everything before the frame
        return sample_id.rsplit("/", 1)[0]


def _cross_lens(
    cfg: DictConfig,
    tests: list[TestLens],
    task: str,
    spec: Any,
    score: Callable[..., EvaluationResult],
    data_config: dict[str, Any],
    datamodule: Any,
    own: EvaluationResult,
    model_camera: CameraModel | None = None,
) -> dict[str, Any]:
    """Score the model on each test lens (the trained one is ``own``) and, with ``robustness=true``, on the trained
    lens perturbed: the ``cross_lens`` block of ``results.json``. A perspective model (``views=``, ``model_camera``)
    was trained on its own camera alone: ``trained`` is then the data's lens through its views, not one it saw."""
    base = OmegaConf.create(data_config)
    trained = (
        [model_camera]
        if model_camera is not None
        else [lens.camera for lens in datamodule.split_dataset(cfg.split).served_lenses]
    )

    def served(data: DictConfig) -> Any:
        return run_datamodule(apply_data_overrides(data, task=task))

    def row(lens: TestLens, result: EvaluationResult, camera: CameraModel) -> dict[str, Any]:
        log.info(
            "lens %s: %s", lens.name, format_results_table(task, result.metrics, {}, spec.primary_metric)
        )
        return {
            "name": lens.name,
            "lens": lens.spec(),
            "camera": camera.to_dict(),
            "seen": (lens.trained and model_camera is None) or any(_same_camera(camera, t) for t in trained),
            "metrics": result.metrics,
            "gap": _gaps(spec, own.metrics, result.metrics),
            "flights": result.groups,
            "num_frames": result.num_frames,
        }

    rows = []
    for lens in tests:
        if lens.trained:
            rows.append(row(lens, own, datamodule.camera))
            continue
        data = lens_data_config(base, lens.camera) if lens.camera else base
        if lens.perturb is not None:
            data = lens_data_config(base, lens.perturb.apply(served(data).camera))
        module = served(data)
        rows.append(row(lens, score(module), module.camera))
    out: dict[str, Any] = {
        "trained_lenses": [camera.to_dict() for camera in trained],
        "views": OmegaConf.to_container(cfg.views)
        if isinstance(cfg.get("views"), ListConfig)
        else cfg.get("views"),
        "primary_metric": spec.primary_metric,
        "lenses": rows,
    }
    if cfg.get("robustness"):
        out["robustness"] = _robustness(cfg, task, spec, score, base, datamodule, own, served)
    return out


def _robustness(cfg, task, spec, score, base, datamodule, own, served) -> dict[str, Any]:
    """The trained lens (a list's first) with its focal, principal point and first distortion term perturbed
    (:func:`~airfisheye_bench.evaluation.cross_lens.robustness_lenses`): each perturbation's metrics and the
    largest change of each from the unperturbed lens."""
    camera = datamodule.camera
    reference = own
    if len(datamodule.split_dataset(cfg.split).served_lenses) > 1:  # own is the list's mixture: lens 0 alone
        reference = score(served(lens_data_config(base, camera)))
    rows = []
    for lens in robustness_lenses(camera):
        module = served(lens_data_config(base, lens.perturb.apply(camera)))
        result = score(module)
        rows.append(
            {"name": lens.name, "lens": lens.spec(), "metrics": result.metrics, "flights": result.groups}
        )
    return {
        "camera": camera.to_dict(),
        "metrics": reference.metrics,
        "flights": reference.groups,
        "perturbations": rows,
        "largest_change": largest_changes(reference.metrics, [r["metrics"] for r in rows]),
    }


def _gaps(spec: Any, own: dict[str, float], other: dict[str, float]) -> dict[str, float]:
    """The cross-lens gap of each headline metric (:func:`~airfisheye_bench.evaluation.cross_lens.cross_lens_gap`)."""
    out = {}
    for key in spec.metric_keys:
        if key in own and key in other:
            out[key] = cross_lens_gap(own[key], other[key], spec.column(key).higher_is_better)
    return out


def _same_camera(a: CameraModel, b: CameraModel) -> bool:
    """Whether two served cameras are the same lens (to rounding: a resized release camera and the ideal lens it
    is)."""
    da, db = a.to_dict(), b.to_dict()
    if da.keys() != db.keys():
        return False
    return all(
        np.allclose(np.asarray(da[k], dtype=float), np.asarray(db[k], dtype=float), rtol=1e-9, atol=1e-9)
        if not isinstance(da[k], str)
        else da[k] == db[k]
        for k in da
    )
