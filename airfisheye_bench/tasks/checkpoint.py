"""Load a trained task from a run directory or a Lightning checkpoint.

Which file of a run directory is its checkpoint, and reading it safely, is :mod:`airfisheye_bench.runs`
(``resolve_checkpoint``, ``read_checkpoint``); this module rebuilds the task module from it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import torch

from airfisheye_bench.errors import InputFileError
from airfisheye_bench.runs import read_checkpoint, resolve_checkpoint
from airfisheye_bench.tasks import TASKS
from airfisheye_bench.tasks.base import BenchmarkTask
from models import list_models, model_task
from models.weights import pretrained_weights_disabled

__all__ = ["load_task"]

#: Model defaults that changed when checkpoints started to record their initial weights (the ``weights``
#: hyperparameter): NLSPN then moved to upstream's confidence sampling. An older checkpoint that did not name the
#: option was trained with the old default, and must be rebuilt with it.
_DEFAULTS_BEFORE_WEIGHTS: dict[str, dict[str, Any]] = {
    "nlspn": {"preserve_input": True, "confidence_sampling": "neighbour"},
}


def load_task(path: str | Path, map_location: str | torch.device = "cpu") -> BenchmarkTask:
    """Rebuild the task module of a checkpoint (or run directory) with its weights, in eval mode.

    The checkpoint is read with ``weights_only=True``: nothing is unpickled beyond tensors and plain
    containers. The task class follows from the registered model name stored in its hyperparameters. A checkpoint
    written before the loss was chosen by config (its loss settings, e.g. ``w_chamfer``, among the task's
    hyperparameters) is rebuilt with the loss they configured (:meth:`BenchmarkTask.upgrade_hparams`).

    Args:
        path: A ``.ckpt`` file or a run directory (see :func:`~airfisheye_bench.runs.resolve_checkpoint`).
        map_location: Device for the weights.

    Raises:
        FileNotFoundError: see :func:`~airfisheye_bench.runs.resolve_checkpoint`.
        ValueError: the file is not a readable Lightning checkpoint of this project.

    Example:
        >>> import tempfile, lightning as L
        >>> from airfisheye_bench.tasks import DepthTask
        >>> task = DepthTask({"name": "adabins", "encoder_name": "resnet18", "n_bins": 16, "decoder_features": 32})
        >>> trainer = L.Trainer(logger=False, enable_progress_bar=False, enable_model_summary=False)
        >>> trainer.strategy.connect(task)
        >>> ckpt = tempfile.mkdtemp() + "/model.ckpt"
        >>> trainer.save_checkpoint(ckpt)
        >>> type(load_task(ckpt)).__name__
        'DepthTask'
    """
    checkpoint = resolve_checkpoint(path)
    state = read_checkpoint(checkpoint)
    hparams: dict[str, Any] = state.get("hyper_parameters", {})
    name = (hparams.get("model") or {}).get("name")
    if "state_dict" not in state or name not in list_models():
        raise InputFileError(
            f"{checkpoint}: not a checkpoint of an airfisheye-bench task "
            f"(expected 'state_dict' and hyper_parameters.model.name among the registered models)"
        )
    task_cls = TASKS[model_task(name)]
    hparams = task_cls.upgrade_hparams(hparams)
    if "weights" not in hparams:  # written before models recorded their weights: the defaults of that time
        hparams = {**hparams, "model": {**_DEFAULTS_BEFORE_WEIGHTS.get(name, {}), **hparams["model"]}}
    with pretrained_weights_disabled():  # the state dict restores every weight: fetch and read nothing else
        module = task_cls(**hparams)
    module.load_state_dict(state["state_dict"])
    return module.to(map_location).eval()
