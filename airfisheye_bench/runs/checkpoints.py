"""A run's checkpoint and configuration: which checkpoint a run directory or ``.ckpt`` path means
(:func:`resolve_checkpoint`), the run that wrote a checkpoint (:func:`run_directory`, :func:`checkpoint_run_name`)
and its ``config.yaml`` (:func:`run_config`), and reading a checkpoint file safely (:func:`read_checkpoint`).

Evaluation and export accept the run directory or a ``.ckpt`` file; the run's data configuration travels with it.
torch is imported on use only: every entry point imports this package before Hydra composes.
"""

from __future__ import annotations

import json
import pickle
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

from airfisheye_bench.errors import InputFileError, MissingFileError
from airfisheye_bench.runs.names import run_label


def resolve_checkpoint(path: str | Path) -> Path:
    """The checkpoint file for ``path``: the file itself, or a run directory's best (else last) checkpoint.

    The best checkpoint is saved as ``checkpoints/epoch_NNN.ckpt`` (its epoch), beside ``last.ckpt``;
    ``<run>/checkpoints/best`` (or ``best.ckpt``), which is no file, names it too.

    Raises:
        FileNotFoundError: no such file or directory, or a run directory without checkpoints.
    """
    path = Path(path).expanduser()
    if path.is_file():
        return path
    if path.name in ("best", "best.ckpt") and path.parent.name == "checkpoints" and not path.exists():
        path = path.parent.parent  # the run directory: its best checkpoint, below
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


def checkpoint_run_name(checkpoint: str | Path) -> str:
    """The name of the training run a checkpoint belongs to: its run directory's (``<run>/checkpoints/x.ckpt``,
    :func:`run_label`).

    A checkpoint outside a run directory is named by its file.

    Example:
        >>> checkpoint_run_name("logs/depth/runs/adabins-r18/checkpoints/epoch_007.ckpt")
        'adabins-r18'
        >>> checkpoint_run_name("logs/depth/multiruns/sweep-1/2/checkpoints/epoch_000.ckpt")
        'sweep-1/2'
        >>> checkpoint_run_name("/tmp/bare.ckpt")
        'bare'
    """
    path = Path(checkpoint)
    return run_label(path.parent.parent) if path.parent.name == "checkpoints" else path.stem


def run_directory(checkpoint: str | Path) -> Path | None:
    """The run directory that wrote ``checkpoint`` (``<run>/checkpoints/x.ckpt``): the folder of its
    ``config.yaml``, if any."""
    checkpoint = Path(checkpoint)
    for folder in (checkpoint.parent, checkpoint.parent.parent):
        if (folder / "config.yaml").is_file():
            return folder
    return None


def run_config(checkpoint: str | Path) -> DictConfig | None:
    """The resolved ``config.yaml`` of the run that wrote ``checkpoint`` (``<run>/checkpoints/x.ckpt``), if any."""
    folder = run_directory(checkpoint)
    return OmegaConf.load(folder / "config.yaml") if folder is not None else None


def read_checkpoint(path: str | Path, mmap: bool = False) -> dict[str, Any]:
    """The contents of a checkpoint file, read with ``weights_only=True`` (tensors and plain containers only).

    Raises:
        InputFileError: the file is not a readable checkpoint (the message names it).
    """
    import torch  # on use: every entry point imports this module before Hydra composes, and it stays light

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
