"""Progress as log lines: one per epoch (losses and validation metrics) and one every N steps.

A progress bar redraws one line of a terminal; redirected to a file, under ``nohup`` or SLURM it shows nothing
until its task ends (minutes, for an epoch of the quick start). :class:`ProgressLog` writes plain log lines
instead, through the command's logging: to the run's ``train.log`` always, to the console when the console is not
a terminal (in a terminal the progress bar shows the same and a printed line would break its redraw).

Example:
    >>> progress_line("epoch 2/8", {"train/loss": 0.51234, "val/loss": 0.6, "val/mIoU": 0.2417}, 12.3)
    'epoch 2/8: train/loss 0.5123, val/loss 0.6000, val/mIoU 0.2417 (12 s)'
"""

from __future__ import annotations

import logging
import math
import time
from typing import Any

import lightning as L

from airfisheye_bench.io.progress_report import console_is_terminal, progress_line

log = logging.getLogger(__name__)

#: Metrics of an epoch line, by prefix; the per-ring and per-class values stay in ``metrics.csv``.
_EPOCH_PREFIXES = ("train/", "val/")


def log_to_files(text: str, logger: logging.Logger = log) -> None:
    """Hand ``text`` to the file handlers of the root logger only (``train.log``), not to the console."""
    record = logger.makeRecord(logger.name, logging.INFO, __file__, 0, text, None, None)
    for handler in logging.getLogger().handlers:
        if isinstance(handler, logging.FileHandler):
            handler.handle(record)


class ProgressLog(L.Callback):
    """Log one line per epoch (after its validation) and one every ``every_n_steps`` optimizer steps.

    The epoch line holds the epoch's training loss and the validation loss and metrics (``val/<metric>``, not the
    per-ring ones); a step line the latest training loss. Lines go to the console only when it is not a terminal
    (``console``: ``"auto"``), or always (``"always"``), and to the log files (``train.log``) in every case.

    Args:
        every_n_steps: Also log every this many optimizer steps (``None`` or 0: epoch lines only).
        console: ``"auto"`` (not a terminal only) or ``"always"``.
    """

    def __init__(self, every_n_steps: int | None = 50, console: str = "auto") -> None:
        if every_n_steps is not None and every_n_steps < 0:
            raise ValueError(f"every_n_steps must be >= 0 or null, got {every_n_steps}")
        if console not in ("auto", "always"):
            raise ValueError(f"console must be 'auto' or 'always', got {console!r}")
        self.every_n_steps = every_n_steps or 0
        self.console = console
        self._epoch_start = time.monotonic()

    def _emit(self, trainer: L.Trainer, text: str) -> None:
        if not trainer.is_global_zero:
            return
        if self.console == "always" or not console_is_terminal():
            log.info(text)
        else:
            log_to_files(text)

    def _where(self, trainer: L.Trainer) -> str:
        total = trainer.max_epochs if trainer.max_epochs is not None and trainer.max_epochs >= 0 else "?"
        return f"epoch {trainer.current_epoch + 1}/{total}"

    def on_train_epoch_start(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        self._epoch_start = time.monotonic()

    def on_train_batch_end(
        self, trainer: L.Trainer, pl_module: L.LightningModule, outputs: Any, batch: Any, batch_idx: int
    ) -> None:
        n = self.every_n_steps
        stepped = (batch_idx + 1) % trainer.accumulate_grad_batches == 0
        if not n or not stepped or trainer.global_step % n or trainer.sanity_checking:
            return
        batches = trainer.num_training_batches
        where = f"{self._where(trainer)} batch {batch_idx + 1}/{batches if math.isfinite(batches) else '?'}"
        metrics = {k: v for k, v in trainer.callback_metrics.items() if k.startswith("train/")}
        metrics = {k.removesuffix("_step"): v for k, v in metrics.items() if not k.endswith("_epoch")}
        self._emit(trainer, progress_line(f"{where} (step {trainer.global_step})", metrics))

    def on_train_epoch_end(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        # Lightning runs the epoch's validation before this hook, so its metrics are in callback_metrics.
        metrics: dict[str, Any] = {}
        for key, value in sorted(trainer.callback_metrics.items()):
            if not key.startswith(_EPOCH_PREFIXES) or key.endswith("_step"):
                continue
            name = key.removesuffix("_epoch")
            if name.count("/") == 1 and name not in metrics:  # val/ring_0-30/mIoU stays in metrics.csv
                metrics[name] = value
        ordered = dict(sorted(metrics.items(), key=lambda kv: (not kv[0].startswith("train/"), kv[0])))
        self._emit(
            trainer, progress_line(self._where(trainer), ordered, time.monotonic() - self._epoch_start)
        )
