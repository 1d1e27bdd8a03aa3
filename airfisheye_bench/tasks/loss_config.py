"""The training loss of a task as configuration: the plain config a checkpoint records, and the module built from it.

A task's loss is chosen by config (``task.module.loss``: ``{"_target_": "models.losses.X", **settings}``, or the
partial Hydra makes of it); :class:`~airfisheye_bench.tasks.base.BenchmarkTask` records :func:`loss_config` in its
hyperparameters, so that a checkpoint alone rebuilds the loss (:func:`build_loss`).
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Mapping
from typing import Any

import hydra
from omegaconf import DictConfig, OmegaConf
from torch import nn

__all__ = ["LossArg", "build_loss", "loss_config"]

#: What a task's ``loss`` argument may be: a config (``{"_target_": "models.losses.X", **settings}``), the partial
#: Hydra makes of one with ``_partial_: true``, a built loss module, or None (the task's default).
LossArg = Mapping[str, Any] | functools.partial | nn.Module | None

_PLAIN = (str, int, float, bool, type(None))


def loss_config(loss: Mapping[str, Any] | functools.partial) -> dict[str, Any]:
    """The plain config (``{"_target_": ..., **settings}``) of a loss given as a config or a Hydra partial: what a
    checkpoint records, so that it alone rebuilds the loss (it is read back with ``weights_only=True``).

    Raises:
        ValueError: no ``_target_``, positional arguments, or a setting that is not plain data.

    Example:
        >>> from models.losses import SILogLoss
        >>> loss_config(functools.partial(SILogLoss, lambd=1.0))
        {'_target_': 'models.losses.SILogLoss', 'lambd': 1.0}
    """
    if isinstance(loss, functools.partial):
        if loss.args:
            raise ValueError(f"loss: a partial of keyword arguments only, got positional {loss.args}")
        config = {"_target_": _public_name(loss.func), **loss.keywords}
    else:
        plain = OmegaConf.to_container(loss, resolve=True) if isinstance(loss, DictConfig) else dict(loss)
        config = {k: v for k, v in plain.items() if k != "_partial_"}
    if not isinstance(config.get("_target_"), str):
        raise ValueError(f"loss: a config needs the loss class as '_target_', got {config}")
    for key, value in config.items():
        if not _is_plain(value):
            raise ValueError(
                f"loss.{key}: a {type(value).__name__}; a loss config holds plain values only (numbers, strings, "
                "lists), which the checkpoint records"
            )
    return config


def _public_name(obj: Any) -> str:
    """The dotted name of ``obj`` in the shallowest package of its module that exports it, as configs write it
    (``models.losses.SILogLoss``, not ``models.losses.depth.SILogLoss``)."""
    parts = obj.__module__.split(".")
    for end in range(1, len(parts)):
        package = ".".join(parts[:end])
        if getattr(sys.modules.get(package), obj.__qualname__, None) is obj:
            return f"{package}.{obj.__qualname__}"
    return f"{obj.__module__}.{obj.__qualname__}"


def _is_plain(value: Any) -> bool:
    if isinstance(value, (list, tuple)):
        return all(_is_plain(v) for v in value)
    if isinstance(value, Mapping):
        return all(isinstance(k, str) and _is_plain(v) for k, v in value.items())
    return isinstance(value, _PLAIN)


def build_loss(config: Mapping[str, Any]) -> nn.Module:
    """The loss module of a :func:`loss_config`.

    Raises:
        ValueError: the config builds something other than an ``nn.Module``.
    """
    loss = hydra.utils.instantiate(dict(config), _convert_="partial")
    if not isinstance(loss, nn.Module):
        raise ValueError(f"loss: {config['_target_']} built a {type(loss).__name__}, not a torch.nn.Module")
    return loss
