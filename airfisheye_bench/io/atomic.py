"""Atomic file writes: write to a hidden temporary name in the same folder, then rename.

A reader (or a resumed generator) therefore never sees a half-written file: a path either does not exist or
holds complete contents. Renames within one folder are atomic on POSIX and Windows (``os.replace``).
Stray temporaries from a killed process match :data:`TEMP_GLOB` and can be removed with
:func:`remove_stale_temporaries`.
"""

from __future__ import annotations

import os
import uuid
from pathlib import Path

#: Glob matching the temporary names used by :func:`atomic_write_bytes` (``.<name>.<hex>.tmp``).
TEMP_GLOB = ".*.tmp"


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically, creating parent folders.

    Args:
        path: Destination file; replaced if it exists.
        data: Complete file contents.

    Example:
        >>> import tempfile, pathlib
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "a" / "b.txt"
        >>> atomic_write_bytes(p, b"hello")
        >>> p.read_bytes()
        b'hello'
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.tmp")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` atomically (``\\n`` line endings on every platform)."""
    atomic_write_bytes(path, text.encode("utf-8"))


def remove_stale_temporaries(root: str | Path) -> int:
    """Delete temporaries left under ``root`` by interrupted writes; returns how many were removed."""
    count = 0
    for tmp in Path(root).rglob(TEMP_GLOB):
        if tmp.is_file():
            tmp.unlink(missing_ok=True)
            count += 1
    return count
