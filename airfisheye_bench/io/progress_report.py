"""Progress of long work on files (generating, verifying or hashing a dataset, predicting on footage): a bar in a
terminal, log lines otherwise.

A bar redraws one line of a terminal with carriage returns; written to a file (a redirected console, ``nohup``,
SLURM) every redraw stays, and a generation's bar became one line of tens of thousands of characters.
:class:`ProgressReport` draws the bar only when its stream (standard error, as tqdm's) is a terminal, and
otherwise logs a line at every tenth of the work (:func:`progress_line`), through the command's logging.

Example:
    >>> progress_line("epoch 2/8", {"train/loss": 0.51234, "val/loss": 0.6, "val/mIoU": 0.2417}, 12.3)
    'epoch 2/8: train/loss 0.5123, val/loss 0.6000, val/mIoU 0.2417 (12 s)'
"""

from __future__ import annotations

import logging
import math
import sys
import time
from collections.abc import Iterable, Iterator, Mapping
from typing import Any, TypeVar

from tqdm.auto import tqdm

log = logging.getLogger(__name__)

T = TypeVar("T")


def console_is_terminal() -> bool:
    """Whether standard output, where the commands print and log, is an interactive terminal."""
    return sys.stdout.isatty()


def progress_line(where: str, metrics: Mapping[str, Any], seconds: float | None = None) -> str:
    """``<where>: key value, ...`` with 4 significant decimals, then the time taken when given.

    Example:
        >>> progress_line("epoch 1/3 step 50/120", {"train/loss": 2.0})
        'epoch 1/3 step 50/120: train/loss 2.0000'
    """
    parts = [f"{key} {_number(value)}" for key, value in metrics.items()]
    timing = f" ({seconds:.0f} s)" if seconds is not None else ""
    return f"{where}: {', '.join(parts) or 'no metrics yet'}{timing}"


def _number(value: Any) -> str:
    value = float(value)
    if not math.isfinite(value):
        return str(value)
    return f"{value:.4g}" if abs(value) >= 1e4 or (value != 0 and abs(value) < 1e-3) else f"{value:.4f}"


class ProgressReport:
    """``total`` units of work called ``desc``: a tqdm bar where standard error is a terminal, else a log line at
    every tenth (``<desc> <done>/<total> <unit>: <unit>s/s <rate> (<seconds> s)``); nothing when not ``enabled``.

    Args:
        total: Units of work (``None``: unknown, a line every 10 units).
        desc: What is done (``generate tiny``).
        unit: The unit counted (``frame``, ``file``).
        enabled: Report at all.
        initial: Units already done (a resumed generation).
        logger: Where the lines go.

    Example:
        >>> import contextlib, io
        >>> with contextlib.redirect_stderr(io.StringIO()), ProgressReport(20, "verify", "file") as report:
        ...     report.update(20)
        >>> report.done
        20
    """

    def __init__(
        self,
        total: int | None,
        desc: str,
        unit: str,
        enabled: bool = True,
        initial: int = 0,
        logger: logging.Logger = log,
    ) -> None:
        self.total, self.desc, self.unit, self.enabled = total, desc, unit, enabled
        self.done = self._logged = self.initial = initial
        self.logger = logger
        self.started = time.monotonic()
        self.bar = None
        if enabled and sys.stderr.isatty():
            self.bar = tqdm(total=total, initial=initial, desc=desc, unit=unit, dynamic_ncols=True)
        self.step = max(1, -(-(total or 100) // 10))  # a tenth, rounded up

    def update(self, n: int = 1) -> None:
        self.done += n
        if self.bar is not None:
            self.bar.update(n)
        elif self.enabled and (
            self.done // self.step != self._logged // self.step or self.done == self.total
        ):
            self._logged = self.done
            seconds = time.monotonic() - self.started
            rate = {f"{self.unit}s/s": (self.done - self.initial) / max(seconds, 1e-9)}
            self.logger.info(
                progress_line(f"{self.desc} {self.done}/{self.total or '?'} {self.unit}s", rate, seconds)
            )

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()

    def __enter__(self) -> ProgressReport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def track(items: Iterable[T], total: int, desc: str, unit: str, enabled: bool = True) -> Iterator[T]:
    """``items``, reporting each one done (:class:`ProgressReport`)."""
    with ProgressReport(total, desc, unit, enabled) as report:
        for item in items:
            yield item
            report.update()
