"""A refused command leaves no folder behind: the run directory Hydra made for it is taken back.

Hydra creates the run directory (``hydra.run.dir``), and any missing parent such as ``logs/seg/runs``, before the
application runs; the application checks everything before it writes there, so a refused command would leave an
empty folder. :class:`RunDirRecord` (a Hydra callback of ``configs/hydra/default.yaml`` and
``configs/evaluate.yaml``) notes which of those folders did not exist when the command started, and
:func:`takes_back_run_dir` removes them again when the application fails, innermost first, each only while it is
empty: a folder that existed before the command (a resumed run, a folder given by ``hydra.run.dir``) or that holds
anything is never removed.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from hydra.experimental.callback import Callback
from omegaconf import DictConfig

F = TypeVar("F", bound=Callable[..., Any])

#: The folders this command's run directory brings: the run directory, then each missing parent (innermost first).
_new_folders: list[Path] = []


def missing_folders(folder: Path) -> list[Path]:
    """``folder`` and its parents that do not exist, innermost first.

    Example:
        >>> import tempfile
        >>> base = Path(tempfile.mkdtemp())
        >>> [p.relative_to(base).as_posix() for p in missing_folders(base / "logs" / "seg")]
        ['logs/seg', 'logs']
        >>> missing_folders(base)
        []
    """
    folder = folder.absolute()
    missing = []
    while not folder.exists() and not folder.is_symlink() and folder.parent != folder:
        missing.append(folder)
        folder = folder.parent
    return missing


class RunDirRecord(Callback):
    """Notes, before Hydra makes it, which folders of the run directory are new (see the module docstring).

    A multirun's jobs (``<sweep>/<job>``) are not taken back: Hydra writes the sweep folder's own files first.
    """

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        _new_folders.clear()
        try:
            run_dir = Path(str(config.hydra.run.dir))
        except Exception:  # an unresolvable run directory: Hydra itself reports it, next
            return
        _new_folders.extend(missing_folders(run_dir))

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        _new_folders.clear()


def remove_new_run_dir() -> None:
    """Remove the folders :class:`RunDirRecord` noted, innermost first, while they are empty."""
    folders, _new_folders[:] = list(_new_folders), []
    for folder in folders:
        try:
            folder.rmdir()  # only an empty folder: anything written into it keeps it, and its parents
        except OSError:
            return


def takes_back_run_dir(function: F) -> F:
    """Decorate a Hydra application: when it fails (a user error or any other), the run directory Hydra made for
    it is removed while empty (:func:`remove_new_run_dir`)."""

    @functools.wraps(function)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return function(*args, **kwargs)
        except BaseException:
            remove_new_run_dir()
            raise
        finally:
            _new_folders.clear()

    return wrapper  # type: ignore[return-value]
