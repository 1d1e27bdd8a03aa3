"""Which files a piece of code opens: Python's ``open`` audit event (every ``open()``, ``Path.read_text``, numpy and
yaml reads go through it), recorded while :func:`opened_files` is active.

Example:
    >>> from pathlib import Path
    >>> with opened_files() as paths:
    ...     _ = Path(__file__).read_text()
    >>> Path(__file__).resolve() in paths
    True
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator
from pathlib import Path

_active: list[list[Path]] = []
_installed = False


def _hook(event: str, args: tuple) -> None:
    if event == "open" and _active and isinstance(args[0], (str, bytes, os.PathLike)):
        path = Path(os.fsdecode(args[0]))
        for paths in _active:
            paths.append(path.resolve() if path.is_absolute() else (Path.cwd() / path).resolve())


@contextlib.contextmanager
def opened_files() -> Iterator[list[Path]]:
    """The paths opened (resolved, once per open, in order) while the context is active. An audit hook cannot be
    removed, so one is installed per process on first use and records only inside a context."""
    global _installed
    if not _installed:
        sys.addaudithook(_hook)
        _installed = True
    paths: list[Path] = []
    _active.append(paths)
    try:
        yield paths
    finally:
        _active.remove(paths)
