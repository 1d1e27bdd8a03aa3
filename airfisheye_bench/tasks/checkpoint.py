"""Find and load a trained task from a run directory or a Lightning checkpoint.

A run directory (``logs/<task>/runs/<time>_<suffix>``) holds ``config.yaml`` (resolved), ``checkpoints/`` and, after
testing, ``results.json`` naming the best checkpoint. Evaluation and export accept either the directory or a
``.ckpt`` file; the run's data configuration (lens, size, occlusion method, dataset) travels with it so the model
is evaluated on the camera it was trained for.
"""

from __future__ import annotations

import json
import pickle
from pathlib import Path
from typing import Any

import torch
from omegaconf import DictConfig, OmegaConf

from airfisheye_bench.errors import InputFileError, MissingFileError
from airfisheye_bench.tasks.base import BenchmarkTask
from models import list_models, model_task
from models.weights import pretrained_weights_disabled

__all__ = ["load_task", "read_checkpoint", "resolve_checkpoint", "run_config"]

#: Model defaults that changed when checkpoints started to record their initial weights (the ``weights``
#: hyperparameter): NLSPN then moved to upstream's confidence sampling. An older checkpoint that did not name the
#: option was trained with the old default, and must be rebuilt with it.
_DEFAULTS_BEFORE_WEIGHTS: dict[str, dict[str, Any]] = {
    "nlspn": {"preserve_input": True, "confidence_sampling": "neighbour"},
}


def resolve_checkpoint(path: str | Path) -> Path:
    """The checkpoint file for ``path``: the file itself, or a run directory's best (else last) checkpoint.

    Raises:
        FileNotFoundError: no such file or directory, or a run directory without checkpoints.
    """
    path = Path(path).expanduser()
    if path.is_file():
        return path
    if not path.is_dir():
        raise MissingFileError(f"checkpoint {path} does not exist (give a .ckpt file or a run directory)")
    results = path / "results.json"
    if results.is_file():
        try:
            best = json.loads(results.read_text()).get("model", {}).get("checkpoint")
        except (OSError, json.JSONDecodeError, AttributeError):
            best = None
        if best and Path(best).is_file():
            return Path(best)
    folder = path / "checkpoints"
    candidates = sorted(p for p in folder.glob("*.ckpt") if p.name != "last.ckpt")
    if (folder / "last.ckpt").is_file() and not candidates:
        return folder / "last.ckpt"
    if len(candidates) == 1:
        return candidates[0]
    if candidates:
        # Several monitored checkpoints and no results.json to say which is best: the newest is the safe guess.
        return max(candidates, key=lambda p: p.stat().st_mtime)
    raise MissingFileError(f"run directory {path} has no checkpoints/*.ckpt")


def run_config(checkpoint: str | Path) -> DictConfig | None:
    """The resolved ``config.yaml`` of the run that wrote ``checkpoint`` (``<run>/checkpoints/x.ckpt``), if any."""
    checkpoint = Path(checkpoint)
    for folder in (checkpoint.parent, checkpoint.parent.parent):
        candidate = folder / "config.yaml"
        if candidate.is_file():
            return OmegaConf.load(candidate)
    return None


def read_checkpoint(path: str | Path, mmap: bool = False) -> dict[str, Any]:
    """The contents of a checkpoint file, read with ``weights_only=True`` (tensors and plain containers only).

    Raises:
        InputFileError: the file is not a readable checkpoint (the message names it).
    """
    try:
        state = torch.load(path, map_location="cpu", weights_only=True, mmap=mmap)
    except pickle.UnpicklingError as err:
        # PyTorch's message advises weights_only=False, which would run any code the file holds: not repeated here.
        raise InputFileError(
            f"{path}: not a readable checkpoint (it holds something other than tensors and plain containers: "
            "corrupt, or not written by train.py); give a .ckpt file of a run"
        ) from err
    except (RuntimeError, EOFError, OSError, ValueError) as err:
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise InputFileError(
            f"{path}: not a readable checkpoint ({reason}); give a .ckpt file of a run"
        ) from err
    if not isinstance(state, dict):
        raise InputFileError(f"{path}: not a checkpoint (it holds a {type(state).__name__}, not a dict)")
    return state


def load_task(path: str | Path, map_location: str | torch.device = "cpu") -> BenchmarkTask:
    """Rebuild the task module of a checkpoint (or run directory) with its weights, in eval mode.

    The checkpoint is read with ``weights_only=True``: nothing is unpickled beyond tensors and plain
    containers. The task class follows from the registered model name stored in its hyperparameters.

    Args:
        path: A ``.ckpt`` file or a run directory (see :func:`resolve_checkpoint`).
        map_location: Device for the weights.

    Raises:
        FileNotFoundError: see :func:`resolve_checkpoint`.
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
    from airfisheye_bench.tasks import TASKS

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
    if "weights" not in hparams:  # written before models recorded their weights: the defaults of that time
        hparams = {**hparams, "model": {**_DEFAULTS_BEFORE_WEIGHTS.get(name, {}), **hparams["model"]}}
    with pretrained_weights_disabled():  # the state dict restores every weight: fetch and read nothing else
        module = task_cls(**hparams)
    module.load_state_dict(state["state_dict"])
    return module.to(map_location).eval()
