"""Atomic file writes: write to a hidden temporary name in the same folder, then rename.

A reader (or a resumed generator) therefore never sees a half-written file: a path either does not exist or
holds complete contents. Renames within one folder are atomic on POSIX and Windows (``os.replace``).
Stray temporaries from a killed process match :data:`TEMP_GLOB` and can be removed with
:func:`remove_stale_temporaries`. Work that several processes may start at once (generating a cached dataset, a
test session's shared run) is done once under :func:`exclusive_lock`.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

from airfisheye_bench.errors import OutputError

try:
    import fcntl
except ImportError:  # Windows: no advisory locks; callers rely on the atomic rename of what they finish
    fcntl = None

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
    atomic_write(path, lambda tmp: tmp.write_bytes(data))


def atomic_write(path: str | Path, write: Callable[[Path], object]) -> None:
    """Let ``write(tmp)`` fill a temporary file next to ``path``, then rename it over ``path``.

    A reader (or a process resumed after a kill) sees the previous file or the new one, never half of one; the
    temporary is removed if ``write`` fails or the process is interrupted (a kill leaves it: see
    :func:`remove_stale_temporaries`).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.tmp")
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` atomically (``\\n`` line endings on every platform)."""
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: str | Path, payload: object, indent: int = 2) -> None:
    """Write ``payload`` as JSON to ``path`` atomically, NaN and infinities as ``null``.

    A study's summary holds NaN where a statistic has no value (the spread of one seed, an interval of one pair);
    Python would write ``NaN``, which is not JSON and which other readers reject.

    Example:
        >>> import tempfile, pathlib
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "s.json"
        >>> atomic_write_json(p, {"sd": float("nan"), "n": 1}, indent=None)
        >>> p.read_text()
        '{"sd": null, "n": 1}\\n'
    """
    clean = json.loads(json.dumps(payload), parse_constant=lambda _: None)
    atomic_write_text(path, json.dumps(clean, indent=indent, allow_nan=False) + "\n")


def check_writable(path: str | Path, key: str = "out") -> Path:
    """Refuse, before any long work, an output file that cannot be written; return it as a ``Path``.

    The nearest existing folder of ``path`` must be a folder (not a file) in which a file can be created: that is
    tried for real, since permission bits do not tell (``/proc`` and ``/sys`` refuse even root).

    Args:
        path: The file to be written (its missing parent folders will be created).
        key: The option that named it, for the message.

    Raises:
        OutputError: ``path`` is a folder, a parent is a file, or the folder is not writable (the message names
            the real target and what to do).

    Example:
        >>> import tempfile, pathlib
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> check_writable(folder / "new" / "model.onnx").name
        'model.onnx'
        >>> (folder / "file").write_text("x")
        1
        >>> check_writable(folder / "file" / "model.onnx")  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        airfisheye_bench.errors.OutputError: out=.../file/model.onnx: .../file is a file, not a folder; ...
    """
    path = Path(path)
    if path.is_dir():
        raise OutputError(
            f"{key}={path} is a folder; give the file to write, e.g. {key}={path / 'model.onnx'}"
        )
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise OutputError(f"{key}={path}: {folder} is a file, not a folder; choose another {key}=")
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as err:
        raise OutputError(
            f"{key}={path}: cannot write into {folder} ({err.strerror or err}); choose a writable folder"
        ) from None
    return path


def remove_stale_temporaries(root: str | Path) -> int:
    """Delete temporaries left under ``root`` by interrupted writes; returns how many were removed."""
    count = 0
    for tmp in Path(root).rglob(TEMP_GLOB):
        if tmp.is_file():
            tmp.unlink(missing_ok=True)
            count += 1
    return count


@contextlib.contextmanager
def exclusive_lock(path: str | Path) -> Iterator[None]:
    """Hold an exclusive inter-process lock on the file ``path`` (created, with its folders) for a ``with`` block.

    Blocks until no other process holds it (``fcntl.flock``, POSIX); elsewhere it locks nothing (best effort: the
    callers' results are renamed into place when complete).

    Example:
        >>> import tempfile, pathlib
        >>> lock = pathlib.Path(tempfile.mkdtemp()) / "a" / "work.lock"
        >>> with exclusive_lock(lock):
        ...     lock.is_file()
        True
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a+") as handle:
        if fcntl is None:
            yield
            return
        fcntl.flock(handle.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle.fileno(), fcntl.LOCK_UN)
