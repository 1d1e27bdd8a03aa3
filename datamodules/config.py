"""A run's ``data`` configuration, re-used after training: overrides on top of it, and its datamodule.

Evaluation and export rebuild the datamodule a model was trained with (from the run's ``config.yaml`` or an ONNX
model's metadata) so the model sees the camera it expects, with ``data.*`` changes from the command line on top.

Example:
    >>> from omegaconf import OmegaConf
    >>> data = OmegaConf.create({"task": "seg", "camera": {"size": 512}, "batch_size": 8})
    >>> cfg = apply_data_overrides(data, {"camera.size": 128, "camera.fov_deg": 180.0}, task="seg")
    >>> OmegaConf.to_container(cfg.camera)
    {'size': 128, 'fov_deg': 180.0}
    >>> apply_data_overrides(data, {"batch_sise": 4})
    Traceback (most recent call last):
    ...
    ValueError: unknown override data.batch_sise: the data config has keys ['batch_size', 'camera', 'task']
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import hydra
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException, InstantiationException
from omegaconf import DictConfig, OmegaConf

from airfisheye_bench.errors import ConfigError, UserError


def apply_data_overrides(
    data: DictConfig | Mapping[str, Any], overrides: Mapping[str, Any] | None = None, task: str | None = None
) -> DictConfig:
    """A resolved copy of ``data`` with ``overrides`` applied.

    Args:
        data: A ``data`` config group (interpolations are resolved in the copy).
        overrides: Values by key relative to ``data`` (``{"camera.size": 128}``). A key must exist, or extend an
            existing section (``camera.k``): a typo at the top level is an error rather than ignored.
        task: If given, ``data.task`` must be this task.

    Raises:
        ValueError: An unknown key, or a ``data.task`` that is not ``task``.
    """
    container = OmegaConf.to_container(data, resolve=True) if isinstance(data, DictConfig) else dict(data)
    cfg = OmegaConf.create(container)
    for key, value in (overrides or {}).items():
        parent = key.rpartition(".")[0]
        node = OmegaConf.select(cfg, parent) if parent else cfg
        if not isinstance(node, DictConfig) or (not parent and key not in cfg):
            raise ValueError(f"unknown override data.{key}: the data config has keys {sorted(cfg.keys())}")
        OmegaConf.update(cfg, key, value, merge=False)
    if task is not None and cfg.get("task") != task:
        raise ValueError(f"data.task={cfg.get('task')!r} but the model is a task={task} model")
    return cfg


def parse_data_overrides(dotlist: Sequence[str]) -> dict[str, Any]:
    """``["data.camera.size=128", ...]`` (command-line form) -> ``{"camera.size": 128}``.

    Values are read by Hydra's override parser, so they mean what they mean to ``train.py`` (``null``, lists
    ``[a,b]``, quoted strings); ``export`` gets its ``data.*`` values from the same parser.

    Raises:
        ConfigError: An item that is not ``data.<key>=<value>``, or a sweep (``a,b``).

    Example:
        >>> parse_data_overrides(["data.camera.size=128", "+data.camera.k=[1.0,0.1]", "data.root=null"])
        {'camera.size': 128, 'camera.k': [1.0, 0.1], 'root': None}
    """
    out: dict[str, Any] = {}
    parser = OverridesParser.create()
    for item in dotlist:
        try:
            (override,) = parser.parse_overrides([item])
        except HydraException as err:
            raise ConfigError(f"{item}: not a key=value override ({str(err).splitlines()[0]})") from None
        key = override.key_or_group
        if not key.startswith("data.") or override.is_delete() or override.is_sweep_override():
            raise ConfigError(f"data overrides look like data.<key>=<value> (one value), got {item!r}")
        out[key.removeprefix("data.")] = override.value()
    return out


#: What a run's data config recorded before an option existed was served with, where that differs from the option's
#: declared default (``config_checks/data_options.py``): the sparse input had every return before
#: ``data.lidar.density`` (its default is now the paper's).
RECORDED_BEFORE: dict[str, Any] = {"lidar": {"density": "native"}}


def instantiate_datamodule(data: DictConfig, stage: str | None = None):
    """The datamodule of ``data`` for use in one process (no loader workers), prepared and set up for ``stage``.

    A key that ``data`` (a run's recorded config) lacks takes what runs served before the key existed
    (:data:`RECORDED_BEFORE`), else its declared default.

    Raises:
        UserError: The datamodule's own message for a wrong value or file (e.g. ``data.root`` is not a folder).
        ValueError: The datamodule cannot be built otherwise; the message says how to fix it with overrides.
    """
    cfg = OmegaConf.merge(RECORDED_BEFORE, data, {"num_workers": 0, "persistent_workers": False})
    try:
        datamodule = hydra.utils.instantiate(cfg, _convert_="partial")
        datamodule.prepare_data()
        if stage is not None:
            datamodule.setup(stage)
    except Exception as err:
        cause = (
            err.__cause__ if isinstance(err, InstantiationException) else err
        )  # Hydra wraps __init__'s error
        if isinstance(cause, UserError):
            raise cause from None
        raise ValueError(
            f"cannot build the datamodule from the data config ({type(err).__name__}: {err}); "
            "fix it with data.<key>=<value> overrides, e.g. data.root=/path/to/dataset"
        ) from err
    return datamodule


__all__ = ["apply_data_overrides", "instantiate_datamodule", "parse_data_overrides"]
