"""User errors: the exception type every mistake of the user's derives from, and the one wrapper of the commands.

A *user error* is a bad config value, a missing, corrupt or unsafe input file, a wrong model file, an output
that cannot be written or an incompatible task: something the user fixes, not the code. Such errors derive from
:class:`UserError` (:class:`~airfisheye_bench.io.errors.DatasetFormatError`,
:class:`~airfisheye_bench.evaluation.submission.SubmissionError`, ``WeightsUnavailableError``, ...), and every
console entry point runs under :func:`report_user_errors`: a user error prints one line, ``error: <message>``, to
stderr and exits with status :data:`EXIT_USER_ERROR` (2, the status of a command-line usage error); anything else
is a bug and keeps its traceback. ``HYDRA_FULL_ERROR=1`` (Hydra's own switch) shows the traceback of user errors
too.

Library functions keep raising the types their callers know (:class:`ConfigError` is also a ``ValueError``,
:class:`InputFileError` a ``ValueError``, :class:`MissingFileError` a ``FileNotFoundError``, ...), so ``except ValueError`` and the like still work.
"""

from __future__ import annotations

import functools
import importlib
import os
import sys
from collections.abc import Callable
from typing import TypeVar

EXIT_USER_ERROR = 2
"""Exit status of a command stopped by a user error (that of a usage error, as argparse uses)."""

DEBUG_ENV = "HYDRA_FULL_ERROR"
"""Set to 1 to see the traceback of user errors as well (Hydra's switch, so one switch serves every command)."""

F = TypeVar("F", bound=Callable[..., object])


class UserError(Exception):
    """Base of the errors the user fixes; the message names the key or file and what to do.

    Example:
        >>> str(UserError("data.root=/nowhere: no such folder; give the dataset's root"))
        "data.root=/nowhere: no such folder; give the dataset's root"
    """


class ConfigError(UserError, ValueError):
    """A configuration value (a Hydra key or a ``key=value`` argument) has the wrong type or range.

    Example:
        >>> err = ConfigError("trainer.max_epochs='abc': expected an integer >= -1 (-1: no limit)")
        >>> isinstance(err, ValueError), isinstance(err, UserError)
        (True, True)
    """


class InputFileError(UserError, ValueError):
    """A file given as input (a checkpoint, an ONNX model) exists but cannot be used; the message names it.

    Example:
        >>> str(InputFileError("model.onnx: not an ONNX model (cannot be parsed); export it again"))
        'model.onnx: not an ONNX model (cannot be parsed); export it again'
    """


class MissingFileError(UserError, FileNotFoundError):
    """A file or folder the user named does not exist; the message names it and what to give instead."""


class OutputError(UserError, OSError):
    """An output cannot be written (its folder is not writable, or is a file); the message names the target."""


class OutputExistsError(UserError, FileExistsError):
    """An output the command refuses to overwrite already exists; the message names it."""


def user_message(err: BaseException) -> str | None:
    """The one-line message of a user error, or ``None`` when ``err`` is a bug (or not an error).

    Errors raised in DataLoader workers reach the main process re-built by PyTorch from their type and formatted
    traceback (a ``RuntimeError`` when the type cannot be re-built from one string): such an error counts as a user
    error when the worker's exception type is one, and its message is the worker's original message.

    Example:
        >>> user_message(ConfigError("data.batch_size=0: expected an integer >= 1"))
        'data.batch_size=0: expected an integer >= 1'
        >>> user_message(KeyError("bug")) is None
        True
        >>> wrapped = RuntimeError(
        ...     "Caught ConfigError in DataLoader worker process 0.\\nOriginal Traceback (most recent call last):\\n"
        ...     '  File "x.py", line 1, in f\\nairfisheye_bench.errors.ConfigError: split file missing\\n'
        ... )
        >>> user_message(wrapped)
        'split file missing'
    """
    if isinstance(err, (RuntimeError, UserError)):
        original = _worker_error(str(err))
        if original is not None:
            return original
    if isinstance(err, UserError):
        return str(err)
    return None


def _worker_error(text: str) -> str | None:
    """The original message of a user error re-raised by PyTorch's DataLoader from a worker process."""
    first, _, rest = text.partition("\n")
    if not (first.startswith("Caught ") and " worker process " in first):
        return None
    # PyTorch keeps only the formatted traceback, which ends with `<module>.<Type>: <message>` (the message may
    # span lines). The type is resolved by import, not compared by name, so only real user-error types qualify.
    lines = rest.rstrip("\n").splitlines()
    for i in range(len(lines) - 1, -1, -1):
        qualname, sep, message = lines[i].partition(": ")
        module, _, name = qualname.rpartition(".")
        if not (sep and module and name.isidentifier()) or lines[i].startswith(" "):
            continue
        try:
            cls = getattr(importlib.import_module(module), name)
        except (ImportError, AttributeError, ValueError):
            continue  # a line of the message that merely looks like `a.b: c`
        if isinstance(cls, type) and issubclass(cls, BaseException):
            return "\n".join([message, *lines[i + 1 :]]) if issubclass(cls, UserError) else None
    return None


def debug_requested() -> bool:
    """Whether ``HYDRA_FULL_ERROR`` asks for full tracebacks (any value but empty or ``0``)."""
    return os.environ.get(DEBUG_ENV, "") not in ("", "0")


def report_user_errors(func: F) -> F:
    """Decorate a command's main function: a user error prints ``error: <message>`` and exits with status 2.

    Anything else propagates with its traceback, as do user errors when ``HYDRA_FULL_ERROR=1``. Under
    ``@hydra.main`` put this decorator below it, so it wraps the task function (Hydra would print a traceback).

    Example:
        >>> @report_user_errors
        ... def main() -> int:
        ...     raise ConfigError("workers=-1: expected an integer >= 1")
        >>> import contextlib, io
        >>> with contextlib.redirect_stderr(io.StringIO()) as stderr:
        ...     try:
        ...         main()
        ...     except SystemExit as stop:
        ...         print(stop.code, stderr.getvalue().strip())
        2 error: workers=-1: expected an integer >= 1
    """

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except Exception as err:
            message = user_message(err)
            if message is None or debug_requested():
                raise
            sys.stderr.flush()
            print(f"error: {message}", file=sys.stderr)
            sys.exit(EXIT_USER_ERROR)

    return wrapper  # type: ignore[return-value]
