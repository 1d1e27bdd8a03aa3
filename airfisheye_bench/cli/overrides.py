"""Unknown keys and options of the Hydra applications, answered in one line with the nearest valid one.

Hydra refuses ``trainer.max_epoch=1`` with a message of its own (exit status 1) that advises
``+trainer.max_epoch=1``, a key nothing reads. :func:`check_overrides` composes the configuration with the
command's overrides before Hydra does (a quarter of a second) and turns an unknown key or group option into a
:class:`~airfisheye_bench.errors.ConfigError`: one line naming it and the closest valid key (:mod:`difflib`); a key
that moved (:data:`MOVED_KEYS`) is answered with where it is now.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Sequence

from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException, MissingConfigException
from omegaconf import DictConfig, OmegaConf

from airfisheye_bench.constants import config_dir
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.runs import flatten

#: Keys that moved, and where they are now. The settings of a task's loss moved into the loss's own config
#: (``task.module.loss``, which chooses the loss class) when losses came to be chosen by config.
MOVED_KEYS = {
    "task.module.w_chamfer": "task.module.loss.w_chamfer",
    "task.module.chamfer_reference_range": "task.module.loss.chamfer_reference_range",
    "task.module.l1_weight": "task.module.loss.l1_weight",
    "task.module.l2_weight": "task.module.loss.l2_weight",
}


def check_moved_keys(overrides: Iterable[str]) -> None:
    """Raise for an override of a key of :data:`MOVED_KEYS` (with ``+``, ``++`` or ``~`` too), naming the new key.

    Raises:
        ConfigError: ``<old key>=<value>: moved; write <new key>=<value>``.

    Example:
        >>> check_moved_keys(["task=depth", "task.module.w_chamfer=0.1"])
        Traceback (most recent call last):
        ...
        airfisheye_bench.errors.ConfigError: task.module.w_chamfer=0.1: the loss's settings moved under task.module.loss; write task.module.loss.w_chamfer=0.1
    """
    for override in overrides:
        name, _, value = override.lstrip("+~").partition("=")
        if name in MOVED_KEYS:
            raise ConfigError(
                f"{name}={value}: the loss's settings moved under task.module.loss; "
                f"write {MOVED_KEYS[name]}={value}"
            )


def check_overrides(config_name: str, argv: Sequence[str]) -> None:
    """Raise for an override of ``argv`` that names no key of ``configs/<config_name>.yaml`` or no group option.

    Arguments Hydra reads itself (``--help``, ``--cfg job``, ``-m``) skip the check; any other composition
    problem is left to Hydra.

    Raises:
        ConfigError: ``<key>=<value>: unknown key; did you mean <nearest>=<value>?`` (or the keys to choose from),
            ``<group>=<option>: no such option; choose one of ...``, or a moved key (:func:`check_moved_keys`).
    """
    if any(arg.startswith("-") for arg in argv):
        return
    overrides = [arg for arg in argv if "=" in arg]
    check_moved_keys(overrides)
    try:
        _compose(config_name, overrides)
    except MissingConfigException as err:
        group, option = _group_option(err, overrides)
        if group is None:
            return
        options = list(err.options or [])
        nearest = difflib.get_close_matches(option, options, n=1)
        hint = f" (did you mean {group}={nearest[0]}?)" if nearest else ""
        raise ConfigError(
            f"{group}={option}: no such option of {group}; choose one of {', '.join(options)}{hint}"
        ) from None
    except ConfigCompositionException as err:
        key = str(getattr(err.__cause__, "full_key", "") or "")
        given = next((o for o in overrides if _is_under(o.partition("=")[0].lstrip("+~"), key)), None)
        if not key or given is None:
            return
        rest = [o for o in overrides if o is not given]
        name, _, value = given.lstrip("+~").partition("=")
        raise ConfigError(_unknown_key_message(name, value, _known_keys(config_name, rest))) from None


def _is_under(name: str, key: str) -> bool:
    return name == key or name.startswith(key + ".")


def _compose(config_name: str, overrides: list[str]) -> DictConfig:
    with initialize_config_dir(config_dir=str(config_dir()), version_base="1.3"):
        return compose(config_name=config_name, overrides=overrides)


def _known_keys(config_name: str, overrides: list[str]) -> list[str]:
    """Every dotted key (nodes and leaves) of the composition with the other overrides (or without any)."""
    try:
        cfg = _compose(config_name, overrides)
    except Exception:  # another override is broken too: the defaults still name the keys
        cfg = _compose(config_name, [])
    leaves = flatten(OmegaConf.to_container(cfg, resolve=False))
    keys = set(leaves)
    for key in leaves:
        parts = key.split(".")
        keys.update(".".join(parts[:i]) for i in range(1, len(parts)))
    return sorted(keys)


def _unknown_key_message(key: str, value: str, known: Iterable[str]) -> str:
    """``key=value: unknown key; did you mean ...?``, the nearest key among its siblings first.

    Example:
        >>> _unknown_key_message("trainer.max_epoch", "1", ["trainer", "trainer.max_epochs", "trainer.devices"])
        'trainer.max_epoch=1: unknown key; did you mean trainer.max_epochs=1?'
        >>> _unknown_key_message("trainer.zzz", "1", ["trainer", "trainer.max_epochs", "trainer.devices"])
        'trainer.zzz=1: unknown key; the keys of trainer: devices, max_epochs'
        >>> _unknown_key_message("data.camra.size", "64", ["data", "data.camera", "data.camera.size"])
        'data.camra.size=64: unknown key; did you mean data.camera.size=64?'
    """
    known = list(known)
    parent, _, leaf = key.rpartition(".")
    siblings = [k.rpartition(".")[2] for k in known if k.rpartition(".")[0] == parent]
    nearest = [f"{parent}.{k}" if parent else k for k in difflib.get_close_matches(leaf, siblings, n=1)]
    nearest = nearest or difflib.get_close_matches(key, known, n=1, cutoff=0.8)
    if nearest:
        return f"{key}={value}: unknown key; did you mean {nearest[0]}={value}?"
    if siblings:
        return f"{key}={value}: unknown key; the keys of {parent or 'the configuration'}: {', '.join(sorted(siblings))}"
    return f"{key}={value}: unknown key (see --help for the keys)"


def _group_option(err: MissingConfigException, overrides: list[str]) -> tuple[str | None, str]:
    """The ``group=option`` override that named a missing config file, if one did."""
    missing = str(getattr(err, "missing_cfg_file", "") or "")
    for override in overrides:
        group, _, option = override.lstrip("+~").partition("=")
        if missing == f"{group}/{option}" or missing.endswith(f"/{group}/{option}"):
            return group, option
    return None, ""
