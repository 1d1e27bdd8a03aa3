"""The schema of the config values a user sets, checked before any long work (dataset generation, model building).

A wrong type or range in a Hydra override (``trainer.max_epochs=abc``, ``data.camera.size=abc``) or a misspelt
option (``data.occlusion=zbufer``) would otherwise surface minutes later, deep inside Lightning or the remap code,
as a message that names neither the key nor the fix. :data:`RULES` is one table, dotted key -> :class:`ValueRule`
(type, range, choices, must-exist), and :func:`check_common_values` raises
:class:`~airfisheye_bench.errors.ConfigError` (a file or folder that does not exist:
:class:`~airfisheye_bench.errors.MissingFileError`) naming the key, the value given and what is expected. Keys
absent from the config are skipped, so the same table serves ``train.yaml``, ``evaluate.yaml`` and a run's
``data`` group.

The choices come from where each is defined (the lens models of :mod:`airfisheye_bench.geometry.camera`, the
occlusion methods of :mod:`airfisheye_bench.geometry.occlusion`, the image sources of :mod:`airfisheye_bench.io.spec`,
the model registry, Lightning's accelerators and precisions), read only when their key is checked: the costly
imports (the model zoo, Lightning) come last, after every cheap key passed. Options that only ``evaluate`` has
take their choices from the evaluation modules, above this one: their rules sit there
(:data:`airfisheye_bench.evaluation.command.EVALUATE_RULES`), checked with the same function.

:data:`EXTRAS` is the second table: keys that need an optional package when set (``logger.mlflow`` needs
``mlflow``), answered with the extra of ``pyproject.toml`` to install (:func:`check_extras`, run by
:func:`check_common_values` with the default rules).
"""

from __future__ import annotations

import importlib.util
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import InterpolationResolutionError

from airfisheye_bench.constants import CAMERA_FITS, LENS_MODELS
from airfisheye_bench.errors import ConfigError, MissingFileError

_ABSENT = object()
_KINDS = ("int", "number", "bool", "choice", "file", "folder", "path", "custom")


@dataclass(frozen=True)
class ValueRule:
    """What one key accepts.

    Attributes:
        kind: ``int``, ``number`` (int or float), ``bool``, ``choice`` (one of ``choices``), ``file`` / ``folder``
            / ``path`` (an existing file, folder, or either) or ``custom`` (``check`` says).
        minimum: Smallest accepted number (``int`` / ``number``).
        maximum: Largest accepted number.
        choices: The accepted values of a ``choice``; a callable defers a costly import until the key is checked.
        nullable: Whether ``null`` is accepted.
        keywords: Values a ``file`` / ``folder`` / ``path`` also accepts as they are (``ckpt_path=last``).
        check: For ``custom``: the reason a value is refused, or ``None``.
        when: Checked only when this returns true for the whole config (e.g. not when resuming).
        hint: What the value means, appended to the message.

    Example:
        >>> ValueRule("int", minimum=1).problem(0)
        'expected an integer >= 1'
        >>> ValueRule("choice", choices=("png", "npy")).problem("tiff")
        'expected one of png, npy'
        >>> ValueRule("bool").problem("yes"), ValueRule("number", maximum=1).problem(0.5)
        ('expected true or false', None)
    """

    kind: str
    minimum: float | None = None
    maximum: float | None = None
    choices: Sequence[Any] | Callable[[], Sequence[Any]] = ()
    nullable: bool = False
    keywords: Sequence[str] = ()
    check: Callable[[Any], str | None] | None = None
    when: Callable[[DictConfig], bool] | None = None
    hint: str = ""

    def __post_init__(self) -> None:
        if self.kind not in _KINDS:
            raise ValueError(f"kind must be one of {_KINDS}, got {self.kind!r}")

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is refused, or ``None`` when it is accepted."""
        if value is None:
            return None if self.nullable else "must be set"
        if self.kind == "choice":
            choices = self.choices() if callable(self.choices) else self.choices
            return None if value in choices else f"expected one of {', '.join(map(str, choices))}"
        if self.kind == "bool":
            return None if isinstance(value, bool) else "expected true or false"
        if self.kind in ("file", "folder", "path"):
            return self._path_problem(value)
        if self.kind == "custom":
            return self.check(value) if self.check is not None else None
        return self._number_problem(value)

    def _number_problem(self, value: Any) -> str | None:
        numeric = (int,) if self.kind == "int" else (int, float)
        what = "an integer" if self.kind == "int" else "a number"
        if self.minimum is not None and self.maximum is not None:
            what += f" in [{self.minimum:g}, {self.maximum:g}]"
        elif self.minimum is not None:
            what += f" >= {self.minimum:g}"
        elif self.maximum is not None:
            what += f" <= {self.maximum:g}"
        if isinstance(value, bool) or not isinstance(value, numeric):
            return f"expected {what}"
        if (self.minimum is not None and value < self.minimum) or (
            self.maximum is not None and value > self.maximum
        ):
            return f"expected {what}"
        return None

    def _path_problem(self, value: Any) -> str | None:
        if value in self.keywords:
            return None
        path = Path(str(value)).expanduser()
        if self.kind == "file" and not path.is_file():
            return "is a folder, expected a file" if path.is_dir() else "no such file"
        if self.kind == "folder" and not path.is_dir():
            return "is a file, expected a folder" if path.exists() else "no such folder"
        if self.kind == "path" and not path.exists():
            return "no such file or folder"
        return None


def _occlusion_methods() -> tuple[str, ...]:
    from airfisheye_bench.geometry.occlusion import SPARSE_INPUTS  # imports torch: only when checked

    return SPARSE_INPUTS


def _image_sources() -> tuple[str, ...]:
    from airfisheye_bench.io.spec import IMAGE_SOURCES  # imports torch: only when checked

    return IMAGE_SOURCES


def _tasks() -> tuple[str, ...]:
    from airfisheye_bench.specs import task_names  # imports torchmetrics: only when checked

    return tuple(task_names())


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


def _calibration_problem(value: Any) -> str | None:
    """``data.camera.calibration``: an existing file (its contents are read, once, by the datamodule), or the camera
    dict an ONNX model's data config carries in its place."""
    if isinstance(value, Mapping):
        return None
    path = Path(str(value)).expanduser()
    if path.is_file():
        return None
    return "is a folder, expected a calibration file" if path.is_dir() else "no such file"


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
    "data.root": ValueRule(
        "folder",
        nullable=True,
        hint="a dataset in the AirFisheye layout, holding dataset.yaml; null: the synthetic data.preset",
    ),
    "data.source": ValueRule("choice", choices=_image_sources),
    "data.camera.size": ValueRule("int", minimum=8, nullable=True, hint="pixels, the served image side"),
    "data.camera.fov_deg": ValueRule("number", minimum=1, nullable=True, hint="degrees; null: the release's"),
    "data.camera.model": ValueRule(
        "choice", choices=LENS_MODELS, nullable=True, hint="null: the release's lens"
    ),
    "data.camera.calibration": ValueRule(
        "custom",
        check=_calibration_problem,
        nullable=True,
        hint="a calibration file: OpenCV, ROS camera_info, Kalibr camchain, basalt, COLMAP cameras.txt, KITTI-360, "
        "WoodScape, OCamCalib or calib.yaml",
    ),
    "data.camera.fit": ValueRule(
        "choice", choices=CAMERA_FITS, hint="a non-square calibration at size x size"
    ),
    "data.occlusion": ValueRule("choice", choices=_occlusion_methods, hint="the LiDAR occlusion correction"),
    "data.motion_compensation": ValueRule("bool"),
    "data.max_depth": ValueRule("number", minimum=0, hint="metres"),
    "data.augment.hflip": ValueRule("number", minimum=0, maximum=1, hint="a probability"),
    "data.augment.rotate_deg": ValueRule("number", minimum=0, hint="degrees"),
    "data.batch_size": ValueRule("int", minimum=1),
    "data.eval_batch_size": ValueRule("int", minimum=1, nullable=True),
    "data.num_workers": ValueRule("int", minimum=0),
    "data.pin_memory": ValueRule("bool"),
    "data.persistent_workers": ValueRule("bool"),
    "data.skip_bad_frames": ValueRule("bool"),
    "data.seed": ValueRule("int"),
    "data.dataset_seed": ValueRule("int", minimum=0, hint="0: the canonical synthetic dataset"),
    "batch_size": ValueRule("int", minimum=1),  # evaluate.yaml's own loader
    "num_workers": ValueRule("int", minimum=0),
    # Costly choices last: they import the model zoo, then Lightning.
    "task.name": ValueRule("choice", choices=_tasks),
    "data.task": ValueRule("choice", choices=_tasks),
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


def check_common_values(cfg: DictConfig, rules: Mapping[str, ValueRule] | None = None) -> None:
    """Raise for the first key of ``rules`` whose value has the wrong type or range, or names a missing file.

    Args:
        cfg: A composed config (``train.yaml``, ``evaluate.yaml``, or ``{"data": <a run's data group>}``).
        rules: The keys to check; :data:`RULES` by default.

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
        try:
            value = OmegaConf.select(cfg, key, default=_ABSENT, throw_on_missing=False)
        except InterpolationResolutionError:  # e.g. data.task=${task.name} before evaluate knows the task
            continue
        if value is _ABSENT or (rule.when is not None and not rule.when(cfg)):
            continue
        if not isinstance(value, (str, int, float, bool, type(None))):
            value = OmegaConf.to_container(value)  # a list (trainer.devices=[0,1]) checked as plain data
        problem = rule.problem(value)
        if problem is not None:
            hint = f" ({rule.hint})" if rule.hint else ""
            error = MissingFileError if problem.startswith("no such") else ConfigError
            raise error(f"{key}={value!r}: {problem}{hint}")
