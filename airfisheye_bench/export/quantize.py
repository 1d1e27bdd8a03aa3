"""int8 quantisation of a verified fp32 ONNX model, and its report: accuracy change and speed-up.

:func:`quantize_model` writes ``<stem>.int8.onnx`` next to the fp32 file with ``onnxruntime.quantization``
(``dynamic``, or ``static`` calibrated on validation frames), carries the deployment metadata over, times both
models in ONNX Runtime and scores both against ground truth on the validation split. A failure is returned in the
report, never raised: the fp32 model is verified already and stays.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import onnx
import onnxruntime as ort
import torch
from torch import Tensor

from airfisheye_bench.export.onnx import first_line, median_ms, size_mb
from airfisheye_bench.export.validation import validation_batches, validation_frames
from airfisheye_bench.runs.deployment import read_onnx_metadata
from airfisheye_bench.specs import get_task

__all__ = ["QUANTIZE_MODES", "QuantizationReport", "quantization_lines", "quantize_model"]

log = logging.getLogger(__name__)

QUANTIZE_MODES = ("none", "dynamic", "static")


@dataclass(frozen=True)
class QuantizationReport:
    """Outcome of the int8 quantisation: accuracy change on the validation split and ORT speed-up.

    Attributes:
        mode: ``dynamic`` or ``static``.
        path: the int8 file, or ``None`` when quantisation failed.
        error: why quantisation failed (``None`` on success).
        frames: validation frames the metrics were computed on.
        metrics_fp32: the task's metrics of the fp32 ONNX model against ground truth.
        metrics_int8: the same for the int8 model.
        fp32_ms: median ONNX Runtime latency of the fp32 model (same batch and threads as ``int8_ms``).
        int8_ms: median ONNX Runtime latency of the int8 model.
        fp32_bytes: size of the fp32 file.
        int8_bytes: size of the int8 file.
        threads: ONNX Runtime intra-op threads of both timings.
        batch: batch size of both timings.
        notes: remarks worth reading (pre-processing skipped, calibration frames, ...).
    """

    mode: str
    path: Path | None = None
    error: str | None = None
    frames: int = 0
    metrics_fp32: dict[str, float] = field(default_factory=dict)
    metrics_int8: dict[str, float] = field(default_factory=dict)
    fp32_ms: float = float("nan")
    int8_ms: float = float("nan")
    fp32_bytes: int = 0
    int8_bytes: int = 0
    threads: int = 0
    batch: int = 0
    notes: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        """Whether the int8 model was written and evaluated."""
        return self.error is None and self.path is not None

    @property
    def speedup(self) -> float:
        """fp32 latency / int8 latency (> 1 means int8 is faster)."""
        return self.fp32_ms / self.int8_ms if self.int8_ms > 0 else float("nan")

    @property
    def metric_deltas(self) -> dict[str, float]:
        """``int8 - fp32`` per metric."""
        return {k: self.metrics_int8[k] - v for k, v in self.metrics_fp32.items() if k in self.metrics_int8}


def quantize_model(
    fp32: Path,
    mode: str,
    task,
    datamodule,
    timing_inputs: dict[str, Tensor],
    workdir: Path,
    calib_samples: int,
    eval_samples: int,
    repeats: int,
) -> QuantizationReport:
    """Write ``<stem>.int8.onnx`` next to ``fp32`` and compare both on the validation split.

    Failures (an op the quantiser or the CPU provider cannot handle, e.g. NLSPN's DeformConv) are caught and
    returned as ``error``: the fp32 model is verified already and stays.
    """
    target = fp32.with_name(f"{fp32.stem}.int8.onnx")
    notes: list[str] = []
    threads = torch.get_num_threads()
    batch = int(timing_inputs["image"].shape[0])
    try:
        candidate = workdir / target.name
        source = _preprocess(fp32, workdir, notes)
        log.info("quantising (%s int8)", mode)
        _run_quantizer(source, candidate, mode, datamodule, task.task, calib_samples, notes)
        _copy_metadata(fp32, candidate)
        int8_session = _session(candidate)
        fp32_session = _session(fp32)
        feed = {k: v.numpy() for k, v in timing_inputs.items()}
        fp32_ms = median_ms(lambda: fp32_session.run(None, feed), repeats)
        int8_ms = median_ms(lambda: int8_session.run(None, feed), repeats)
        log.info("evaluating fp32 vs int8 on the validation split")
        frames, metrics_fp32, metrics_int8 = _compare_metrics(
            task, datamodule, fp32_session, int8_session, eval_samples
        )
        os.replace(candidate, target)
        notes.extend(_accuracy_notes(task.task, metrics_fp32, metrics_int8))
        if int8_ms > fp32_ms:
            notes.append(
                "int8 is slower than fp32 here: onnxruntime's CPU int8 convolution kernels (ConvInteger for "
                "dynamic, QLinearConv for static) often lose to its fp32 ones on small conv nets"
                + ("; static quantisation usually does better" if mode == "dynamic" else "")
            )
    except Exception as err:  # the quantiser raises anything from KeyError to onnxruntime's Fail
        with contextlib.suppress(FileNotFoundError):
            target.unlink()  # an int8 file from an earlier export would no longer match the new fp32 model
        return QuantizationReport(
            mode=mode,
            error=f"{mode} int8 quantisation of {task.hparams['model']['name']} failed "
            f"({type(err).__name__}: {first_line(err)}); the fp32 model {fp32} is unaffected",
            notes=tuple(notes),
        )
    return QuantizationReport(
        mode=mode,
        path=target,
        frames=frames,
        metrics_fp32=metrics_fp32,
        metrics_int8=metrics_int8,
        fp32_ms=fp32_ms,
        int8_ms=int8_ms,
        fp32_bytes=fp32.stat().st_size,
        int8_bytes=target.stat().st_size,
        threads=threads,
        batch=batch,
        notes=tuple(notes),
    )


def _preprocess(fp32: Path, workdir: Path, notes: list[str]) -> Path:
    """ORT's recommended pre-processing (graph optimisation, shape inference) of a copy without ``value_info``.

    The quantisers re-run ONNX shape inference, which rejects some of the exporter's intermediate shape
    annotations (AdaBins: "Inferred shape and existing shape differ") although ONNX Runtime runs the graph
    correctly (parity passed); the annotations are optional, so they are dropped and inferred afresh.
    """
    from onnxruntime.quantization import quant_pre_process  # loaded on use: only quantize= needs it

    model = onnx.load(str(fp32))
    del model.graph.value_info[:]
    stripped = workdir / "stripped.onnx"
    onnx.save(model, str(stripped))
    out = workdir / "preprocessed.onnx"
    try:
        # Symbolic shape inference targets transformers and gives up on these graphs; ONNX inference suffices.
        quant_pre_process(str(stripped), str(out), skip_symbolic_shape=True)
        return out
    except Exception as err:
        notes.append(f"pre-processing skipped ({type(err).__name__}: {first_line(err)})")
        return stripped


def _run_quantizer(
    source: Path, target: Path, mode: str, datamodule, task: str, calib_samples: int, notes: list[str]
) -> None:
    # loaded on use: only quantize= needs the quantisers
    from onnxruntime.quantization import QuantType, quantize_dynamic, quantize_static

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if mode == "dynamic":
            quantize_dynamic(str(source), str(target), weight_type=QuantType.QInt8)
            return
        # The graph's own inputs: the task's, and a camera-aware model's ray map unless it is baked in.
        graph = onnx.load(str(source), load_external_data=False).graph
        constants = {t.name for t in graph.initializer}
        names = [i.name for i in graph.input if i.name not in constants]
        reader = _calibration_reader(datamodule, names, calib_samples)
        quantize_static(str(source), str(target), reader)
        notes.append(
            f"static calibration on {reader.frames} validation frame(s), the split the accuracy is measured on"
        )


def _calibration_reader(datamodule, names: Sequence[str], limit: int):
    """A ``CalibrationDataReader`` of validation frames, one frame per call (calibration needs no batching)."""
    from onnxruntime.quantization import CalibrationDataReader  # loaded on use: only quantize=static needs it

    class ValidationReader(CalibrationDataReader):
        def __init__(self) -> None:
            frames = validation_frames(datamodule, limit, names)
            self.frames = int(frames["image"].shape[0])
            self._feeds = iter([{k: frames[k][i : i + 1].numpy() for k in names} for i in range(self.frames)])

        def get_next(self) -> dict[str, np.ndarray] | None:
            return next(self._feeds, None)

    return ValidationReader()


def _copy_metadata(source: Path, target: Path) -> None:
    """The quantisers drop ``metadata_props``; the int8 model carries the same deployment metadata."""
    model = onnx.load(str(target))
    del model.metadata_props[:]
    for key, value in read_onnx_metadata(source).items():
        model.metadata_props.add(key=key, value=value)
    onnx.save(model, str(target))


def _session(path: Path):
    options = ort.SessionOptions()
    options.intra_op_num_threads = torch.get_num_threads()
    options.inter_op_num_threads = 1
    return ort.InferenceSession(str(path), sess_options=options, providers=["CPUExecutionProvider"])


def _compare_metrics(task, datamodule, fp32_session, int8_session, limit: int):
    """The task's metrics of both ONNX models against ground truth on the validation split."""
    names = [i.name for i in fp32_session.get_inputs()]
    metric_fp32, metric_int8 = task.make_metric(), task.make_metric()
    frames = 0
    for batch in validation_batches(datamodule, limit):
        feed = {k: batch[k].numpy() for k in names}
        target, mask = task.target(batch), batch["valid_mask"]
        metric_fp32.update(torch.from_numpy(fp32_session.run(None, feed)[0]), target, mask=mask)
        metric_int8.update(torch.from_numpy(int8_session.run(None, feed)[0]), target, mask=mask)
        frames += int(batch["image"].shape[0])
    return frames, _scalars(metric_fp32.compute()), _scalars(metric_int8.compute())


def _accuracy_notes(task: str, fp32: Mapping[str, float], int8: Mapping[str, float]) -> list[str]:
    """Flag headline metrics that int8 moves by more than 5 % (relative): worth a look before deploying."""
    notes = []
    for key in get_task(task).export.headline:
        before, after = fp32.get(key, math.nan), int8.get(key, math.nan)
        if (
            math.isfinite(before)
            and math.isfinite(after)
            and abs(after - before) > 0.05 * max(abs(before), 1e-6)
        ):
            notes.append(
                f"int8 moves {key} by {100 * (after - before) / max(abs(before), 1e-6):+.0f}% "
                f"({before:.4g} -> {after:.4g}): check the int8 model before deploying it"
            )
    return notes


def _scalars(values: Mapping[str, Tensor]) -> dict[str, float]:
    return {k: float(v) for k, v in values.items()}


def quantization_lines(q: QuantizationReport, task: str) -> list[str]:
    """The int8 part of :meth:`DeploymentReport.summary`: metric changes, latencies and notes."""
    if not q.ok:
        return [f"int8: FAILED: {q.error}", *(f"  note: {n}" for n in q.notes)]
    lines = [
        f"int8 ({q.mode}) {q.path} ({size_mb(q.path)}), on {q.frames} validation frame(s), fp32 -> int8:"
    ]
    parts = [
        f"{k} {q.metrics_fp32[k]:.4f} -> {q.metrics_int8[k]:.4f} ({q.metric_deltas[k]:+.4f})"
        for k in get_task(task).export.headline
        if k in q.metrics_fp32
    ]
    lines.append("  " + ", ".join(parts))
    lines.append(
        f"  latency (batch {q.batch}, {q.threads} threads, median): fp32 {q.fp32_ms:.1f} ms, int8 "
        f"{q.int8_ms:.1f} ms, speed-up x{q.speedup:.2f}"
    )
    lines.extend(f"  note: {n}" for n in q.notes)
    return lines
