"""Run ``train.py`` and ``kill -9`` it from inside at a chosen hook and step (no cleanup, no flush runs).

``python -m tests.helpers.killer HOOK STEP train.py-overrides...``: the kill callback is added to the Trainer
outside the configuration, so a resume of the run (which must match its configuration) does not inherit it.
"""

from __future__ import annotations

import os
import runpy
import signal
import sys
from pathlib import Path
from typing import Any

import lightning as L

#: Hooks a kill can hit: during a step, between steps, in validation, at an epoch's end and start.
HOOKS = (
    "on_train_batch_start",
    "on_before_optimizer_step",
    "on_train_batch_end",
    "on_validation_batch_end",
    "on_train_epoch_end",
    "on_train_epoch_start",
)


class KillAt(L.Callback):
    """SIGKILL the process at the first ``hook`` call once ``trainer.global_step >= step``."""

    def __init__(self, hook: str, step: int) -> None:
        if hook not in HOOKS:
            raise ValueError(f"hook must be one of {HOOKS}, got {hook!r}")
        self.step = step
        setattr(self, hook, self._maybe_kill)

    def _maybe_kill(self, trainer: L.Trainer, *args: Any) -> None:
        if trainer.global_step >= self.step and not trainer.sanity_checking:
            os.kill(os.getpid(), signal.SIGKILL)


def main(argv: list[str]) -> None:
    hook, step, overrides = argv[0], int(argv[1]), argv[2:]
    init = L.Trainer.__init__

    def init_with_killer(self: L.Trainer, *args: Any, callbacks: list | None = None, **kwargs: Any) -> None:
        init(self, *args, callbacks=[*(callbacks or []), KillAt(hook, step)], **kwargs)

    L.Trainer.__init__ = init_with_killer
    script = Path(__file__).resolve().parents[2] / "train.py"
    sys.argv = [str(script), *overrides]
    runpy.run_path(str(script), run_name="__main__")


if __name__ == "__main__":
    main(sys.argv[1:])
