"""Run directories: unique names, resuming one with the configuration it was started with, and finding its checkpoint.

A run directory (``logs/<task>/runs/<time>_<suffix>``) holds ``config.yaml`` (the resolved configuration),
``checkpoints/`` (``last.ckpt`` and the best ones), ``metrics.csv`` and, after testing, ``results.json`` naming the
best checkpoint. Resuming it (``ckpt_path=last hydra.run.dir=<run> [key=value ...]``) starts from that
configuration and applies only the keys given (:func:`resume_config`); a change of what the checkpoint means
(:data:`RESUME_UNSAFE`) is refused, a harmless one (:data:`RESUME_HARMLESS`) recorded, any other needs
``resume_overrides_ok=true`` (:func:`check_resume`). Evaluation and export
accept the directory or a ``.ckpt`` file (:func:`resolve_checkpoint`); the run's data configuration travels with it
(:func:`run_config`). The command's log file is written only once the run directory is (:func:`run_log`). Kept
light (no torch import at module level): the entry points register
:func:`register_resolvers` before Hydra composes.

What a run writes beside its checkpoints has its own modules here: ``results.json`` (:mod:`.results`, written by
training and evaluation alike) and the deployed ONNX model's metadata (:mod:`.deployment`, written by export, read by
evaluation and prediction).
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import functools
import json
import logging
import logging.handlers
import os
import pickle
import re
import secrets
import socket
import sys
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, ListConfig, OmegaConf, open_dict
from omegaconf.errors import InterpolationResolutionError

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.errors import ConfigError, InputFileError, MissingFileError

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


@functools.cache
def run_name() -> str:
    """The run directory's name, fixed for the process (``hydra.run.dir`` ends in ``${run_name:}``).

    One command: ``<date>_<time>_<pid>-<4 hex digits>``; two commands started in the same second differ by the
    pid (processes alive at the same time) or the random part (hosts sharing a filesystem). Cached, so every
    re-resolution of the run directory agrees. Lightning's own DDP launcher passes the first process's directory
    to the processes it starts; torchrun and ``srun`` start every rank as its own command, so there the name is
    the one every rank of the launch shares (:func:`launch_id`) after the date.

    Example:
        >>> run_name() == run_name() and f"_{os.getpid()}-" in run_name()
        True
    """
    return run_name_for(os.environ, _dt.datetime.now(), os.getpid(), os.getppid())


def run_name_for(environ: Mapping[str, str], now: _dt.datetime, pid: int, parent_pid: int) -> str:
    """:func:`run_name` for the given environment, time and process ids.

    Example:
        >>> t = _dt.datetime(2026, 11, 24, 9, 30, 5)
        >>> run_name_for({}, t, 812, 1)[:-4]
        '2026-11-24_09-30-05_812-'
        >>> run_name_for({"SLURM_JOB_ID": "4471", "SLURM_STEP_ID": "0", "SLURM_NTASKS": "8"}, t, 812, 1)
        '2026-11-24_slurm-4471.0'
        >>> run_name_for({"TORCHELASTIC_RUN_ID": "none", "WORLD_SIZE": "2"}, t, 812, 77)  # doctest: +ELLIPSIS
        '2026-11-24_torchrun-pid77-...'
    """
    shared = launch_id(environ, parent_pid)
    if shared is not None:  # ranks start seconds apart: the time of day would split them
        return f"{now:%Y-%m-%d}_{shared}"
    return f"{now:%Y-%m-%d_%H-%M-%S}_{pid}-{secrets.token_hex(2)}"


def launch_id(environ: Mapping[str, str], parent_pid: int) -> str | None:
    """The id every rank of one multi-process launch shares, or ``None`` for a single process.

    - ``srun`` with several tasks: ``slurm-<job>.<step>``.
    - torchrun with ``WORLD_SIZE > 1``: ``torchrun-<rendezvous id>`` (``--rdzv-id``; ``--standalone`` draws one);
      with the default id ``none``, the agent's pid, which every rank of a single-node launch shares, and the host
      name: ``torchrun-pid<agent>-<host>``.
    """
    if environ.get("SLURM_JOB_ID") and int(environ.get("SLURM_NTASKS", "1")) > 1:
        step = environ.get("SLURM_STEP_ID")
        return f"slurm-{environ['SLURM_JOB_ID']}" + (f".{step}" if step else "")
    run_id = environ.get("TORCHELASTIC_RUN_ID")
    if run_id is not None and int(environ.get("WORLD_SIZE", "1")) > 1:
        if run_id == "none":
            return f"torchrun-pid{parent_pid}-{socket.gethostname()}"
        return f"torchrun-{_safe(run_id)}"
    return None


def _safe(text: str) -> str:
    """``text`` with anything but letters, digits, ``.``, ``_`` and ``-`` replaced: a folder-name part."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", text)


#: The environment variable that hands a multirun's folder name to jobs that a launcher runs in other processes.
SWEEP_NAME_ENV = "AIRFISHEYE_SWEEP_NAME"


def sweep_name() -> str:
    """The sweep folder's name (``hydra.sweep.dir`` ends in ``${sweep_name:}``): one for every job of a multirun.

    Hydra's basic launcher runs the jobs in the process that resolved the folder, but the submitit launcher
    resolves ``hydra.sweep.dir`` again in each job's own process (another pid, another host): the first resolution
    is kept in :data:`SWEEP_NAME_ENV`, which those processes inherit (locally and through ``sbatch``).

    Example:
        >>> os.environ.pop(SWEEP_NAME_ENV, None) and None
        >>> sweep_name() == run_name() == os.environ.pop(SWEEP_NAME_ENV)
        True
    """
    name = os.environ.get(SWEEP_NAME_ENV)
    if not name:
        name = os.environ[SWEEP_NAME_ENV] = run_name()
    return name


def run_label(run_dir: str | Path) -> str:
    """The name a run goes by (leaderboard rows, MLflow runs): its folder's, with the sweep's for a multirun job.

    A multirun job's folder is its number under the sweep folder (``hydra.sweep.subdir``); a run directory's
    name never is a bare number (:func:`run_name`).

    Example:
        >>> run_label("logs/seg/runs/2026-11-24_09-30-05_812-a3f0")
        '2026-11-24_09-30-05_812-a3f0'
        >>> run_label("logs/seg/multiruns/2026-11-24_09-30-05_812-a3f0/3")
        '2026-11-24_09-30-05_812-a3f0/3'
    """
    path = Path(run_dir)
    return f"{path.parent.name}/{path.name}" if path.name.isdigit() and path.parent.name else path.name


#: A name of :func:`run_name`: ``<date>_<time>_<pid>-<4 hex>``, or ``<date>_<launch id>`` (:func:`launch_id`).
_RUN_NAME = re.compile(
    r"(?P<date>\d{4}-\d{2}-\d{2})_(?:(?P<time>\d{2}-\d{2}-\d{2})_\d+-[0-9a-f]{4}|(?P<launch>(?:slurm|torchrun)-.+))"
)


def run_started(label: str) -> str | None:
    """When a run whose folder :func:`run_name` named started, as a person reads it, from its :func:`run_label`;
    ``None`` for a name given by hand (``hydra.run.dir=``, an evaluation's ``name=``).

    Example:
        >>> run_started("2026-11-24_09-30-05_812-a3f0")
        '2026-11-24 09:30:05'
        >>> run_started("2026-11-24_09-30-05_812-a3f0/3"), run_started("2026-11-24_slurm-4471.0")
        ('2026-11-24 09:30:05, job 3', '2026-11-24 (slurm-4471.0)')
        >>> run_started("adabins-r18") is None
        True
    """
    sweep, _, job = label.rpartition("/")
    name, job = (sweep, job) if sweep and job.isdigit() else (label, "")
    match = _RUN_NAME.fullmatch(name)
    if match is None:
        return None
    time = match["time"]
    when = f"{match['date']} {time.replace('-', ':')}" if time else f"{match['date']} ({match['launch']})"
    return f"{when}, job {job}" if job else when


def register_resolvers() -> None:
    """Register ``${run_name:}`` and ``${sweep_name:}`` (``hydra.run.dir``, ``hydra.sweep.dir``) with OmegaConf;
    safe to call more than once."""
    if not OmegaConf.has_resolver("run_name"):
        OmegaConf.register_new_resolver("run_name", run_name)
    if not OmegaConf.has_resolver("sweep_name"):
        OmegaConf.register_new_resolver("sweep_name", sweep_name)


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


def numbered_sibling(path: Path) -> Path:
    """The first free ``<stem>.<n><suffix>`` next to ``path`` (n = 1, 2, ...): where a replaced file is kept.

    Example:
        >>> import tempfile
        >>> folder = Path(tempfile.mkdtemp())
        >>> _ = (folder / "config.1.yaml").write_text("")
        >>> numbered_sibling(folder / "config.yaml").name
        'config.2.yaml'
    """
    n = 1
    while (candidate := path.with_name(f"{path.stem}.{n}{path.suffix}")).exists():
        n += 1
    return candidate


def keep_metric_rows(path: Path, rows: int) -> None:
    """Cut ``metrics.csv`` back to its header and first ``rows`` rows: the ones a checkpoint had logged.

    Rows written after that checkpoint, by the killed process, are logged again by the resumed one.

    Example:
        >>> import tempfile
        >>> p = Path(tempfile.mkdtemp()) / "metrics.csv"
        >>> _ = p.write_text("step,loss\\r\\n0,1.5\\r\\n1,1.2\\r\\n2,0.9\\r\\n")
        >>> keep_metric_rows(p, 2)
        >>> p.read_text().splitlines()
        ['step,loss', '0,1.5', '1,1.2']
    """
    if not path.is_file():
        return
    lines = path.read_text().splitlines(keepends=True)
    if len(lines) > rows + 1:
        atomic_write_text(path, "".join(lines[: rows + 1]))


def _plain(config: DictConfig | dict) -> Any:
    return OmegaConf.to_container(config, resolve=True) if isinstance(config, DictConfig) else config


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


#: The format of log lines when no handler gives one (Hydra's job logging: ``[time][logger][level] - message``).
LOG_FORMAT = "[%(asctime)s][%(name)s][%(levelname)s] - %(message)s"


@contextlib.contextmanager
def run_log(output_dir: Path) -> Iterator[Callable[[], None]]:
    """Write the command's log to ``<run>/<job name>.log`` (``train.log``, ``evaluate.log``) while active; yields
    ``open_log``.

    Until ``open_log()`` is called the records are held in memory: the checks and the building of the data and
    model log lines too, but a refused command writes nothing into the run directory. ``open_log()``, called once
    the command writes its run directory, writes the held records to the file, then every later one (Hydra's own
    file handler is switched off in ``configs/hydra/default.yaml`` and ``configs/evaluate.yaml``). Outside a Hydra
    application (a library caller) nothing is attached.
    """
    if not HydraConfig.initialized():
        yield lambda: None
        return
    root = logging.getLogger()
    console = next((h for h in root.handlers if h.formatter is not None), None)
    # Never flushed on its own (no capacity or level reached): open_log hands the records to the file.
    held = logging.handlers.MemoryHandler(sys.maxsize, logging.CRITICAL + 1, flushOnClose=False)
    root.addHandler(held)
    handlers: list[logging.Handler] = []

    def open_log() -> None:
        output_dir.mkdir(parents=True, exist_ok=True)
        handler = logging.FileHandler(output_dir / f"{HydraConfig.get().job.name}.log")
        handler.setFormatter(console.formatter if console else logging.Formatter(LOG_FORMAT))
        root.removeHandler(held)
        held.setTarget(handler)
        held.flush()
        root.addHandler(handler)
        handlers.append(handler)

    try:
        yield open_log
    finally:
        root.removeHandler(held)
        held.close()
        for handler in handlers:
            root.removeHandler(handler)
            handler.close()
