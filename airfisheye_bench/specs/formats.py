"""What a task predicts, per pixel: class labels or a range in metres, and how each is stored as a file.

A :class:`PredictionFormat` turns a model's primary output into the metric input and reads, writes and checks the
prediction files of a submission (docs/design.md, "Adding a task"). Two exist: :data:`LABELS` (``seg``) and
:data:`RANGE` (``depth``, ``completion``); a new task that predicts labels or a metric map reuses one of them.

- labels: 8-bit single-channel PNG of training-class ids (255 = no prediction).
- range: 16-bit PNG of ``round(range * 256)`` (0 = no prediction; 1/512 m resolution, up to 256 m) or ``.npy``
  float32/float16 of the range in metres, ``[H, W]`` or ``[1, H, W]``.

Example:
    >>> import tempfile, numpy as np
    >>> from pathlib import Path
    >>> path = Path(tempfile.mkdtemp()) / "000001.png"
    >>> _ = path.write_bytes(RANGE.encode(".png", np.full((2, 3), 10.0, np.float32)))
    >>> RANGE.check(path, (2, 3)), RANGE.decode(path).shape, float(RANGE.decode(path).max())
    (None, torch.Size([1, 2, 3]), 10.0)
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import torch
from PIL import Image
from torch import Tensor

__all__ = ["DEPTH_PNG_SCALE", "LABELS", "RANGE", "LabelMaps", "PredictionFormat", "RangeMaps"]

#: Depth PNGs hold ``round(range * 256)`` like the dataset's depth files.
DEPTH_PNG_SCALE = 256.0
_NPY_DTYPES = (np.dtype("<f4"), np.dtype("<f2"))


class PredictionFormat:
    """Per-pixel predictions of one kind. Subclasses say how outputs become predictions and files.

    Attributes:
        name: ``labels`` or ``range``.
        suffixes: File suffixes a submission may use, the default first.
    """

    name: str
    suffixes: tuple[str, ...]

    def from_output(self, output: Tensor) -> Tensor:
        """A model's primary output as the metric input (labels ``[B, H, W]`` or values ``[B, 1, H, W]``)."""
        raise NotImplementedError

    def suffix(self, file_format: str = "png") -> str:
        """The suffix a writer uses for ``file_format`` (``png`` or ``npy``; formats without a choice ignore it)."""
        return self.suffixes[0]

    def encode(self, suffix: str, array: np.ndarray) -> bytes:
        """The file contents of a prediction ``[H, W]`` stored with ``suffix``; ``ValueError`` if it cannot be."""
        raise NotImplementedError

    def decode(self, path: Path) -> Tensor:
        """Decode one checked prediction file."""
        raise NotImplementedError

    def check(self, path: Path, shape: tuple[int, int]) -> str | None:
        """What is wrong with a prediction file of image size ``shape`` ``(H, W)``, from its header only."""
        raise NotImplementedError

    def _check_png(self, path: Path, shape: tuple[int, int], modes: tuple[str, ...], kind: str) -> str | None:
        try:
            with Image.open(path) as image:
                size, mode, fmt = (image.height, image.width), image.mode, image.format
        except (OSError, SyntaxError) as err:
            return f"not a readable PNG ({err})"
        if fmt != "PNG":
            return f"is a {fmt} file, expected PNG"
        if mode not in modes:
            return f"PNG mode {mode}, expected a {kind} PNG"
        if size != tuple(shape):
            return f"size {size[0]}x{size[1]}, expected {shape[0]}x{shape[1]} (HxW)"
        return None

    def __repr__(self) -> str:
        return f"<prediction format {self.name}>"


class LabelMaps(PredictionFormat):
    """Class ids per pixel; logits are reduced by ``argmax`` over channels."""

    name = "labels"
    suffixes = (".png",)

    def from_output(self, output: Tensor) -> Tensor:
        return output.argmax(1) if output.ndim == 4 else output.long()

    def encode(self, suffix: str, array: np.ndarray) -> bytes:
        if array.min(initial=0) < 0 or array.max(initial=0) > 255:
            raise ValueError("labels must be in 0..255")
        buf = io.BytesIO()
        Image.fromarray(array.astype(np.uint8), mode="L").save(buf, format="PNG")
        return buf.getvalue()

    def decode(self, path: Path) -> Tensor:
        with Image.open(path) as image:
            return torch.from_numpy(np.asarray(image).astype(np.int64))

    def check(self, path: Path, shape: tuple[int, int]) -> str | None:
        return self._check_png(path, shape, ("L", "P"), "8-bit single-channel label")


class RangeMaps(PredictionFormat):
    """A non-negative value in metres per pixel (0 = none), as 16-bit PNG (``range * 256``) or float ``.npy``."""

    name = "range"
    suffixes = (".png", ".npy")

    def from_output(self, output: Tensor) -> Tensor:
        return output if output.ndim == 4 else output.unsqueeze(1)

    def suffix(self, file_format: str = "png") -> str:
        if f".{file_format}" not in self.suffixes:
            raise ValueError(f"prediction_format must be 'png' or 'npy', got {file_format!r}")
        return f".{file_format}"

    def encode(self, suffix: str, array: np.ndarray) -> bytes:
        # A file holds finite values only (a submission holding others is refused): NaN and -inf become 0 (no
        # prediction) and +inf the largest value the file can hold, which the metrics clamp to max_depth as they
        # clamp +inf, so saved predictions score as the model's own output did.
        buf = io.BytesIO()
        if suffix == ".npy":
            top = float(np.finfo(np.float32).max)
            clean = np.nan_to_num(array.astype(np.float32), nan=0.0, posinf=top, neginf=0.0)
            np.save(buf, clean, allow_pickle=False)
        else:
            top = 65535 / DEPTH_PNG_SCALE
            clean = np.clip(np.nan_to_num(array, nan=0.0, posinf=top, neginf=0.0), 0, top)
            Image.fromarray(np.round(clean * DEPTH_PNG_SCALE).astype(np.uint16)).save(buf, format="PNG")
        return buf.getvalue()

    def decode(self, path: Path) -> Tensor:
        if path.suffix == ".npy":
            array = np.load(path, allow_pickle=False).astype(np.float32)
            return torch.from_numpy(array.reshape(1, *array.shape[-2:]))
        with Image.open(path) as image:
            array = np.asarray(image)
        return torch.from_numpy(array.astype(np.float32) / DEPTH_PNG_SCALE)[None]

    def check(self, path: Path, shape: tuple[int, int]) -> str | None:
        if path.suffix == ".npy":
            return _check_npy(path, shape)
        return self._check_png(path, shape, ("I;16", "I;16B", "I"), "16-bit depth (range * 256)")


def _check_npy(path: Path, shape: tuple[int, int]) -> str | None:
    try:
        with path.open("rb") as f:
            version = np.lib.format.read_magic(f)
            header = (
                np.lib.format.read_array_header_1_0(f)
                if version == (1, 0)
                else np.lib.format.read_array_header_2_0(f)
            )
    except (OSError, ValueError) as err:
        return f"not a readable .npy file ({err})"
    array_shape, _, dtype = header
    if dtype.hasobject or dtype not in _NPY_DTYPES:
        return f"dtype {dtype}, expected float32 or float16 range in metres"
    if tuple(array_shape) not in (tuple(shape), (1, *shape)):
        return f"shape {tuple(array_shape)}, expected {tuple(shape)} or {(1, *shape)}"
    return None


#: Class-label predictions (``seg``).
LABELS = LabelMaps()
#: Range predictions in metres (``depth``, ``completion``).
RANGE = RangeMaps()
