"""A folder of prediction files (a submission): its layout, validation, reading and writing.

One file per frame of the split, at the frame's id: ``<dir>/<env>/<trajectory>/<frame>.<ext>``, in the task's
prediction format (``TaskSpec.prediction``, :mod:`airfisheye_bench.specs.formats`):

- ``seg``: 8-bit single-channel PNG of training-class ids (255 = no prediction).
- ``depth`` / ``completion``: 16-bit PNG of ``round(range * 256)`` (0 = no prediction; 1/512 m resolution, up to
  256 m) or ``.npy`` float32/float16 of the range in metres, ``[H, W]`` or ``[1, H, W]``.

Submissions come from other people, so nothing in them is trusted: every problem (missing, extra, ambiguous,
wrongly sized or typed files, links leading out of the folder, NaN or infinite values) is collected and reported in
one error, headers are read before any value, and ``.npy`` files are loaded with ``allow_pickle=False``.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
import torch

from airfisheye_bench.atomic import atomic_write_bytes
from airfisheye_bench.errors import MissingFileError, OutputExistsError, UserError
from airfisheye_bench.specs import DEPTH_PNG_SCALE, get_task
from airfisheye_bench.specs.formats import RANGE

__all__ = [
    "DEPTH_FORMATS",
    "DEPTH_PNG_SCALE",
    "SubmissionError",
    "SubmissionWriter",
    "read_prediction",
    "validate_submission",
    "write_prediction",
    "write_submission",
]

#: Encodings of a depth or completion prediction (``prediction_format``): 16-bit PNG of ``round(range * 256)``
#: or float ``.npy``.
DEPTH_FORMATS = tuple(suffix.lstrip(".") for suffix in RANGE.suffixes)
_MAX_LISTED = 20


class SubmissionError(UserError, ValueError):
    """A prediction folder that cannot be evaluated; ``problems`` lists every reason."""

    def __init__(self, root: Path, problems: list[str]) -> None:
        self.root = root
        self.problems = problems
        shown = problems[:_MAX_LISTED]
        more = f"\n  ... and {len(problems) - len(shown)} more" if len(problems) > len(shown) else ""
        super().__init__(
            f"prediction folder {root} is not a valid submission ({len(problems)} problems):\n  "
            + "\n  ".join(shown)
            + more
        )


def validate_submission(
    root: str | Path, task: str, sample_ids: Sequence[str], shape: tuple[int, int]
) -> dict[str, Path]:
    """Check a prediction folder against the frames of a split before anything is scored.

    Each file's header is checked first (type, size); the values of a well-formed ``.npy`` are then scanned for NaN
    and infinity, which the metrics would otherwise average in silently (a PNG holds integers only).

    Args:
        root: The prediction folder.
        task: A registered task (its prediction format says which file types are allowed).
        sample_ids: The split's frame ids ``<env>/<trajectory>/<frame>``.
        shape: The served image size ``(H, W)`` every prediction must have.

    Returns:
        The prediction file of every frame id.

    Raises:
        SubmissionError: listing all missing, extra, ambiguous, escaping, wrongly sized or typed files, and the
            files holding NaN or infinite values with their counts.

    Example:
        >>> import tempfile, numpy as np
        >>> root = Path(tempfile.mkdtemp())
        >>> _ = write_prediction(root / "env/traj/000001.npy", np.ones((4, 6), np.float32), "depth")
        >>> sorted(validate_submission(root, "depth", ["env/traj/000001"], (4, 6)))
        ['env/traj/000001']
        >>> validate_submission(root, "depth", ["env/traj/000001", "env/traj/000002"], (4, 6))
        Traceback (most recent call last):
        ...
        airfisheye_bench.evaluation.submission.SubmissionError: prediction folder ... (1 problems):
          env/traj/000002: missing (expected env/traj/000002.png or env/traj/000002.npy)
    """
    fmt = get_task(task).prediction
    root = Path(root).expanduser()
    if not root.is_dir():
        raise MissingFileError(f"prediction folder {root} does not exist or is not a directory")
    base = root.resolve()
    suffixes = fmt.suffixes
    problems: list[str] = []
    found: dict[str, Path] = {}
    expected: set[Path] = set()
    for sample_id in sample_ids:
        candidates = [root / f"{sample_id}{s}" for s in suffixes]
        expected.update(candidates)
        present = [p for p in candidates if p.exists() or p.is_symlink()]
        if not present:
            problems.append(
                f"{sample_id}: missing (expected {' or '.join(_rel(p, root) for p in candidates)})"
            )
            continue
        if len(present) > 1:
            problems.append(f"{sample_id}: ambiguous, both {' and '.join(_rel(p, root) for p in present)}")
            continue
        path = present[0]
        problem = _check_inside(path, base, root) or fmt.check(path, shape) or _check_finite(path)
        if problem:
            problems.append(f"{_rel(path, root)}: {problem}")
        else:
            found[sample_id] = path
    problems.extend(
        f"{_rel(p, root)}: extra file, not a frame of the split" for p in _extra_files(root, expected)
    )
    if problems:
        raise SubmissionError(root, problems)
    return found


def read_prediction(path: str | Path, task: str) -> torch.Tensor:
    """Decode one validated prediction file: labels ``int64 [H, W]`` or range ``float32 [1, H, W]`` in metres."""
    return get_task(task).prediction.decode(Path(path))


def write_prediction(path: str | Path, prediction: np.ndarray | torch.Tensor, task: str) -> Path:
    """Write one prediction in the submission format, atomically; the suffix of ``path`` picks the encoding.

    Args:
        path: ``.png`` (labels, or depth as ``round(range * 256)`` in 16 bits) or ``.npy`` (depth, float32).
        prediction: Labels ``[H, W]`` or range in metres ``[H, W]`` / ``[1, H, W]``.
        task: A registered task (``seg``, ``depth``, ``completion``).
    """
    path = Path(path)
    fmt = get_task(task).prediction
    array = np.asarray(prediction.detach().cpu() if isinstance(prediction, torch.Tensor) else prediction)
    array = array.reshape(array.shape[-2:])
    if path.suffix not in fmt.suffixes:
        raise ValueError(f"{path}: a {task} prediction is written as {' or '.join(fmt.suffixes)}")
    try:
        data = fmt.encode(path.suffix, array)
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from None
    return atomic_write_bytes(path, data)


class SubmissionWriter:
    """Write a prediction folder frame by frame into a temporary sibling, renamed into place on success.

    Use as a context manager: leaving the block normally publishes the folder, an exception deletes it.

    Args:
        root: Destination folder; must not exist yet (a new submission is never mixed with an old one).
        task: A registered task (``seg``, ``depth``, ``completion``).
        depth_format: ``png`` (16-bit, the released depth format) or ``npy`` (float32, exact); range predictions
            only (labels are always PNG).

    Example:
        >>> import tempfile, numpy as np
        >>> root = Path(tempfile.mkdtemp()) / "preds"
        >>> with SubmissionWriter(root, "seg") as writer:
        ...     writer.add("env/traj/000001", np.zeros((4, 6), np.uint8))
        >>> sorted(p.relative_to(root).as_posix() for p in root.rglob("*.png"))
        ['env/traj/000001.png']
    """

    def __init__(self, root: str | Path, task: str, depth_format: str = "png") -> None:
        self.root = Path(root)
        if self.root.exists():
            raise OutputExistsError(f"{self.root} already exists; choose a new folder for the predictions")
        fmt = get_task(task).prediction
        if depth_format not in DEPTH_FORMATS:
            raise ValueError(f"depth_format must be one of {DEPTH_FORMATS}, got {depth_format!r}")
        self.task = task
        self.suffix = fmt.suffix(depth_format)
        self._tmp: Path | None = None

    def __enter__(self) -> SubmissionWriter:
        self.root.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = Path(tempfile.mkdtemp(prefix=f".{self.root.name}.", dir=self.root.parent))
        return self

    def add(self, sample_id: str, prediction: np.ndarray | torch.Tensor) -> Path:
        """Write the prediction of one frame."""
        if self._tmp is None:
            raise RuntimeError("SubmissionWriter.add outside its `with` block")
        return write_prediction(self._tmp / f"{sample_id}{self.suffix}", prediction, self.task)

    def add_batch(self, batch: dict, predictions: torch.Tensor) -> None:
        """Write the predictions of a collated batch (frame ids from ``batch["sample_id"]``)."""
        for sample_id, prediction in zip(batch["sample_id"], predictions, strict=True):
            self.add(sample_id, prediction)

    def __exit__(self, exc_type, exc, tb) -> None:
        assert self._tmp is not None
        if exc_type is None:
            self._tmp.rename(self.root)
        else:
            shutil.rmtree(self._tmp, ignore_errors=True)
        self._tmp = None


def write_submission(
    root: str | Path,
    task: str,
    predictions: Iterable[tuple[str, np.ndarray | torch.Tensor]],
    depth_format: str = "png",
) -> Path:
    """Write a whole prediction folder from ``(sample_id, prediction)`` pairs (see :class:`SubmissionWriter`)."""
    with SubmissionWriter(root, task, depth_format) as writer:
        for sample_id, prediction in predictions:
            writer.add(sample_id, prediction)
    return Path(root)


def _rel(path: Path, root: Path) -> str:
    try:
        return path.relative_to(root).as_posix()
    except ValueError:
        return str(path)


def _check_inside(path: Path, base: Path, root: Path) -> str | None:
    """A link (or ``..`` in an id) must not lead out of the submission folder."""
    try:
        resolved = path.resolve(strict=True)
    except (OSError, RuntimeError):
        return "broken link"
    if not resolved.is_relative_to(base):
        return f"leads outside the prediction folder (to {resolved})"
    if not resolved.is_file():
        return "not a regular file"
    return None


def _check_finite(path: Path) -> str | None:
    """The count of NaN and infinite values of a ``.npy`` prediction whose header was accepted."""
    if path.suffix != ".npy":
        return None  # PNG predictions hold integers
    try:
        array = np.load(path, mmap_mode="r", allow_pickle=False)
        finite = int(np.count_nonzero(np.isfinite(array)))
        nan = int(np.count_nonzero(np.isnan(array)))
    except (OSError, ValueError) as err:  # e.g. truncated after its header
        return f"not a readable .npy file ({err})"
    if finite == array.size:
        return None
    return (
        f"{array.size - finite} of {array.size} values are not finite ({nan} NaN, {array.size - finite - nan} "
        "infinite); write 0 where there is no prediction"
    )


def _extra_files(root: Path, expected: set[Path]) -> list[Path]:
    # Hidden files (.DS_Store, editor swap files) are ignored rather than reported.
    return sorted(
        p
        for p in root.rglob("*")
        if (p.is_file() or p.is_symlink())
        and p not in expected
        and not any(part.startswith(".") for part in p.relative_to(root).parts)
    )
