"""Where predictions come from: a trained checkpoint, an exported ONNX model, or a folder of prediction files.

Each predictor turns a collated batch into the prediction the task's metric takes (labels ``[B, H, W]`` or range
``[B, 1, H, W]``), so :func:`airfisheye_bench.evaluation.evaluate_predictions` scores all three the same way.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch
from torch import Tensor
from torch.utils.data import Dataset

from airfisheye_bench.errors import MissingFileError
from airfisheye_bench.evaluation.submission import read_prediction, validate_submission
from airfisheye_bench.io.manifest import sha256_file
from airfisheye_bench.runs.deployment import read_deployment_metadata
from airfisheye_bench.specs import get_task

__all__ = [
    "TTA_MODES",
    "CheckpointPredictor",
    "FilePredictor",
    "OnnxPredictor",
    "PredictionFilesDataset",
    "Predictor",
    "check_tta",
    "flip_tta",
    "to_prediction",
]

#: Test-time augmentations of model predictions: ``None`` (off) or ``"flip"`` (see :func:`flip_tta`).
TTA_MODES = (None, "flip")


class Predictor(Protocol):
    """Anything that predicts a batch for one task."""

    task: str

    def __call__(self, batch: dict) -> Tensor: ...

    def identity(self) -> dict[str, Any]:
        """What was evaluated, for ``results.json`` (name, file, checksum, ...)."""
        ...


def to_prediction(task: str, output: Tensor) -> Tensor:
    """A model's primary output (logits or depth) as the metric input: labels ``[B, H, W]`` or depth ``[B, 1, H, W]``.

    The task's prediction format decides (``TaskSpec.prediction``).
    """
    return get_task(task).prediction.from_output(output)


def check_tta(tta: str | None) -> str | None:
    """``tta`` if it is one of :data:`TTA_MODES`.

    Example:
        >>> check_tta("flip")
        'flip'
        >>> check_tta("rotate")
        Traceback (most recent call last):
        ...
        ValueError: tta must be null or 'flip', got 'rotate'
    """
    if tta not in TTA_MODES:
        raise ValueError(f"tta must be null or 'flip', got {tta!r}")
    return tta


def flip_tta(
    run: Callable[[list[Tensor]], Tensor], inputs: Sequence[Tensor], fixed: Sequence[Tensor] = ()
) -> Tensor:
    """Horizontal-flip test-time augmentation: the mean of the model output and the mirrored output of the
    mirrored inputs, as AdaBins' evaluation (logits for segmentation, depth otherwise).

    Every input (image and, for completion, sparse depth) is mirrored along its width: the served fisheye image is
    symmetric about its vertical centre line, the assumption training's horizontal-flip augmentation makes too. The
    ``fixed`` inputs are passed as they are: a camera-aware model's ray map describes the lens, which a mirrored
    image keeps (training's flip keeps the map too).

    Args:
        run: the model, called with the list of input tensors ``[B, C, H, W]``, returning ``[B, C', H, W]``.
        inputs: the model inputs that are mirrored.
        fixed: inputs after them that are not (the ray map).

    Example:
        >>> x = torch.arange(4.0).view(1, 1, 1, 4)
        >>> flip_tta(lambda xs: xs[0] * torch.tensor([1.0, 0.0, 0.0, 0.0]), [x]).tolist()
        [[[[0.0, 0.0, 0.0, 1.5]]]]
    """
    inputs, fixed = list(inputs), list(fixed)
    mirrored = run([*(t.flip(-1) for t in inputs), *fixed]).flip(-1)
    return 0.5 * (run([*inputs, *fixed]) + mirrored)


class CheckpointPredictor:
    """Predictions of a trained task module (see :func:`airfisheye_bench.tasks.load_task`).

    Args:
        module: The task module, weights loaded.
        checkpoint: Its file (recorded in the results).
        device: Where to run the model.
        tta: Test-time augmentation, one of :data:`TTA_MODES`.
    """

    def __init__(
        self,
        module,
        checkpoint: str | Path | None = None,
        device: str | torch.device = "cpu",
        tta: str | None = None,
    ) -> None:
        self.module = module.to(device).eval()
        self.task = module.task
        self.device = torch.device(device)
        self.checkpoint = Path(checkpoint) if checkpoint else None
        self.tta = check_tta(tta)

    def __call__(self, batch: dict) -> Tensor:
        return to_prediction(self.task, self.output(batch))

    @torch.no_grad()
    def output(self, batch: dict) -> Tensor:
        """The model's primary output (logits or depth, with the TTA) on the CPU: what ``__call__`` turns into the
        prediction, and what a wrapper that blends outputs (:mod:`~airfisheye_bench.evaluation.perspective`) takes.
        The ray map is fed as it is under flip TTA: a lens symmetric about its principal point mirrors onto itself."""
        inputs = [batch[key].to(self.device, non_blocking=True) for key in get_task(self.task).inputs]
        fixed = [self._rays(batch)] if self.takes_rays else []
        output = flip_tta(self._run, inputs, fixed) if self.tta == "flip" else self._run([*inputs, *fixed])
        return output.cpu()

    @property
    def takes_rays(self) -> bool:
        """Whether the model takes the batch's ray map (``model.camera_input=rays``)."""
        return self.module.camera_input == "rays"

    def _rays(self, batch: dict) -> Tensor | None:
        """The batch's ray map on the device (``None``, which the model refuses in one line, when it has none)."""
        rays = batch.get("rays")
        return None if rays is None else rays.to(self.device, non_blocking=True)

    def _run(self, inputs: list[Tensor]) -> Tensor:
        return self.module(*inputs)

    def identity(self) -> dict[str, Any]:
        model = dict(self.module.hparams.get("model", {}))
        out: dict[str, Any] = {"source": "checkpoint", "name": model.get("name"), "config": model}
        if self.checkpoint is not None:
            out.update(checkpoint=str(self.checkpoint), sha256=sha256_file(self.checkpoint))
        out.update(weights=self.module.hparams.get("weights"), tta=self.tta)
        return out


class OnnxPredictor:
    """Predictions of an exported ``.onnx`` model run by ONNX Runtime.

    Args:
        path: The model file; its deployment metadata says the task and the input names.
        threads: Intra-op threads (``None``: ONNX Runtime's default).
        providers: Execution providers (default CPU).
        tta: Test-time augmentation, one of :data:`TTA_MODES`.
    """

    def __init__(
        self,
        path: str | Path,
        threads: int | None = None,
        providers: list[str] | None = None,
        tta: str | None = None,
    ) -> None:
        import onnxruntime as ort  # loaded on use: only ONNX predictions need it

        self.path = Path(path)
        self.tta = check_tta(tta)
        if not self.path.is_file():
            raise MissingFileError(f"ONNX model {self.path} does not exist")
        self.metadata = read_deployment_metadata(self.path)
        self.task = self.metadata["task"]
        options = ort.SessionOptions()
        if threads:
            options.intra_op_num_threads = int(threads)
        self.session = ort.InferenceSession(
            str(self.path), sess_options=options, providers=providers or ["CPUExecutionProvider"]
        )
        names = [i.name for i in self.session.get_inputs()]
        # The ray map (a camera-aware model's input) is fed as it is; the other inputs are mirrored by flip TTA.
        self.input_names = [*(n for n in names if n != "rays"), *(n for n in names if n == "rays")]
        self.output_name = self.session.get_outputs()[0].name
        # ``(H, W)`` when the graph fixes the image size, ``None`` when exported with dynamic spatial dims.
        spatial = self.session.get_inputs()[0].shape[-2:]
        self.fixed_size = tuple(spatial) if all(isinstance(d, int) for d in spatial) else None

    def __call__(self, batch: dict) -> Tensor:
        return to_prediction(self.task, self.output(batch))

    def output(self, batch: dict) -> Tensor:
        """The model's primary output (logits or depth, with the TTA), as :meth:`CheckpointPredictor.output`."""
        missing = [n for n in self.input_names if n not in batch]
        if missing:
            raise ValueError(f"{self.path}: the batch lacks the model inputs {missing} (has {sorted(batch)})")
        inputs = [batch[n].detach().cpu().float() for n in self.input_names if n != "rays"]
        fixed = [batch[n].detach().cpu().float() for n in self.input_names if n == "rays"]
        return flip_tta(self._run, inputs, fixed) if self.tta == "flip" else self._run([*inputs, *fixed])

    @property
    def takes_rays(self) -> bool:
        """Whether the file takes the ray map as an input (a camera-aware model whose map is not baked in)."""
        return "rays" in self.input_names

    def _run(self, inputs: list[Tensor]) -> Tensor:
        feed = {n: np.ascontiguousarray(t.numpy()) for n, t in zip(self.input_names, inputs, strict=True)}
        output = self.session.run([self.output_name], feed)[0]
        return torch.from_numpy(np.ascontiguousarray(output))

    def identity(self) -> dict[str, Any]:
        return {
            "source": "onnx",
            "name": self.metadata.get("model"),
            "onnx": str(self.path),
            "precision": onnx_precision(self.path),
            "sha256": sha256_file(self.path),
            "config": self.metadata.get("model_config"),
            "source_checkpoint": self.metadata.get("source_checkpoint"),
            "weights": self.metadata.get("weights"),
            "tta": self.tta,
        }


#: Operators only a quantised graph holds (onnxruntime.quantization writes them; an fp32 export never does).
_QUANTISED_OPS = frozenset(
    {
        "QuantizeLinear",
        "DequantizeLinear",
        "DynamicQuantizeLinear",
        "QLinearConv",
        "QLinearMatMul",
        "ConvInteger",
        "MatMulInteger",
    }
)


def onnx_precision(path: str | Path) -> str:
    """``int8`` for a quantised ONNX model, ``fp32`` otherwise, read from its graph's operators.

    The deployment metadata is copied unchanged onto the int8 model, so the graph is what tells them apart.

    Example:
        >>> import tempfile, onnx
        >>> from onnx import TensorProto, helper
        >>> x = helper.make_tensor_value_info("x", TensorProto.FLOAT, [1])
        >>> graph = helper.make_graph([helper.make_node("Relu", ["x"], ["y"])], "g", [x], [x])
        >>> path = tempfile.mkdtemp() + "/m.onnx"
        >>> onnx.save(helper.make_model(graph), path)
        >>> onnx_precision(path)
        'fp32'
    """
    import onnx  # optional heavy dependency: only ONNX evaluation needs it

    graph = onnx.load(str(path), load_external_data=False).graph
    return "int8" if any(node.op_type in _QUANTISED_OPS for node in graph.node) else "fp32"


class PredictionFilesDataset(Dataset):
    """A split's dataset with each frame's prediction file decoded next to it (in the loader workers).

    Args:
        base: The ground-truth dataset (samples carry ``sample_id``).
        files: Validated prediction file of every frame id (:func:`validate_submission`).
        task: Which decoding to use.
    """

    def __init__(self, base: Dataset, files: dict[str, Path], task: str) -> None:
        self.base, self.files, self.task = base, files, task

    def __len__(self) -> int:
        return len(self.base)  # type: ignore[arg-type]

    def __getitem__(self, index: int) -> dict | None:
        sample = self.base[index]
        if sample is not None:
            sample["prediction"] = read_prediction(self.files[sample["sample_id"]], self.task)
        return sample


class FilePredictor:
    """Predictions read from a submission folder (validated as a whole when constructed).

    Args:
        root: The prediction folder.
        task: A registered task (``seg``, ``depth``, ``completion``).
        sample_ids: Frames of the evaluated split.
        shape: Served image size ``(H, W)``.
        name: Label of the submission in the results (default: the folder name).
    """

    def __init__(
        self,
        root: str | Path,
        task: str,
        sample_ids: list[str],
        shape: tuple[int, int],
        name: str | None = None,
    ) -> None:
        self.root = Path(root)
        self.task = task
        self.files = validate_submission(self.root, task, sample_ids, shape)
        self.name = name or self.root.resolve().name

    def wrap(self, dataset: Dataset) -> PredictionFilesDataset:
        """The dataset whose samples carry their ``prediction`` (decoded in parallel by the loader)."""
        return PredictionFilesDataset(dataset, self.files, self.task)

    def __call__(self, batch: dict) -> Tensor:
        if "prediction" not in batch:
            raise ValueError("FilePredictor needs batches from FilePredictor.wrap(dataset)")
        return batch["prediction"]

    def identity(self) -> dict[str, Any]:
        digest = hashlib.sha256()
        for sample_id in sorted(self.files):
            digest.update(f"{sample_id}:{sha256_file(self.files[sample_id])}\n".encode())
        return {
            "source": "predictions",
            "name": self.name,
            "predictions": str(self.root),
            "sha256": digest.hexdigest(),
        }
