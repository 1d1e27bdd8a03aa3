"""Resuming a run with the configuration it was started with, and the differences a resume may make.

Resuming a run directory (``ckpt_path=last hydra.run.dir=<run> [key=value ...]``) starts from its ``config.yaml``
and applies only the keys given (:func:`resume_config`); a change of what the checkpoint means
(:data:`RESUME_UNSAFE`) is refused, a harmless one (:data:`RESUME_HARMLESS`) recorded, any other needs
``resume_overrides_ok=true`` (:func:`check_resume`).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf, open_dict
from omegaconf.errors import InterpolationResolutionError

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.runs.files import numbered_sibling

log = logging.getLogger(__name__)

#: Keys a resume may set without counting as a configuration change.
RESUME_KEYS = frozenset({"ckpt_path", "resume_overrides_ok", "retest"})

#: What a checkpoint means: a resume may not change these keys, nor any key under them, even with
#: ``resume_overrides_ok=true`` (the one list of them; :func:`resume_change`). The dataset and how it is served
#: (``data``: preset, root, source, lens and image size, occlusion, augmentation, batch size), the model, the task
#: (its loss, metrics, optimiser) and the experiment recipe.
RESUME_UNSAFE = ("data", "model", "task", "experiment")

#: Config groups whose options sit elsewhere than under the group's name (their ``# @package`` line): a group
#: override (``loss=silog``) sets that node (:func:`resume_config`), so a resume judges it as the node's change.
GROUP_PACKAGES = {"loss": "task.module.loss"}

#: Changes a resume makes without asking: how long to train, what is logged and printed, how data is loaded.
#: An entry under a :data:`RESUME_UNSAFE` one (``data.num_workers``) is the more specific and wins.
RESUME_HARMLESS = (
    "trainer.max_epochs",
    "trainer.max_steps",
    "trainer.max_time",
    "trainer.log_every_n_steps",
    "trainer.enable_progress_bar",
    "trainer.enable_model_summary",
    "logger",
    "callbacks.progress",
    "callbacks.rich_progress_bar",
    "callbacks.lr_monitor",
    "callbacks.last_checkpoint.every_n_train_steps",
    "data.num_workers",
    "data.pin_memory",
    "data.persistent_workers",
    "data.remap_on",
    "data.eval_batch_size",
    "data.cache_dir",
    "paths.data_dir",
    "paths.log_dir",
    "print_breakdown",
    "test",
)


def flatten(config: Any, prefix: str = "") -> dict[str, Any]:
    """Dotted keys of a nested dict/list config and their leaf values.

    Example:
        >>> flatten({"a": {"b": 1, "c": [2, {"d": 3}]}, "e": {}})
        {'a.b': 1, 'a.c.0': 2, 'a.c.1.d': 3, 'e': {}}
    """
    items = (
        config.items()
        if isinstance(config, dict)
        else enumerate(config)
        if isinstance(config, list)
        else None
    )
    if items is None or not config:
        return {prefix: config}
    flat: dict[str, Any] = {}
    for key, value in items:
        flat.update(flatten(value, f"{prefix}.{key}" if prefix else str(key)))
    return flat


def config_differences(saved: DictConfig | dict, current: DictConfig | dict) -> list[str]:
    """``key: run has X, now Y`` for every key (resume keys aside) whose resolved value differs.

    Example:
        >>> config_differences({"a": 1, "b": {"c": 2}, "ckpt_path": None}, {"a": 1, "b": {"c": 3}, "ckpt_path": "last"})
        ['b.c: run has 2, now 3']
    """
    return [f"{key}: run has {old}, now {new}" for key, old, new in _changes(saved, current)]


def _changes(saved: DictConfig | dict, current: DictConfig | dict) -> list[tuple[str, Any, Any]]:
    """``(key, run's value, new value)`` for every leaf (resume keys aside) whose resolved value differs."""
    old, new = (flatten(_plain(c)) for c in (saved, current))
    missing = "<absent>"
    return [
        (key, old.get(key, missing), new.get(key, missing))
        for key in sorted(old.keys() | new.keys())
        if key.split(".")[0] not in RESUME_KEYS and old.get(key, missing) != new.get(key, missing)
    ]


def resume_change(key: str) -> str:
    """How a resume may change ``key``: ``"unsafe"`` (refused), ``"harmless"`` (allowed) or ``"changed"``.

    The most specific entry of :data:`RESUME_UNSAFE` and :data:`RESUME_HARMLESS` that ``key`` is (or lies under)
    decides; a key in neither is ``"changed"``: allowed with ``resume_overrides_ok=true``.

    Example:
        >>> resume_change("data.camera.model"), resume_change("data.num_workers"), resume_change("trainer.max_epochs")
        ('unsafe', 'harmless', 'harmless')
        >>> resume_change("trainer.limit_train_batches")
        'changed'
    """
    parts = key.split(".")
    best, kind = -1, "changed"
    for entries, name in ((RESUME_UNSAFE, "unsafe"), (RESUME_HARMLESS, "harmless")):
        for entry in entries:
            depth = entry.count(".") + 1
            if parts[:depth] == entry.split(".") and depth > best:
                best, kind = depth, name
    return kind


def resume_config(cfg: DictConfig, task_overrides: Iterable[str]) -> DictConfig:
    """The configuration of a resume: the run's own ``config.yaml`` with the command's overrides applied on top.

    ``task_overrides`` are the command line's overrides (``hydra.*`` ones are not among them). For
    ``python train.py ckpt_path=last hydra.run.dir=<run> trainer.max_epochs=3`` the result is the run's configuration
    with ``trainer.max_epochs`` set to 3 and nothing else changed (the defaults, and the keys the run's own command
    set, stay the run's). Each override takes its value from ``cfg`` (the command's composition): a ``key=value``
    override sets that key, a group (``logger=tensorboard``) replaces the group's node, ``~key`` deletes it. Without
    a resume (no ``ckpt_path``, or no ``config.yaml`` in the run directory) ``cfg`` is returned; whether the changes
    are allowed is :func:`check_resume`'s decision.
    """
    saved = Path(cfg.paths.output_dir) / "config.yaml"
    if cfg.get("ckpt_path") is None or not saved.is_file():
        return cfg
    run_cfg = saved_config(saved, cfg.paths.output_dir)
    typed = [_override_key(o) for o in task_overrides]
    with open_dict(run_cfg):
        for key in RESUME_KEYS:
            run_cfg[key] = cfg.get(key)
        for key, deleted in typed:
            if key.split(".")[0] in RESUME_KEYS:
                continue
            if deleted:
                parent, _, leaf = key.rpartition(".")
                node = OmegaConf.select(run_cfg, parent) if parent else run_cfg
                if isinstance(node, DictConfig) and leaf in node:
                    node.pop(leaf)
                continue
            value = OmegaConf.select(cfg, key, throw_on_missing=False)
            if isinstance(value, (DictConfig, ListConfig)):
                try:
                    value = OmegaConf.to_container(value, resolve=True)
                except InterpolationResolutionError:  # e.g. loss=silog's ${task.module.min_depth}: the run's
                    value = OmegaConf.to_container(value, resolve=False)
            OmegaConf.update(run_cfg, key, value, merge=False, force_add=True)
    return run_cfg


def _override_key(override: str) -> tuple[str, bool]:
    """The dotted key an override sets and whether it deletes it: ``+a.b=1`` -> ``("a.b", False)``.

    A group override (``logger=tensorboard``, ``experiment=paper/seg``) sets the group's node (``logger``,
    ``experiment``), or the node of its package (:data:`GROUP_PACKAGES`: ``loss=silog`` sets ``task.module.loss``);
    a package override (``group@pkg=option``) its package.

    Example:
        >>> _override_key("++trainer.max_epochs=3"), _override_key("~logger.csv"), _override_key("model@x=y")
        (('trainer.max_epochs', False), ('logger.csv', True), ('x', False))
        >>> _override_key("loss=silog")
        ('task.module.loss', False)
    """
    key = override.split("=", 1)[0]
    deleted = key.startswith("~")
    key = key.lstrip("+~")
    if "@" in key:
        return key.split("@", 1)[1].replace("/", "."), deleted
    return GROUP_PACKAGES.get(key, key.replace("/", ".")), deleted


def saved_config(path: Path, output_dir: str | Path) -> DictConfig:
    """A run's ``config.yaml``, its paths under the run directory moved to ``output_dir``.

    ``config.yaml`` is saved resolved, so it names the directory the run was started in (``paths.output_dir``,
    the checkpoint folder, the logger's folder); a run directory that was moved or copied since is resumed where
    it is now.

    Example:
        >>> import tempfile
        >>> old = Path(tempfile.mkdtemp())
        >>> _ = (old / "config.yaml").write_text(f"paths: {{output_dir: {old}}}\\nckpt: {old}/checkpoints\\nseed: 1\\n")
        >>> moved = saved_config(old / "config.yaml", "/data/runs/moved")
        >>> moved.paths.output_dir, moved.ckpt, moved.seed
        ('/data/runs/moved', '/data/runs/moved/checkpoints', 1)
    """
    config = OmegaConf.load(path)
    assert isinstance(config, DictConfig)
    old, new = str(config.get("paths", {}).get("output_dir", "")), str(output_dir)
    if not old or old == new:
        return config

    def move(value: Any) -> Any:
        if isinstance(value, str) and (value == old or value.startswith(old + os.sep)):
            return new + value[len(old) :]
        if isinstance(value, dict):
            return {k: move(v) for k, v in value.items()}
        if isinstance(value, list):
            return [move(v) for v in value]
        return value

    return OmegaConf.create(move(OmegaConf.to_container(config)))


def check_resume(cfg: DictConfig, output_dir: Path, write: bool) -> None:
    """Refuse a resume that changes what the checkpoint means, or record the accepted changes.

    Each key that differs from the run's ``config.yaml`` is judged by :func:`resume_change`: a change of a
    :data:`RESUME_UNSAFE` key (the dataset, model, task, lens, image size) is refused whatever the switches; a
    :data:`RESUME_HARMLESS` one (more epochs, logging, loader workers) is accepted; any other needs
    ``resume_overrides_ok=true``. Accepted changes are logged, the previous ``config.yaml`` is kept as
    ``config.<n>.yaml`` and the new one becomes ``config.yaml`` (``write`` is false on all but the first process,
    and in the checks made before anything is written).

    Raises:
        ConfigError: one line naming the refused keys, their values and what to do instead.
    """
    saved = output_dir / "config.yaml"
    if not saved.is_file():
        if write:
            atomic_write_text(saved, OmegaConf.to_yaml(cfg, resolve=True))
        return
    changes = _changes(saved_config(saved, output_dir), cfg)
    if not changes:
        return
    described = {key: f"{key} (run has {old}, now {new})" for key, old, new in changes}
    unsafe = [described[key] for key, _, _ in changes if resume_change(key) == "unsafe"]
    if unsafe:
        raise ConfigError(
            f"resuming {output_dir} cannot change {'; '.join(unsafe)}: the checkpoint was trained with the run's "
            "value; start a new run for it (leave out ckpt_path and hydra.run.dir)"
        )
    unsure = [described[key] for key, _, _ in changes if resume_change(key) == "changed"]
    if unsure and not cfg.get("resume_overrides_ok"):
        raise ConfigError(
            f"resuming {output_dir} changes {'; '.join(unsure)}; add resume_overrides_ok=true to continue with "
            "this change, or leave it out to continue as configured"
        )
    if write:
        level = logging.WARNING if unsure else logging.INFO
        log.log(level, "resuming with a changed configuration: %s", "; ".join(described.values()))
        atomic_write_text(
            numbered_sibling(saved), saved.read_text()
        )  # copy first: a kill leaves config.yaml in place
        atomic_write_text(saved, OmegaConf.to_yaml(cfg, resolve=True))


def _plain(config: DictConfig | dict) -> Any:
    return OmegaConf.to_container(config, resolve=True) if isinstance(config, DictConfig) else config
