"""Run directories: unique names, resuming one with the configuration it was started with, and finding its checkpoint.

A run directory (``logs/<task>/runs/<time>_<suffix>``) holds ``config.yaml`` (the resolved configuration),
``checkpoints/`` (``last.ckpt`` and the best ones), ``metrics.csv`` and, after testing, ``results.json`` naming the
best checkpoint. The modules here, each named for what it holds:

- :mod:`.names`: the run and sweep folder names (``${run_name:}``, ``${sweep_name:}``; :func:`register_resolvers`,
  registered by the entry points before Hydra composes) and the name a run goes by (:func:`run_label`);
- :mod:`.resume`: resuming a run with its own configuration (:func:`resume_config`) and which changes a resume may
  make (:data:`RESUME_UNSAFE`, :data:`RESUME_HARMLESS`, :func:`check_resume`);
- :mod:`.checkpoints`: the checkpoint of a run directory or ``.ckpt`` path (:func:`resolve_checkpoint`), the run
  that wrote it and its configuration (:func:`run_config`), reading a checkpoint file (:func:`read_checkpoint`);
- :mod:`.files`: the command's log file, written only once the run directory is (:func:`run_log`), ``metrics.csv``
  cut back on a resume, the numbered copy of a replaced file;
- :mod:`.results` (``results.json``, written by training and evaluation alike) and :mod:`.deployment` (the deployed
  ONNX model's metadata, written by export, read by evaluation and prediction): what a run writes beside its
  checkpoints.

The names of the first four are re-exported here. Kept light (no torch import at module level).
"""

from airfisheye_bench.runs.checkpoints import (
    checkpoint_run_name,
    read_checkpoint,
    resolve_checkpoint,
    run_config,
    run_directory,
)
from airfisheye_bench.runs.files import LOG_FORMAT, keep_metric_rows, numbered_sibling, run_log
from airfisheye_bench.runs.names import (
    SWEEP_NAME_ENV,
    launch_id,
    register_resolvers,
    run_label,
    run_name,
    run_name_for,
    run_started,
    sweep_name,
)
from airfisheye_bench.runs.resume import (
    GROUP_PACKAGES,
    RESUME_HARMLESS,
    RESUME_KEYS,
    RESUME_UNSAFE,
    check_resume,
    config_differences,
    flatten,
    resume_change,
    resume_config,
    saved_config,
)

__all__ = [
    "GROUP_PACKAGES",
    "LOG_FORMAT",
    "RESUME_HARMLESS",
    "RESUME_KEYS",
    "RESUME_UNSAFE",
    "SWEEP_NAME_ENV",
    "check_resume",
    "checkpoint_run_name",
    "config_differences",
    "flatten",
    "keep_metric_rows",
    "launch_id",
    "numbered_sibling",
    "read_checkpoint",
    "register_resolvers",
    "resolve_checkpoint",
    "resume_change",
    "resume_config",
    "run_config",
    "run_directory",
    "run_label",
    "run_log",
    "run_name",
    "run_name_for",
    "run_started",
    "saved_config",
    "sweep_name",
]
