"""The checks the commands run before any long work: optional packages (:func:`check_extras`), each value a config
sets (:func:`check_common_values`, against :data:`~airfisheye_bench.config_checks.rules.RULES`) and, for
``train``, the rules across keys (:func:`check_train_config`)."""

from __future__ import annotations

import importlib
import importlib.util
import inspect
from collections.abc import Mapping, Sequence
from typing import Any

from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import InterpolationResolutionError

from airfisheye_bench.config_checks.rules import EXTRAS, RULES
from airfisheye_bench.config_checks.value_rule import ValueRule
from airfisheye_bench.constants import config_dir
from airfisheye_bench.errors import ConfigError

_ABSENT = object()


def check_extras(cfg: DictConfig, extras: Mapping[str, tuple[tuple[str, ...], str]] | None = None) -> None:
    """Raise when a set key of ``extras`` needs a package that is not installed, naming the extra to install.

    A look-up of the package only (nothing is imported), so it answers before the value checks import anything.

    Raises:
        ConfigError: ``<key> needs the Python package <module>: pip install -e ".[<extra>]"``.

    Example:
        >>> check_extras(OmegaConf.create({"logger": {"x": {}}}), {"logger.x": (("no_such_module_0",), "x")})
        Traceback (most recent call last):
        ...
        airfisheye_bench.errors.ConfigError: logger.x needs the Python package no_such_module_0, which is not installed: pip install -e ".[x]" (or pip install "airfisheye-bench[x]")
        >>> check_extras(OmegaConf.create({"logger": {"x": None}}), {"logger.x": (("no_such_module_0",), "x")})
    """
    for key, (modules, extra) in (EXTRAS if extras is None else extras).items():
        if OmegaConf.select(cfg, key, default=None, throw_on_missing=False) is None:
            continue
        if not any(importlib.util.find_spec(module) is not None for module in modules):
            raise ConfigError(
                f"{key} needs the Python package {modules[0]}, which is not installed: "
                f'pip install -e ".[{extra}]" (or pip install "airfisheye-bench[{extra}]")'
            )


def check_common_values(
    cfg: DictConfig, rules: Mapping[str, ValueRule] | None = None, skip: Sequence[str] = ()
) -> None:
    """Raise for the first key of ``rules`` whose value has the wrong type or range, or names a missing file.

    Args:
        cfg: A composed config (``train.yaml``, ``evaluate.yaml``, or ``{"data": <a run's data group>}``).
        rules: The keys to check; :data:`RULES` by default.
        skip: Groups whose keys are checked elsewhere, once (``evaluate`` checks ``data`` when it knows which data
            config it serves).

    Raises:
        ConfigError: ``<key>=<value>: expected ...`` (a ``ValueError``).
        MissingFileError: ``<key>=<value>: no such file`` or folder (a ``FileNotFoundError``).

    Example:
        >>> cfg = OmegaConf.create({"trainer": {"max_epochs": "abc"}, "data": {"camera": {"size": 64}}})
        >>> check_common_values(cfg)
        Traceback (most recent call last):
        ...
        airfisheye_bench.errors.ConfigError: trainer.max_epochs='abc': expected an integer >= -1 (-1: no limit)
        >>> check_common_values(OmegaConf.create({"data": {"camera": {"size": 64, "model": "equisolid"}}}))
        >>> check_common_values(OmegaConf.create({"data": {"occlusion": "zbufer"}}))
        Traceback (most recent call last):
        ...
        airfisheye_bench.errors.ConfigError: data.occlusion='zbufer': expected one of ordering, zbuffer, hpr, none, oracle (the LiDAR occlusion correction)
    """
    if rules is None:
        check_extras(cfg)
    for key, rule in (RULES if rules is None else rules).items():
        if any(key.startswith(f"{group}.") for group in skip):
            continue
        try:
            value = OmegaConf.select(cfg, key, default=_ABSENT, throw_on_missing=False)
        except InterpolationResolutionError:  # e.g. data.task=${task.name} before evaluate knows the task
            continue
        if value is _ABSENT or (rule.when is not None and not rule.when(cfg)):
            continue
        value = _plain(value)
        rule.enforce(key, value, *(_plain(_select(cfg, other)) for other in rule.uses))


def _select(cfg: DictConfig, key: str) -> Any:
    try:
        return OmegaConf.select(cfg, key, default=None, throw_on_missing=False)
    except InterpolationResolutionError:
        return None


def _plain(value: Any) -> Any:
    """A list or mapping (``trainer.devices=[0,1]``, ``data.occlusion_options``) as plain data."""
    if isinstance(value, (str, int, float, bool, type(None))):
        return value
    return OmegaConf.to_container(value)


def check_loss_arguments(loss: Mapping[str, Any]) -> None:
    """Refuse a ``task.module.loss`` whose ``_target_`` names no class, or that sets an argument the class does not
    take (the settings of another loss, e.g. ``experiment=paper/depth``'s ``w_chamfer`` with ``loss=silog``).

    Raises:
        ConfigError: the key, and what the class takes.

    Example:
        >>> check_loss_arguments({"_target_": "models.losses.SILogLoss", "_partial_": True, "w_chamfer": 0.1})
        Traceback (most recent call last):
        ...
        airfisheye_bench.errors.ConfigError: task.module.loss.w_chamfer: models.losses.SILogLoss takes no argument 'w_chamfer'; it takes lambd, scale, min_depth, max_depth (loss=<option> picks a loss with its own settings: configs/loss/)
    """
    target = str(loss["_target_"])
    module, _, name = target.rpartition(".")
    try:  # the class named by the config, as Hydra will locate it (the model zoo is imported by now)
        built = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError, ValueError):
        raise ConfigError(
            f"task.module.loss._target_={target}: no such class (a loss of models/losses, e.g. "
            "models.losses.SILogLoss, or a model's own)"
        ) from None
    taken = inspect.signature(built).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in taken.values()):
        return
    for key in loss:
        if not str(key).startswith("_") and key not in taken:
            raise ConfigError(
                f"task.module.loss.{key}: {target} takes no argument {key!r}; it takes {', '.join(taken)} "
                "(loss=<option> picks a loss with its own settings: configs/loss/)"
            )


def check_train_config(cfg: DictConfig) -> None:
    """Everything a ``train.yaml`` config must satisfy, before any work: :func:`check_common_values` (optional
    packages, types, ranges, choices, files), then the rules across keys, each saying what to write instead.

    Raises:
        ConfigError: the key, the value given and what to write instead (a ``ValueError``).
    """
    check_common_values(cfg)  # task.name and model.name among the choices: registered names from here on
    from airfisheye_bench.specs import get_task  # imports torchmetrics: once the values passed
    from models import list_models, model_task  # imports the model zoo: once the values passed

    task = cfg.task.name
    monitored = get_task(task).column(cfg.task.get("primary_metric"))
    if monitored is not None and cfg.task.get("mode") != ("max" if monitored.higher_is_better else "min"):
        raise ConfigError(
            f"task.mode={cfg.task.get('mode')} but a higher {monitored.key} is "
            f"{'better' if monitored.higher_is_better else 'worse'}; write task.mode="
            f"{'max' if monitored.higher_is_better else 'min'}"
        )
    name = cfg.model.name
    if model_task(name) != task:
        folder = config_dir() / "model"
        configs = [p.stem for p in sorted(folder.glob("*.yaml"))]
        fitting = [
            n for n in configs if OmegaConf.load(folder / f"{n}.yaml").get("name") in list_models(task)
        ]
        raise ConfigError(
            f"model={name} solves task={model_task(name)}, not task={task}; use one of "
            f"{', '.join('model=' + m for m in fitting)} or task={model_task(name)}"
        )
    wanted, served = cfg.model.get("camera_input", "none"), cfg.data.get("camera_input", "none")
    if wanted != served:
        raise ConfigError(
            f"model.camera_input={wanted} but data.camera_input={served}: the data must serve what the model takes; "
            "drop data.camera_input (it follows model.camera_input)"
        )
    loss = OmegaConf.select(cfg, "task.module.loss", default=None)
    if loss is not None:
        check_loss_arguments(OmegaConf.to_container(loss))
    model_checkpoint = (cfg.get("callbacks") or {}).get("model_checkpoint") or {}
    if model_checkpoint.get("save_last"):
        raise ConfigError(
            "callbacks.model_checkpoint.save_last=true is unsupported: last.ckpt belongs to callbacks.last_checkpoint, "
            "which rewrites it at every epoch end (ModelCheckpoint's would be another state)"
        )
    if model_checkpoint.get("every_n_train_steps"):
        raise ConfigError(
            "callbacks.model_checkpoint.every_n_train_steps is unsupported (that callback keeps the best checkpoints "
            "by a validation metric); use callbacks.last_checkpoint.every_n_train_steps to save last.ckpt every N steps"
        )
    optimized = cfg.get("optimized_metric")
    if optimized is not None and optimized != model_checkpoint.get("monitor"):
        raise ConfigError(
            f"optimized_metric={optimized}: a sweep optimises the best value of the monitored validation metric; "
            f"write optimized_metric=val/{cfg.task.get('primary_metric')} (callbacks.model_checkpoint.monitor), "
            "or null for the test primary metric"
        )
    # data.sources: each source has its own location (checked by the training command, datamodules.sources).
    if not cfg.data.get("sources") and cfg.data.get("root") is None and cfg.data.get("preset") is None:
        raise ConfigError(
            "data.root is unset and data.preset is null: give data.root=/path or data.preset=quickstart"
        )
