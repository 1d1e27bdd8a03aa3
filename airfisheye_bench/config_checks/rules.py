"""The tables of what a config may set: :data:`RULES` (dotted key -> :class:`ValueRule`) and :data:`EXTRAS` (keys
that need an optional package). The data options' rules come from their declarations (:mod:`.data_options`);
the others are stated here. Costly rules come last: they import torch, then the task specs, the model zoo and
Lightning (the package docstring says why)."""

from __future__ import annotations

import typing
from collections.abc import Mapping, Sequence
from typing import Any

from omegaconf import DictConfig

from airfisheye_bench.config_checks.data_options import data_rules
from airfisheye_bench.config_checks.data_rules import camera_inputs, tasks
from airfisheye_bench.config_checks.value_rule import ValueRule


def _model_names() -> list[str]:
    from models import list_models  # imports the model zoo: only when checked

    return list_models()


def _encoder_weights_problem(value: Any) -> str | None:
    """The model zoo's own reading of ``encoder_weights``: null, a pretrained tag, or an existing weights file."""
    from models.weights import resolve_encoder_weights  # imports the model zoo: only when checked

    try:
        resolve_encoder_weights(value)
    except ValueError as err:
        return str(err)
    return None


def _accelerators() -> list[str]:
    from lightning.pytorch.accelerators import AcceleratorRegistry  # imports Lightning: checked last

    return ["auto", "gpu", *sorted(AcceleratorRegistry.available_accelerators())]


def _precision_problem(value: Any) -> str | None:
    """``trainer.precision``: one of the Trainer's own precision names (``16`` and ``"16"`` alike)."""
    from lightning.fabric.connector import _PRECISION_INPUT  # the Trainer's annotation; imports Lightning

    def literals(annotation: Any) -> list[str]:
        args = typing.get_args(annotation)
        return [a for arg in args for a in literals(arg)] if args else [str(annotation)]

    names = list(dict.fromkeys(literals(_PRECISION_INPUT)))
    return None if str(value) in names else f"expected one of {', '.join(names)}"


def _devices_problem(value: Any) -> str | None:
    """``trainer.devices``: a count >= 1 (or -1: all), ``auto``, or a list of device indices."""

    def index(i: Any) -> bool:
        return isinstance(i, int) and not isinstance(i, bool)

    if value == "auto" or (index(value) and (value >= 1 or value == -1)):
        return None
    if (
        isinstance(value, Sequence)
        and not isinstance(value, str)
        and value
        and all(index(i) and i >= 0 for i in value)
    ):
        return None
    return "expected a device count >= 1 (-1: all), auto, or a list of device indices"


def _loss_problem(value: Any) -> str | None:
    """``task.module.loss``: a partial of a loss class, which the task builds and its checkpoint records.

    Example:
        >>> _loss_problem({"_target_": "models.losses.SILogLoss", "_partial_": True})
        >>> _loss_problem({"_target_": "models.losses.SILogLoss"})
        'add _partial_: true: the task builds the loss, so that its checkpoint records its settings'
    """
    if not isinstance(value, Mapping) or not isinstance(value.get("_target_"), str):
        return "expected {_target_: <a loss class, e.g. models.losses.SILogLoss>, _partial_: true, <its settings>}"
    if value.get("_partial_") is not True:
        return "add _partial_: true: the task builds the loss, so that its checkpoint records its settings"
    return None


def _not_resuming(cfg: DictConfig) -> bool:
    # A resume restores every weight from the checkpoint and never reads the initial weights (which may be gone).
    return cfg.get("ckpt_path") is None


RULES: dict[str, ValueRule] = {
    "seed": ValueRule("int"),
    "train": ValueRule("bool"),
    "test": ValueRule("bool"),
    "compile": ValueRule("bool"),
    "resume_overrides_ok": ValueRule("bool"),
    "retest": ValueRule("bool"),
    "print_breakdown": ValueRule("bool"),
    "ckpt_path": ValueRule(
        "path",
        nullable=True,
        keywords=("last",),
        hint="a checkpoint or a run directory; train also takes last",
    ),
    "onnx_path": ValueRule("file", nullable=True, hint="a model written by scripts/export_onnx.py"),
    "predictions": ValueRule("folder", nullable=True, hint="a folder of prediction files"),
    "trainer.max_epochs": ValueRule("int", minimum=-1, nullable=True, hint="-1: no limit"),
    "trainer.min_epochs": ValueRule("int", minimum=0, nullable=True),
    "trainer.max_steps": ValueRule("int", minimum=-1, nullable=True, hint="-1: no limit"),
    "trainer.devices": ValueRule("custom", check=_devices_problem),
    "trainer.num_nodes": ValueRule("int", minimum=1),
    "trainer.accumulate_grad_batches": ValueRule("int", minimum=1),
    "trainer.check_val_every_n_epoch": ValueRule("int", minimum=1, nullable=True),
    "trainer.log_every_n_steps": ValueRule("int", minimum=1, nullable=True),
    "trainer.limit_train_batches": ValueRule(
        "number", minimum=0, nullable=True, hint="a count, or a fraction"
    ),
    "trainer.limit_val_batches": ValueRule("number", minimum=0, nullable=True, hint="a count, or a fraction"),
    "trainer.limit_test_batches": ValueRule(
        "number", minimum=0, nullable=True, hint="a count, or a fraction"
    ),
    "trainer.num_sanity_val_steps": ValueRule("int", minimum=-1, nullable=True, hint="-1: the whole split"),
    "trainer.gradient_clip_val": ValueRule("number", minimum=0, nullable=True),
    "callbacks.last_checkpoint.every_n_train_steps": ValueRule("int", minimum=1, nullable=True),
    "callbacks.progress.every_n_steps": ValueRule(
        "int", minimum=0, nullable=True, hint="0 or null: epochs only"
    ),
    **data_rules(cost=0),
    "batch_size": ValueRule("int", minimum=1),  # evaluate.yaml's own loader
    "num_workers": ValueRule("int", minimum=0),
    "task.module.loss": ValueRule(
        "custom", check=_loss_problem, nullable=True, hint="the training loss; null: the task's default"
    ),
    # Costly choices last: they import torch, then the task specs, the model zoo and Lightning.
    # Before data.camera_input, which follows it: a wrong value is named where it was written.
    "model.camera_input": ValueRule(
        "choice", choices=camera_inputs, hint="what the model takes of its camera besides the image"
    ),
    **data_rules(cost=1),
    "task.name": ValueRule("choice", choices=tasks),
    **data_rules(cost=2),
    "model.name": ValueRule("choice", choices=_model_names, hint="a registered model"),
    "model.encoder_weights": ValueRule(
        "custom", check=_encoder_weights_problem, nullable=True, when=_not_resuming
    ),
    "model.weights_path": ValueRule(
        "file", nullable=True, when=_not_resuming, hint="a state dict of the whole model"
    ),
    "trainer.accelerator": ValueRule("choice", choices=_accelerators),
    "trainer.precision": ValueRule("custom", check=_precision_problem),
}
"""The checked keys (dotted, from the config root) and what each accepts."""


EXTRAS: dict[str, tuple[tuple[str, ...], str]] = {
    "logger.mlflow": (("mlflow",), "mlflow"),
    "mlflow_run": (("mlflow",), "mlflow"),
    "logger.tensorboard": (("tensorboard", "tensorboardX"), "tensorboard"),
}
"""Keys that need an optional package when set (not null): key -> (the modules, any of which serves; the extra
of ``pyproject.toml`` that installs the first)."""
