"""Deployment export: a trained run becomes one verified, self-describing ONNX file (optionally also int8).

``python scripts/export_onnx.py ckpt_path=<ckpt or run dir> out=model.onnx [options] [data.<key>=<value> ...]``
(console script ``airfisheye-export``) does, in order:

1. rebuild the task from the checkpoint (:func:`~airfisheye_bench.tasks.checkpoint.load_task`) and its data
   module from the run's ``config.yaml`` (``data.*`` overrides applied, e.g. another lens or size);
2. export the zoo model (:func:`~airfisheye_bench.export.onnx.export_onnx`): one file, dynamic batch, fixed or
   dynamic spatial size, named inputs/output, the metadata of :mod:`airfisheye_bench.runs.deployment`;
3. check ONNX Runtime (CPU) against PyTorch on real validation frames (no augmentation): segmentation logits
   within 1e-4 absolute, depth within 1e-3 relative (+ 1e-4 m). The file is written under a temporary name and
   only renamed to ``out`` once it passes, so a failed export never leaves a bad model behind;
4. optionally quantise to int8 (:mod:`~airfisheye_bench.export.quantize`: ``quantize=dynamic|static``,
   ``<out stem>.int8.onnx``) and report the change of the task's metrics on the validation split (fp32 ONNX vs
   int8 ONNX against ground truth) with the speed-up.

Exit codes of the command (:func:`airfisheye_bench.cli.commands.export`; ``--help`` lists the options): 0
success, 1 export or parity failure (nothing written at ``out``), 2 bad arguments or inputs (checkpoint, run
config, overrides), 3 the fp32 model was exported and verified but the requested int8 quantisation failed.
"""

from __future__ import annotations

import logging
import math
import os
import shutil
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from omegaconf import DictConfig, OmegaConf
from torch import Tensor

from airfisheye_bench.atomic import check_writable
from airfisheye_bench.config_checks import check_common_values
from airfisheye_bench.export.camera import BakedRays, bake_problem
from airfisheye_bench.export.onnx import ParityReport, export_onnx, first_line, size_mb, verify_onnx
from airfisheye_bench.export.quantize import (
    QUANTIZE_MODES,
    QuantizationReport,
    quantization_lines,
    quantize_model,
)
from airfisheye_bench.export.validation import validation_frames
from airfisheye_bench.io.manifest import sha256_file
from airfisheye_bench.runs import resolve_checkpoint, run_config, run_directory
from airfisheye_bench.runs.deployment import deployment_metadata, graph_inputs
from airfisheye_bench.runs.results import dataset_identity
from airfisheye_bench.specs import get_task
from airfisheye_bench.tasks.checkpoint import load_task
from airfisheye_bench.tracking import log_to_run, resolve_run
from datamodules.config import apply_data_overrides, instantiate_datamodule

__all__ = [
    "QUANTIZE_MODES",
    "DeploymentReport",
    "ExportError",
    "QuantizationReport",
    "export_deployment",
    "log_export",
    "parity_tolerance",
]

log = logging.getLogger(__name__)


def _relative(path: Path) -> str:
    """``path`` relative to the working directory when it lies below it (a record names no machine's folders)."""
    try:
        return Path(path).resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return str(path)


def _finite(value: float) -> float | None:
    """A plain float for JSON (numpy scalars included), ``None`` for ``nan``."""
    value = float(value)
    return value if math.isfinite(value) else None


def parity_tolerance(task: str) -> tuple[float, float]:
    """``(atol, rtol)`` of the task's parity check: ``|ort - torch| <= atol + rtol * |torch|`` element-wise.

    Example:
        >>> parity_tolerance("seg"), parity_tolerance("depth")
        ((0.0001, 0.0), (0.0001, 0.001))
    """
    export = get_task(task).export
    return export.atol, export.rtol


class ExportError(RuntimeError):
    """The model could not be exported (the exporter's message is kept)."""


@dataclass(frozen=True)
class DeploymentReport:
    """What :func:`export_deployment` wrote and measured.

    Attributes:
        path: the verified fp32 ``.onnx`` file.
        task: ``seg``, ``depth`` or ``completion``.
        model: registry name of the model.
        checkpoint: the source checkpoint file.
        metadata: the ``metadata_props`` written (see :mod:`airfisheye_bench.runs.deployment`).
        parity: ONNX Runtime vs PyTorch on ``parity_frames`` validation frames (one batch).
        parity_frames: validation frames in the parity batch.
        atol: absolute tolerance of the parity check.
        rtol: relative tolerance of the parity check.
        dynamic_spatial: whether height and width are symbolic in the graph.
        quantization: the int8 report, or ``None`` with ``quantize=none``.
        dataset: the identity of the data its frames came from
            (:func:`~airfisheye_bench.runs.results.dataset_identity`; one per source for a run of several sources).
        inputs: the graph's input names (the task's, and ``rays`` for a camera-aware model's map as an input).
        rays_baked: a camera-aware model's ray map is a constant of the graph (``bake_camera=true``).
    """

    path: Path
    task: str
    model: str
    checkpoint: Path
    metadata: dict[str, str]
    parity: ParityReport
    parity_frames: int
    atol: float
    rtol: float
    dynamic_spatial: bool
    quantization: QuantizationReport | None = None
    dataset: dict[str, Any] | None = None
    inputs: tuple[str, ...] = ()
    rays_baked: bool = False

    def to_dict(self) -> dict[str, Any]:
        """The report as plain JSON values (paths as written, ``nan`` as ``None``), for a committed record."""
        p = self.parity
        record: dict[str, Any] = {
            "onnx": str(self.path),
            "onnx_bytes": self.path.stat().st_size,
            "task": self.task,
            "model": self.model,
            "checkpoint": _relative(self.checkpoint),
            "dynamic_spatial": self.dynamic_spatial,
            "parity": {
                "frames": self.parity_frames,
                "atol": self.atol,
                "rtol": self.rtol,
                "max_abs_diff": _finite(p.max_abs_diff),
                "max_rel_diff": _finite(p.max_rel_diff),
                "max_allowance_used": _finite(p.max_allowance_used),
                "verdict": p.verdict(self.atol, self.rtol),
                "output_shape": [int(n) for n in p.output_shape],
            },
            "latency": {
                "batch": self.parity_frames,
                "threads": torch.get_num_threads(),
                "onnxruntime_ms": _finite(p.ort_ms),
                "pytorch_ms": _finite(p.torch_ms),
                "ratio_ort_over_torch": _finite(p.latency_ratio),
            },
        }
        q = self.quantization
        if q is not None:
            record["int8"] = {
                "mode": q.mode,
                "ok": q.ok,
                "error": q.error,
                "onnx": None if q.path is None else str(q.path),
                "frames": q.frames,
                "metrics_fp32": {k: _finite(v) for k, v in q.metrics_fp32.items()},
                "metrics_int8": {k: _finite(v) for k, v in q.metrics_int8.items()},
                "fp32_bytes": q.fp32_bytes,
                "int8_bytes": q.int8_bytes,
                "fp32_ms": _finite(q.fp32_ms),
                "int8_ms": _finite(q.int8_ms),
                "speedup": _finite(q.speedup) if q.ok else None,
                "threads": q.threads,
                "batch": q.batch,
                "notes": list(q.notes),
            }
        if self.dataset is not None:
            record["dataset"] = self.dataset
        if self.rays_baked or "rays" in self.inputs:  # a camera-aware model: how its ray map is given
            record |= {"inputs": list(self.inputs), "rays_baked": self.rays_baked}
        return record

    def summary(self) -> str:
        """A short human-readable report (a few lines)."""
        p = self.parity
        spatial = (
            "dynamic H, W" if self.dynamic_spatial else f"fixed {p.output_shape[-2]}x{p.output_shape[-1]}"
        )
        lines = [  # the verdict and the rule that decided it, then what was written
            f"parity on {self.parity_frames} validation frame(s), onnxruntime CPU vs PyTorch: "
            f"{p.verdict(self.atol, self.rtol)}",
            f"wrote {self.path} ({size_mb(self.path)}): task={self.task} model={self.model}, "
            f"inputs {list(self.inputs or get_task(self.task).inputs)}{' (ray map baked in)' if self.rays_baked else ''}"
            f" -> {get_task(self.task).output}, dynamic batch, {spatial}",
            f"latency (batch {self.parity_frames}, {torch.get_num_threads()} threads): onnxruntime "
            f"{p.ort_ms:.1f} ms, PyTorch {p.torch_ms:.1f} ms, ratio ort/torch {p.latency_ratio:.2f}",
        ]
        if self.quantization is not None:
            lines.extend(quantization_lines(self.quantization, self.task))
        return "\n".join(lines)


def export_deployment(
    ckpt_path: str | os.PathLike,
    out: str | os.PathLike,
    *,
    dynamic_spatial: bool = False,
    batch: int = 2,
    parity_samples: int = 4,
    quantize: str = "none",
    opset: int = 20,
    data_overrides: Mapping[str, Any] | None = None,
    calib_samples: int = 16,
    eval_samples: int = 0,
    repeats: int = 10,
    bake_camera: bool = False,
) -> DeploymentReport:
    """Export a trained checkpoint (or run directory) to a verified ONNX file with deployment metadata.

    Args:
        ckpt_path: a ``.ckpt`` inside a run directory, or the run directory (its best, else last, checkpoint).
            The run's ``config.yaml`` must be next to the checkpoint or one folder above it.
        out: destination ``.onnx``; only written once the parity check passes.
        dynamic_spatial: make height and width symbolic (default: fixed to the served camera size).
        batch: batch size of the example used for tracing (>= 2: the batch dimension is always dynamic).
        parity_samples: validation frames of the parity check (fewer if the split is smaller).
        quantize: ``none``, ``dynamic`` or ``static`` (int8 via ``onnxruntime.quantization``).
        opset: ONNX opset (>= 19 for NLSPN's ``DeformConv``).
        data_overrides: changes to the run's ``data`` config, keys relative to it (``{"camera.size": 128}``).
        calib_samples: validation frames fed to static calibration.
        eval_samples: validation frames of the int8 accuracy comparison (0: the whole split).
        repeats: timed calls of each latency median (ORT vs PyTorch, fp32 vs int8).
        bake_camera: a camera-aware model (``camera_input=rays``): store the data's camera's ray map in the graph
            as a constant, so the file takes the image alone (else it takes ``rays`` as a second input).

    Returns:
        A :class:`DeploymentReport` (``.summary()`` prints it). A failed quantisation does not raise: it is
        reported in ``report.quantization.error`` and the verified fp32 model stays in place.

    Raises:
        FileNotFoundError: no checkpoint at ``ckpt_path``.
        ValueError: unreadable checkpoint, no run config, bad overrides or arguments (``bake_camera`` for a model
            without a camera input, or with ``dynamic_spatial``).
        ExportError: ``torch.onnx.export`` failed.
        OnnxParityError: ONNX Runtime differs from PyTorch beyond the tolerance (``out`` is not written).

    Example:
        >>> report = export_deployment("logs/seg/runs/2026-01-01_00-00-00", "seg.onnx")  # doctest: +SKIP
        >>> print(report.summary())                                                    # doctest: +SKIP
        exported seg.onnx (...): task=seg model=deeplabv3plus, inputs ['image'] -> logits, dynamic batch, ...
    """
    _check_arguments(batch, parity_samples, quantize, calib_samples, eval_samples, repeats)
    out = check_writable(out, "out")  # before the minutes of loading, exporting and verifying

    checkpoint = resolve_checkpoint(ckpt_path)
    task = load_task(checkpoint)
    problem = bake_problem(bake_camera, task.camera_input, dynamic_spatial)
    if problem is not None:
        raise ValueError(problem)

    data_cfg = apply_data_overrides(_run_data(checkpoint), data_overrides, task=task.task)
    if (
        task.camera_input != "none"
    ):  # the frames carry what the model takes (the data config follows the model)
        data_cfg.camera_input = task.camera_input
    check_common_values(OmegaConf.create({"data": data_cfg}))
    datamodule = instantiate_datamodule(data_cfg, "validate")  # a few frames: main-process loading
    metadata = _metadata(task, datamodule, data_cfg, checkpoint, bake_camera)
    names = graph_inputs(task.spec.inputs, task.camera_input, bake_camera)
    # The exported module: the model, or the model with the camera's ray map held as a constant.
    model = BakedRays(task.net, datamodule.ray_map()) if bake_camera else task.net
    frames = validation_frames(datamodule, max(parity_samples, batch), names)
    available = int(frames["image"].shape[0])
    if available < parity_samples:
        log.info(
            "the validation split has %d frame(s), fewer than parity_samples=%d", available, parity_samples
        )
    example = {k: _repeat_to(frames[k], batch) for k in names}
    parity_inputs = {k: frames[k][:parity_samples] for k in names}
    atol, rtol = parity_tolerance(task.task)

    out.parent.mkdir(parents=True, exist_ok=True)
    workdir = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        candidate = workdir / out.name
        _export(task, example, candidate, opset, dynamic_spatial, metadata, model)
        log.info("verifying against PyTorch on %d validation frame(s)", min(parity_samples, available))
        parity = verify_onnx(candidate, model, parity_inputs, atol=atol, rtol=rtol, repeats=repeats)
        os.replace(candidate, out)  # the report says "wrote", after the parity verdict
        quantization = None
        if quantize != "none":
            quantization = quantize_model(
                out, quantize, task, datamodule, parity_inputs, workdir, calib_samples, eval_samples, repeats
            )
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    return DeploymentReport(
        path=out,
        task=task.task,
        model=task.hparams["model"]["name"],
        checkpoint=checkpoint,
        metadata=metadata,
        parity=parity,
        parity_frames=int(parity_inputs["image"].shape[0]),
        atol=atol,
        rtol=rtol,
        dynamic_spatial=dynamic_spatial,
        quantization=quantization,
        dataset=_dataset(datamodule),
        inputs=tuple(names),
        rays_baked=bake_camera,
    )


def _check_arguments(
    batch: int, parity_samples: int, quantize: str, calib_samples: int, eval_samples: int, repeats: int
) -> None:
    if batch < 2:
        raise ValueError(f"batch must be >= 2 (the batch dimension is exported dynamic), got {batch}")
    if parity_samples < 1:
        raise ValueError(f"parity_samples must be >= 1, got {parity_samples}")
    if quantize not in QUANTIZE_MODES:
        raise ValueError(f"quantize must be one of {list(QUANTIZE_MODES)}, got {quantize!r}")
    if calib_samples < 1 or eval_samples < 0 or repeats < 1:
        raise ValueError(
            f"need calib_samples >= 1, eval_samples >= 0 (0 = all), repeats >= 1; "
            f"got {calib_samples}, {eval_samples}, {repeats}"
        )


# ---------------------------------------------------------------------------------------- run and data
def _run_data(checkpoint: Path) -> DictConfig:
    """The ``data`` section of the run that wrote ``checkpoint``."""
    cfg = run_config(checkpoint)
    if cfg is None or "data" not in cfg:
        raise ValueError(
            f"{checkpoint}: no config.yaml with a 'data' section in {checkpoint.parent} or "
            f"{checkpoint.parent.parent}; export needs the run's data config (give the run directory, or keep "
            "the checkpoint inside it)"
        )
    return cfg.data


def _dataset(datamodule) -> dict[str, Any]:
    """The identity of the data the parity and int8 frames came from (the validation split's dataset)."""
    if getattr(datamodule, "source_names", None):  # a run of several sources: one identity each
        val = datamodule.split_dataset("val")
        return {
            name: dataset_identity(root, val.datasets[name].spec.name)
            for name, root in datamodule.source_roots().items()
        }
    return dataset_identity(datamodule.dataset_root(), datamodule.split_dataset("val").spec.name)


def _repeat_to(x: Tensor, n: int) -> Tensor:
    reps = math.ceil(n / x.shape[0])
    return x.repeat(reps, *([1] * (x.ndim - 1)))[:n]


def _metadata(
    task, datamodule, data_cfg: DictConfig, checkpoint: Path, rays_baked: bool = False
) -> dict[str, str]:
    """The deployment metadata of a task module: the common keys plus the keys its spec lists, and how a
    camera-aware model takes its ray map.

    The task's own values come from the module's metric options (class names, ignore index, depth bounds), its
    palette and the data config (occlusion); the spec says which of them the task carries.
    """
    spec = task.spec
    model_config = dict(task.hparams["model"])
    options = task.metric_options()
    if spec.uses_classes:
        classes = list(options["class_names"])
        if list(datamodule.class_names) != classes:
            raise ValueError(
                f"the data config's classes {list(datamodule.class_names)} differ from the checkpoint's {classes}; "
                "the logits would be scored against the wrong labels"
            )
        options["palette"] = task.hparams.get("palette") or datamodule.palette[: len(classes)].tolist()
    available = {**options, "occlusion": str(data_cfg.get("occlusion"))}
    missing = [k for k in spec.export.metadata if k not in available]
    if missing:
        raise ValueError(f"task={spec.name} lists metadata {missing} that the task module does not provide")
    return deployment_metadata(
        task=task.task,
        model=model_config["name"],
        model_config=model_config,
        normalization=datamodule.normalization,
        camera=datamodule.camera.to_dict(),
        data_config=_portable_data_config(data_cfg, datamodule),
        checkpoint_sha256=sha256_file(checkpoint),
        source_checkpoint=str(checkpoint.resolve()),
        weights=task.hparams.get("weights"),
        camera_input=task.camera_input,
        rays_baked=rays_baked,
        **{k: available[k] for k in spec.export.metadata},
    )


def _portable_data_config(data_cfg: DictConfig, datamodule) -> dict:
    """The run's data config as plain data, with a calibration file replaced by the camera it holds.

    The metadata must rebuild the served camera wherever the model goes, without the training machine's file:
    ``camera.calibration`` becomes the calibrated lens's flat dict (``camera.camera`` is then no longer needed).
    """
    config = OmegaConf.to_container(data_cfg, resolve=True)
    camera = config.get("camera") or {}
    if isinstance(camera.get("calibration"), str):
        lens = datamodule.camera_config.lens
        config["camera"] = {**camera, "calibration": lens.to_dict(), "camera": None}
    return config


# ------------------------------------------------------------------------------------------------ export
def _export(
    task,
    example: dict[str, Tensor],
    path: Path,
    opset: int,
    dynamic_spatial: bool,
    metadata: dict[str, str],
    model: torch.nn.Module | None = None,
) -> None:
    """Export ``model`` (default: the task's network) with ``example``'s names as the graph's inputs."""
    log.info(
        "exporting %s (%s) at %s, dynamic_spatial=%s",
        task.hparams["model"]["name"],
        task.task,
        tuple(example["image"].shape),
        dynamic_spatial,
    )
    try:
        export_onnx(
            task.net if model is None else model,
            example,
            path,
            output_name=task.spec.output,
            opset=opset,
            dynamic_batch=True,
            dynamic_spatial=dynamic_spatial,
            metadata=metadata,
        )
    except Exception as err:
        hint = " (retry with dynamic_spatial=false)" if dynamic_spatial else ""
        raise ExportError(
            f"torch.onnx.export failed for {task.hparams['model']['name']}{hint}: "
            f"{type(err).__name__}: {first_line(err)}"
        ) from err


# ------------------------------------------------------------------------------------------------- report
def log_export(report: DeploymentReport, mlflow_run: str, tracking_uri: str | None = None) -> None:
    """Log the exported ONNX file(s) (artifacts under ``export/``), the parity and latency numbers (metrics
    ``export/...``) and the file's path (tag ``onnx_path``) to an MLflow run: ``auto``, the run the checkpoint was
    trained in with ``logger=mlflow``, or a run id (:func:`~airfisheye_bench.tracking.resolve_run`)."""
    uri, run_id = resolve_run(mlflow_run, run_directory(report.checkpoint), tracking_uri)
    p = report.parity
    metrics = {
        "export/parity_max_abs_diff": p.max_abs_diff,
        "export/parity_max_rel_diff": p.max_rel_diff,
        "export/ort_ms": p.ort_ms,
        "export/torch_ms": p.torch_ms,
    }
    artifacts = {f"export/{report.path.name}": report.path}
    q = report.quantization
    if q is not None and q.ok and q.path is not None:
        artifacts[f"export/{q.path.name}"] = q.path
        metrics |= {"export/int8_ms": q.int8_ms, "export/fp32_ms": q.fp32_ms}
        metrics |= {f"export/int8_delta/{k}": v for k, v in q.metric_deltas.items()}
    log_to_run(
        uri, run_id, metrics=metrics, artifacts=artifacts, tags={"onnx_path": str(report.path.absolute())}
    )
    log.info("logged %s to MLflow run %s (%s)", report.path, run_id, uri)
