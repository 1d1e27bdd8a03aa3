"""Export a model to ONNX and check it against PyTorch with ONNX Runtime.

Every model of the zoo follows one calling convention (see ``models/__init__.py``): named tensor inputs
(``image``, and ``sparse_depth`` for completion) and one primary output (``logits`` or ``depth``). The helpers
here keep those names in the ONNX graph, so a consumer feeds ``{"image": ...}`` and reads ``"depth"``.

Why the dynamo exporter: it is the default and maintained path of ``torch.onnx.export`` since torch 2.9
(the TorchScript path is deprecated), it is the only one that maps ``torchvision::deform_conv2d`` to ONNX
``DeformConv`` (NLSPN), and ``dynamic_shapes`` replaces the deprecated ``dynamic_axes``.

Pitfalls handled here:

- a dynamic batch dimension cannot be specialised from an example of batch 1 (torch.export treats sizes 0 and 1
  as constants), so :func:`export_onnx` refuses a batch-1 example when ``dynamic_batch=True``;
- ``external_data`` defaults to True in torch; models here are < 2 GB, so one self-contained file is written;
- the file is written under a temporary name and renamed, so a crash never leaves a truncated ``.onnx``.
"""

from __future__ import annotations

import contextlib
import inspect
import io
import os
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn
from torch.export import Dim

from airfisheye_bench.atomic import atomic_write

__all__ = ["OnnxParityError", "ParityReport", "export_onnx", "verify_onnx"]


class OnnxParityError(AssertionError):
    """ONNX Runtime output differs from the PyTorch output beyond the tolerance."""


@dataclass(frozen=True)
class ParityReport:
    """How closely an ONNX model reproduces the eager PyTorch model on one set of inputs.

    Attributes:
        max_abs_diff: ``max |ort - torch|`` over all output elements.
        max_rel_diff: ``max |ort - torch| / max(|torch|, 1e-12)``.
        ort_ms: median ONNX Runtime (CPU) latency per call in milliseconds (``nan`` if not measured).
        torch_ms: median eager PyTorch latency per call in milliseconds (``nan`` if not measured).
        output_shape: shape of the compared output.
        max_allowance_used: ``max |ort - torch| / (atol + rtol * |torch|)``: the share of its tolerance the worst
            element uses (``<= 1`` passes; ``nan`` if not computed).
    """

    max_abs_diff: float
    max_rel_diff: float
    ort_ms: float
    torch_ms: float
    output_shape: tuple[int, ...]
    max_allowance_used: float = float("nan")

    def verdict(self, atol: float, rtol: float) -> str:
        """The parity result with the rule that decided it, ``|ort - torch| <= atol + rtol * |torch|``.

        Example:
            >>> report = ParityReport(1.6e-5, 0.12, 1.0, 1.0, (1, 13, 8, 8), 0.16)
            >>> report.verdict(1e-4, 0.0)
            'max |diff| 1.6e-05 ≤ atol 0.0001: OK'
            >>> ParityReport(2e-3, 4e-4, 1.0, 1.0, (1, 1, 8, 8), 0.4).verdict(0.0, 1e-3)
            'max |diff|/|torch| 0.0004 ≤ rtol 0.001: OK'
            >>> ParityReport(2e-3, 4e-4, 1.0, 1.0, (1, 1, 8, 8), 0.4).verdict(1e-4, 1e-3)
            '|diff| ≤ atol 0.0001 + rtol 0.001 × |torch| everywhere (max |diff| 0.002, worst element at 40% of its bound): OK'
        """
        ok = "OK" if not self.max_allowance_used > 1 else "FAILED"
        if rtol == 0:
            sign = "≤" if ok == "OK" else ">"
            return f"max |diff| {self.max_abs_diff:.2g} {sign} atol {atol:g}: {ok}"
        if atol == 0:
            sign = "≤" if ok == "OK" else ">"
            return f"max |diff|/|torch| {self.max_rel_diff:.2g} {sign} rtol {rtol:g}: {ok}"
        return (
            f"|diff| ≤ atol {atol:g} + rtol {rtol:g} × |torch| everywhere (max |diff| {self.max_abs_diff:.2g}, "
            f"worst element at {self.max_allowance_used:.0%} of its bound): {ok}"
        )

    @property
    def latency_ratio(self) -> float:
        """ONNX Runtime latency divided by eager PyTorch latency (< 1 means ORT is faster)."""
        return self.ort_ms / self.torch_ms if self.torch_ms > 0 else float("nan")


def export_onnx(
    model: nn.Module,
    example_inputs: Mapping[str, Tensor],
    path: str | os.PathLike,
    output_name: str,
    opset: int = 20,
    dynamic_batch: bool = True,
    dynamic_spatial: bool = False,
    metadata: Mapping[str, str] | None = None,
) -> Path:
    """Export ``model`` to a single self-contained ONNX file with named inputs and output.

    The model is called as ``model(**example_inputs)`` in eval mode (its training flag is restored afterwards)
    and must return one tensor. ONNX input names are the keys of ``example_inputs``; the output is named
    ``output_name``.

    Args:
        model: module following the zoo calling convention.
        example_inputs: named example tensors, e.g. ``{"image": x}`` or ``{"image": x, "sparse_depth": d}``.
            With ``dynamic_batch`` the batch size must be >= 2 (a batch of 1 would be baked in as a constant).
        path: destination ``.onnx`` file; parent folders are created. Written atomically (temp file, rename).
        output_name: name of the graph output, ``"logits"`` or ``"depth"`` by convention.
        opset: ONNX opset; >= 19 is needed for ``DeformConv`` (NLSPN), 20 is torch's default.
        dynamic_batch: make dim 0 of every input (and the output) symbolic.
        dynamic_spatial: make dims 2 and 3 symbolic too. The model must then be traceable for any size
            (the exporter records the divisibility constraints it discovers); otherwise export fails.
        metadata: string key/values stored in the model's ``metadata_props`` (e.g. task, classes, depth range).

    Returns:
        The path of the written file.

    Raises:
        ValueError: empty ``example_inputs``, names that do not fit ``model.forward``, non-tensor values,
            a batch of 1 with ``dynamic_batch``, inputs with different batch sizes, ``opset`` < 18, or
            non-string metadata.

    Example:
        >>> import tempfile, torch
        >>> net = torch.nn.Conv2d(3, 2, 1)
        >>> path = export_onnx(net, {"input": torch.randn(2, 3, 8, 8)}, tempfile.mkdtemp() + "/conv.onnx",
        ...                    output_name="logits", metadata={"task": "seg"})
        >>> from airfisheye_bench.runs.deployment import read_onnx_metadata
        >>> read_onnx_metadata(path)["task"]
        'seg'
    """
    _check_inputs(example_inputs, "example_inputs")
    batch_sizes = {int(t.shape[0]) for t in example_inputs.values()}
    if len(batch_sizes) != 1:
        raise ValueError(f"example_inputs must share one batch size, got {sorted(batch_sizes)}")
    if dynamic_batch and batch_sizes == {1}:
        raise ValueError(
            "example_inputs has batch size 1; with dynamic_batch=True export at batch >= 2 "
            "(torch.export specialises a size-1 dimension to a constant)"
        )
    if opset < 18:
        raise ValueError(f"opset must be >= 18 for the dynamo exporter, got {opset}")
    metadata = dict(metadata or {})
    bad = {k: v for k, v in metadata.items() if not (isinstance(k, str) and isinstance(v, str))}
    if bad:
        raise ValueError(f"metadata keys and values must be str, got {bad!r}")

    _check_signature(model, example_inputs)
    dynamic_shapes = _dynamic_shapes(example_inputs, dynamic_batch, dynamic_spatial)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)

    was_training = model.training
    model.eval()
    try:
        # The exporter prints progress to stdout and warns about merged axis names; neither is actionable here.
        with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
            warnings.filterwarnings("ignore", message=r".*axis name.*will not be used.*")
            program = torch.onnx.export(
                model,
                (),
                kwargs=dict(example_inputs),
                dynamo=True,
                opset_version=opset,
                dynamic_shapes=dynamic_shapes,
                output_names=[output_name],
                external_data=False,
                verbose=False,
            )
    finally:
        model.train(was_training)

    if program is None:  # only the legacy exporter returns None; dynamo=True must give an ONNXProgram
        raise RuntimeError("torch.onnx.export(dynamo=True) returned no ONNXProgram")
    outputs = [o.name for o in program.model.graph.outputs]
    if len(outputs) != 1:
        raise ValueError(f"model must return exactly one tensor to export, got outputs {outputs}")
    program.model.metadata_props.update(metadata)

    atomic_write(path, lambda tmp: program.save(str(tmp), external_data=False))
    return path


def verify_onnx(
    path: str | os.PathLike,
    model: nn.Module,
    inputs: Mapping[str, Tensor],
    atol: float = 1e-4,
    rtol: float = 1e-3,
    measure_latency: bool = True,
    repeats: int = 3,
) -> ParityReport:
    """Run an exported model in ONNX Runtime (CPU) and compare it with the eager PyTorch model.

    The check is element-wise, as in :func:`torch.testing.assert_close`: it passes when
    ``|ort - torch| <= atol + rtol * |torch|`` everywhere. Use ``rtol=0`` for a pure absolute check
    (segmentation logits) or ``atol=0`` for a pure relative one (depth in metres).

    Args:
        path: the ``.onnx`` file.
        model: the eager model; run in eval mode under ``torch.no_grad`` (training flag restored).
        inputs: named inputs; the names must match the ONNX graph inputs exactly.
        atol: absolute tolerance.
        rtol: relative tolerance.
        measure_latency: time both runtimes (1 warm-up call, then the median of ``repeats`` calls) with the
            same number of threads as torch (``torch.get_num_threads()``).
        repeats: timed calls per runtime.

    Returns:
        A :class:`ParityReport`.

    Raises:
        ValueError: input names differ from the graph's, or bad tolerances.
        OnnxParityError: shapes differ, or the outputs differ beyond the tolerance (message gives the diffs).

    Example:
        >>> import tempfile, torch
        >>> net = torch.nn.Conv2d(3, 2, 1)
        >>> x = {"input": torch.randn(2, 3, 8, 8)}
        >>> path = export_onnx(net, x, tempfile.mkdtemp() + "/conv.onnx", output_name="logits")
        >>> report = verify_onnx(path, net, {"input": torch.randn(3, 3, 8, 8)}, measure_latency=False)
        >>> report.max_abs_diff < 1e-5
        True
    """
    import onnxruntime as ort  # loaded on use: exporting alone does not need it

    _check_inputs(inputs, "inputs")
    if atol < 0 or rtol < 0:
        raise ValueError(f"atol and rtol must be >= 0, got atol={atol}, rtol={rtol}")
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")

    options = ort.SessionOptions()
    options.intra_op_num_threads = torch.get_num_threads()
    options.inter_op_num_threads = 1
    session = ort.InferenceSession(str(path), sess_options=options, providers=["CPUExecutionProvider"])
    graph_inputs = [i.name for i in session.get_inputs()]
    if sorted(graph_inputs) != sorted(inputs):
        raise ValueError(f"inputs must have the ONNX graph's names {graph_inputs}, got {list(inputs)}")
    feed = {name: t.detach().cpu().float().numpy() for name, t in inputs.items()}
    output_name = session.get_outputs()[0].name

    was_training = model.training
    model.eval()
    try:
        with torch.no_grad():
            expected = model(**inputs)
            torch_ms = median_ms(lambda: model(**inputs), repeats) if measure_latency else float("nan")
    finally:
        model.train(was_training)
    actual = session.run([output_name], feed)[0]
    ort_ms = median_ms(lambda: session.run([output_name], feed), repeats) if measure_latency else float("nan")

    expected_np = expected.detach().cpu().float().numpy()
    if actual.shape != expected_np.shape:
        raise OnnxParityError(
            f"ONNX output {output_name!r} has shape {actual.shape}, PyTorch {expected_np.shape}"
        )
    abs_diff = np.abs(actual.astype(np.float64) - expected_np.astype(np.float64))
    scale = np.abs(expected_np.astype(np.float64))
    rel_diff = abs_diff / np.maximum(scale, 1e-12)
    report = ParityReport(
        max_abs_diff=float(abs_diff.max(initial=0.0)),
        max_rel_diff=float(rel_diff.max(initial=0.0)),
        ort_ms=ort_ms,
        torch_ms=torch_ms,
        output_shape=tuple(expected_np.shape),
        max_allowance_used=float(
            (abs_diff / np.maximum(atol + rtol * scale, 1e-300)).max(initial=0.0) if abs_diff.size else 0.0
        ),
    )
    if not np.isfinite(actual).all() or (abs_diff > atol + rtol * scale).any():
        raise OnnxParityError(
            f"ONNX Runtime output {output_name!r} of {path} differs from PyTorch: "
            f"max abs diff {report.max_abs_diff:.3g}, max rel diff {report.max_rel_diff:.3g} "
            f"(allowed |diff| <= {atol:g} + {rtol:g} * |torch|), shape {report.output_shape}"
        )
    return report


def _check_inputs(inputs: Mapping[str, Tensor], arg: str) -> None:
    if not inputs:
        raise ValueError(f"{arg} must name at least one tensor, e.g. {{'image': x}}")
    for name, value in inputs.items():
        if not isinstance(value, Tensor):
            raise ValueError(f"{arg}[{name!r}] must be a torch.Tensor, got {type(value).__name__}")


def _check_signature(model: nn.Module, inputs: Mapping[str, Tensor]) -> None:
    # torch.export reports a name mismatch deep inside a long trace; say it plainly up front.
    try:
        inspect.signature(model.forward).bind(**inputs)
    except TypeError as err:
        params = list(inspect.signature(model.forward).parameters)
        raise ValueError(
            f"example_inputs names {list(inputs)} do not fit {type(model).__name__}.forward{params}: {err}"
        ) from None


def _dynamic_shapes(
    inputs: Mapping[str, Tensor], dynamic_batch: bool, dynamic_spatial: bool
) -> dict[str, dict[int, object]] | None:
    if not (dynamic_batch or dynamic_spatial):
        return None

    # One shared Dim ties the batch of every input together, which is what the model requires anyway.
    batch = Dim("batch", min=1, max=65536)
    shapes: dict[str, dict[int, object]] = {}
    for name, tensor in inputs.items():
        dims: dict[int, object] = {}
        if dynamic_batch:
            dims[0] = batch
        if dynamic_spatial and tensor.ndim >= 4:
            # DYNAMIC lets torch.export derive the relation between inputs (same H, W) and divisibility itself.
            dims[tensor.ndim - 2] = Dim.DYNAMIC
            dims[tensor.ndim - 1] = Dim.DYNAMIC
        shapes[name] = dims
    return shapes


def median_ms(fn, repeats: int) -> float:
    """Median wall time of ``fn()`` in milliseconds over ``repeats`` calls, after one warm-up call."""
    fn()  # warm-up: first calls allocate and pick kernels
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append((time.perf_counter() - start) * 1e3)
    return float(np.median(times))


def first_line(err: BaseException) -> str:
    """The first line of an exception's message (exporters and quantisers raise pages of text)."""
    text = str(err).strip()
    return text.splitlines()[0] if text else ""


def size_mb(path: Path | None) -> str:
    """A file's size for a report, ``"?"`` when there is none."""
    return f"{path.stat().st_size / 1e6:.1f} MB" if path is not None and path.exists() else "?"
