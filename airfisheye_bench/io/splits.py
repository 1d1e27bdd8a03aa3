"""Split files: ``splits/<name>.txt`` with one sample id ``<env>/<trajectory>/<frame>`` per line; the frame-block
rule of a dataset with too few trajectories to split by trajectory."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.io.errors import DatasetFormatError


def parse_sample_id(sample_id: str) -> tuple[str, str, str]:
    """Split ``"<env>/<traj>/<frame>"`` into its three parts.

    Example:
        >>> parse_sample_id("suburban/traj00/000012")
        ('suburban', 'traj00', '000012')
    """
    parts = sample_id.split("/")
    if len(parts) != 3 or not all(parts) or any(p in (".", "..") for p in parts):
        raise ValueError(f"sample_id must look like '<env>/<trajectory>/<frame>', got {sample_id!r}")
    return parts[0], parts[1], parts[2]


def write_split(path: str | Path, sample_ids: list[str]) -> None:
    """Atomically write a split file (ids validated, order kept)."""
    for sid in sample_ids:
        parse_sample_id(sid)
    if len(set(sample_ids)) != len(sample_ids):
        raise ValueError("sample_ids must be unique")
    atomic_write_text(path, "".join(f"{sid}\n" for sid in sample_ids))


def read_split(path: str | Path) -> list[str]:
    """Read a split file; blank lines and ``#`` comments are skipped; errors name the file and line."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise DatasetFormatError(path, "file does not exist") from None
    ids: list[str] = []
    seen: set[str] = set()
    for lineno, line in enumerate(lines, start=1):
        sid = line.strip()
        if not sid or sid.startswith("#"):
            continue
        try:
            parse_sample_id(sid)
        except ValueError as exc:
            raise DatasetFormatError(path, str(exc), key=f"line {lineno}") from None
        if sid in seen:
            raise DatasetFormatError(path, f"duplicate sample id {sid!r}", key=f"line {lineno}")
        seen.add(sid)
        ids.append(sid)
    return ids


def frame_blocks(frames: Sequence[str], period: int) -> dict[str, list[str]]:
    """One trajectory's frames in three contiguous blocks: ``train``, then ``val``, then ``test``, the last two of
    ``len(frames) // period`` frames each (at least one); fewer than 3 frames all go to ``train``.

    Contiguous blocks keep neighbouring (near-duplicate) frames in one split: only the two cuts border another split.

    Example:
        >>> {name: len(ids) for name, ids in frame_blocks([f"{i:06d}" for i in range(25)], 10).items()}
        {'train': 21, 'val': 2, 'test': 2}
        >>> frame_blocks(["000000", "000001", "000002"], 10)
        {'train': ['000000'], 'val': ['000001'], 'test': ['000002']}
    """
    n = len(frames)
    held = max(1, n // period) if n >= 3 else 0
    return {
        "train": list(frames[: n - 2 * held]),
        "val": list(frames[n - 2 * held : n - held]),
        "test": list(frames[n - held :]),
    }
