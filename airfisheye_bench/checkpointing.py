"""``last.ckpt`` that always holds the run's latest state, written atomically, and a ``metrics.csv`` that survives
a resume.

Lightning's ``ModelCheckpoint(save_last=True)`` rewrites ``last.ckpt`` only when it also saves a top-k checkpoint,
so after an epoch without improvement ``last.ckpt`` is stale. :class:`LastCheckpoint` owns ``last.ckpt`` instead
(``ModelCheckpoint`` keeps the best ones) and saves it

* at the end of every epoch (after its validation), and at the end of training;
* every ``every_n_train_steps`` optimizer steps when set (not on an epoch's last batch: the epoch-end one follows).

A best checkpoint that ``ModelCheckpoint`` wrote at the same step becomes a hard link to the new ``last.ckpt``
(:func:`share_file`): the same state is stored once (a one-epoch run kept two 99 MB copies of it).

The state is taken at Lightning's own restore points (``on_train_batch_end``, ``on_train_epoch_end``) but written
at the next hook, once the metrics of that step or epoch have been handed to the loggers: the checkpoint records
how many ``metrics.csv`` rows it covers, so a resumed run cuts the file back to them and appends, and the file ends
equal to an uninterrupted run's. A kill between the two leaves the previous ``last.ckpt``; the write itself goes
through :class:`AtomicCheckpointIO` (temporary file + rename), so a kill during it does too.
"""

from __future__ import annotations

import csv
import os
import uuid
from pathlib import Path
from typing import Any

import lightning as L
import torch
from lightning.fabric.loggers.logger import rank_zero_experiment
from lightning.pytorch.callbacks import ModelCheckpoint
from lightning.pytorch.loggers import CSVLogger
from lightning.pytorch.loggers.csv_logs import ExperimentWriter
from lightning.pytorch.plugins.io import TorchCheckpointIO

from airfisheye_bench.atomic import atomic_write

#: Checkpoint key: how many ``metrics.csv`` rows had been written when the checkpoint was.
METRIC_ROWS_KEY = "metrics_csv_rows"


class AtomicCheckpointIO(TorchCheckpointIO):
    """Saves checkpoints to a temporary file in the same folder, then renames it over the target.

    A reader, or a run resumed after a kill, sees either the previous file or the new one, never half of one.
    """

    def save_checkpoint(
        self, checkpoint: dict[str, Any], path: str | Path, storage_options: Any | None = None
    ) -> None:
        atomic_write(path, lambda tmp: torch.save(checkpoint, tmp))


class LastCheckpoint(L.Callback):
    """Keep ``<dirpath>/last.ckpt`` the latest state of the run (see the module docstring).

    Args:
        dirpath: Checkpoint folder (the run's ``checkpoints/``).
        every_n_train_steps: Also save every this many optimizer steps (``None`` or 0: epoch ends only).
    """

    def __init__(self, dirpath: str | Path, every_n_train_steps: int | None = None) -> None:
        if every_n_train_steps is not None and every_n_train_steps < 0:
            raise ValueError(f"every_n_train_steps must be >= 0 or null, got {every_n_train_steps}")
        self.path = Path(dirpath) / "last.ckpt"
        self.every_n_train_steps = every_n_train_steps or 0
        self._pending: dict[str, Any] | None = None

    def on_train_batch_end(
        self, trainer: L.Trainer, pl_module: L.LightningModule, outputs: Any, batch: Any, batch_idx: int
    ) -> None:
        n = self.every_n_train_steps
        stepped = (batch_idx + 1) % trainer.accumulate_grad_batches == 0
        last_of_epoch = batch_idx + 1 >= trainer.num_training_batches
        if n and stepped and not last_of_epoch and trainer.global_step % n == 0 and not trainer.fast_dev_run:
            self._pending = self._state(trainer)

    def on_train_batch_start(self, trainer: L.Trainer, *args: Any) -> None:
        self._write_pending(trainer)

    def on_train_epoch_end(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        if not trainer.fast_dev_run:
            self._pending = self._state(trainer)

    def on_train_epoch_start(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        # Runs before other callbacks' epoch-start logging (LearningRateMonitor): this callback is listed first.
        self._write_pending(trainer)

    def on_train_end(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        self._write_pending(trainer)

    @staticmethod
    def _state(trainer: L.Trainer) -> dict[str, Any]:
        # The checkpoint dict Trainer.save_checkpoint would write now. Its tensors are the live ones, unchanged
        # until the next optimizer step, which comes after the write; callback states are taken at the write.
        return trainer._checkpoint_connector.dump_checkpoint(weights_only=False)

    def _write_pending(self, trainer: L.Trainer) -> None:
        if self._pending is None:
            return
        checkpoint, self._pending = self._pending, None
        # Callbacks that saved files in between (ModelCheckpoint's best one) hold state that refers to them.
        callback_states = {cb.state_key: cb.state_dict() for cb in trainer.callbacks}
        checkpoint["callbacks"] = {key: state for key, state in callback_states.items() if state}
        if trainer.is_global_zero:
            checkpoint[METRIC_ROWS_KEY] = flush_metric_rows(trainer)
        trainer.strategy.save_checkpoint(checkpoint, self.path)
        if trainer.is_global_zero:
            for best in _saved_at_step(trainer, checkpoint.get("global_step")):
                share_file(self.path, best)
        trainer.strategy.barrier("LastCheckpoint")


def _saved_at_step(trainer: L.Trainer, step: int | None) -> list[Path]:
    """The full checkpoints that ``ModelCheckpoint`` callbacks wrote at optimizer step ``step`` and still keep."""
    found = []
    for callback in trainer.checkpoint_callbacks:
        if not isinstance(callback, ModelCheckpoint) or callback.save_weights_only:
            continue
        # Lightning's record of its latest save (no public name): the file and the step it was written at.
        path = getattr(callback, "_last_checkpoint_saved", "")
        if (
            path
            and getattr(callback, "_last_global_step_saved", None) == step
            and path in callback.best_k_models
        ):
            found.append(Path(path))
    return found


def share_file(source: Path, target: Path) -> None:
    """Make ``target`` a hard link to ``source`` (the same bytes, stored once), atomically; left as it is where the
    file system has no hard links or they are on different devices.

    A best checkpoint written at the step of ``last.ckpt`` holds the same weights, optimizer and loop state: a
    short run (``trainer=debug``) would keep two copies of the model. ``last.ckpt`` is only ever replaced by a
    rename (:class:`AtomicCheckpointIO`), never written in place, so the best file keeps its bytes when
    ``last.ckpt`` moves on, and the best one gains ``last.ckpt``'s record of its ``metrics.csv`` rows.
    """
    if not source.is_file() or not target.is_file() or source.resolve() == target.resolve():
        return
    link = target.with_name(f".{target.name}.{uuid.uuid4().hex[:12]}.tmp")  # atomic.TEMP_GLOB, as a write's
    try:
        os.link(source, link)
        os.replace(link, target)
    except OSError:
        link.unlink(missing_ok=True)


def flush_metric_rows(trainer: L.Trainer) -> int | None:
    """Write the CSV logger's pending rows; return how many rows ``metrics.csv`` has (``None``: no CSV logger)."""
    for logger in trainer.loggers:
        if isinstance(logger, CSVLogger):
            logger.save()
            path = Path(logger.experiment.metrics_file_path)
            if not path.is_file():
                return 0
            with path.open(newline="") as f:
                return max(sum(1 for _ in csv.reader(f)) - 1, 0)
    return None


class _AppendingWriter(ExperimentWriter):
    """Lightning's CSV writer, minus deleting an existing ``metrics.csv``: it continues the file instead."""

    def _check_log_dir_exists(self) -> None:
        if self._fs.isfile(self.metrics_file_path):
            with self._fs.open(self.metrics_file_path, "r", newline="") as f:
                self.metrics_keys = sorted(next(csv.reader(f), []))


class RunCSVLogger(CSVLogger):
    """``CSVLogger`` writing ``<save_dir>/metrics.csv`` that appends to the file a resumed run already has.

    ``train`` cuts the file back to the rows the resumed checkpoint covers first; a new run starts a new file.
    """

    @property
    @rank_zero_experiment
    def experiment(self) -> _AppendingWriter:
        if self._experiment is None:
            self._fs.makedirs(self.root_dir, exist_ok=True)
            self._experiment = _AppendingWriter(log_dir=self.log_dir)
        return self._experiment
