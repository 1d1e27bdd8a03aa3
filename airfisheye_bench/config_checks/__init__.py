"""The schema of the config values a user sets, checked before any long work (dataset generation, model building).

A wrong type or range in a Hydra override (``trainer.max_epochs=abc``, ``data.camera.size=abc``) or a misspelt
option (``data.occlusion=zbufer``) would otherwise surface minutes later, deep inside Lightning or the remap code,
as a message that names neither the key nor the fix. :data:`RULES` is one table, dotted key -> :class:`ValueRule`
(type, range, choices, must-exist), and :func:`check_common_values` raises
:class:`~airfisheye_bench.errors.ConfigError` (a file or folder that does not exist:
:class:`~airfisheye_bench.errors.MissingFileError`) naming the key, the value given and what is expected. Keys
absent from the config are skipped, so the same table serves ``train.yaml``, ``evaluate.yaml`` and a run's
``data`` group.

This is the one check of each value a config sets: the commands run it before anything else, and the
constructors below (the datamodule, the dataset, the occlusion and camera code) check only the arguments a library
caller hands them directly, once, in their constructor (docs/design.md, "Layers").

Every choice list is read the same way: from the module that defines it (the lens models of
:mod:`airfisheye_bench.geometry.cameras.ideal`, the fits of :mod:`airfisheye_bench.geometry.serving`, the occlusion methods
and options of :mod:`airfisheye_bench.geometry.occlusion`, the LiDAR presets, the image sources of
:mod:`airfisheye_bench.io.dataset_spec`, the task and model registries, Lightning's accelerators and precisions), imported
inside the function that reads it, when its key is checked. Importing this module costs a fifth of a second; its
owners import torch (2 s), the model zoo (8 s) or Lightning: a mistyped ``trainer.max_epochs`` is answered before
any of them, and the rules are ordered so that the costly imports come last, after every cheap key passed. Options
that only ``evaluate`` has take their choices from the evaluation modules, above this one: their rules sit there
(:data:`airfisheye_bench.evaluation.command.EVALUATE_RULES`), checked with the same function.

:data:`EXTRAS` is the second table: keys that need an optional package when set (``logger.mlflow`` needs
``mlflow``), answered with the extra of ``pyproject.toml`` to install (:func:`check_extras`, run by
:func:`check_common_values` with the default rules).
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import math
import typing
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import InterpolationResolutionError

from airfisheye_bench.config_checks.value_rule import ValueRule
from airfisheye_bench.constants import config_dir
from airfisheye_bench.errors import ConfigError, MissingFileError

_ABSENT = object()


# The choice lists, each read from the module that defines it when its key is checked (see the module docstring).
def _lens_models() -> tuple[str, ...]:
    from airfisheye_bench.geometry.cameras.ideal import LENS_MODELS  # imports torch: only when checked

    return LENS_MODELS


def _camera_fits() -> tuple[str, ...]:
    from airfisheye_bench.geometry.serving import FITS  # imports torch: only when checked

    return FITS


def _occlusion_methods() -> tuple[str, ...]:
    from airfisheye_bench.geometry.occlusion import SPARSE_INPUTS  # imports torch: only when checked

    return SPARSE_INPUTS


def _occlusion_options_problem(value: Any, method: Any) -> str | None:
    """``data.occlusion_options``: the options of ``data.occlusion``'s method (the method's own check)."""
    # imports torch: only when checked
    from airfisheye_bench.geometry.occlusion import check_occlusion_options

    if not isinstance(value, Mapping):
        return "expected a mapping of option: value"
    try:
        check_occlusion_options(method, dict(value))
    except ValueError as err:
        return f"{err} (data.occlusion={method})"
    return None


def _gimbal_problem(value: Any, source: Any) -> str | None:
    """``data.gimbal``: the forms of ``geometry.gimbal`` (its own parser), on a remap source."""
    from airfisheye_bench.geometry.gimbal import Gimbal  # imports torch: only when checked

    try:
        Gimbal.parse(value)
    except ValueError as err:
        return str(err).removeprefix("data.gimbal: ")
    if source == "fisheye":
        return "needs data.source=cubemap or equirect (pre-rendered fisheye images have a fixed orientation)"
    return None


def _lidar_densities() -> tuple[str, ...]:
    from airfisheye_bench.geometry.lidar_density import LIDAR_DENSITIES  # imports torch: only when checked

    return LIDAR_DENSITIES


def _dataset_formats() -> tuple[str, ...]:
    from airfisheye_bench.io.datasets import DATASET_FORMATS  # imports torch: only when checked

    return tuple(DATASET_FORMATS)


def _format_options_problem(value: Any, format_name: Any) -> str | None:
    """``data.format_options``: the options of ``data.format``'s reader (the format's own check)."""
    from airfisheye_bench.io.datasets import (  # imports torch: only when checked
        DATASET_FORMATS,
        check_options,
    )

    if not isinstance(value, Mapping):
        return "expected a mapping of option: value"
    try:
        check_options(format_name, dict(value), DATASET_FORMATS[format_name].OPTIONS)
    except ValueError as err:
        return str(err).removeprefix("data.format_options: ")
    return None


def _root_problem(value: Any, format_name: Any) -> str | None:
    """``data.root``: a folder, described as ``data.format`` lays it out (the formats' own description)."""
    from airfisheye_bench.io.datasets import root_description  # imports torch: only when checked

    problem = ValueRule("folder").problem(value)
    return None if problem is None else f"{problem} ({root_description(str(format_name or 'airfisheye'))})"


def _lidar_preset_problem(value: Any, root: Any) -> str | None:
    """``data.lidar.preset``: the LiDAR's own rule (a named sensor, or with ``data.root`` a spec file)."""
    from airfisheye_bench.io.lidar_spec import lidar_preset_problem  # imports torch: only when checked

    return lidar_preset_problem(value, synthetic=root is None)


def _image_sources() -> tuple[str, ...]:
    from airfisheye_bench.io.dataset_spec import IMAGE_SOURCES  # imports torch: only when checked

    return IMAGE_SOURCES


def _remap_site_problem(value: Any, source: Any, sources: Any, gimbal: Any) -> str | None:
    """``data.remap_on``: a site the data can be remapped at (``io.dataset_spec``'s own check)."""
    from airfisheye_bench.io.dataset_spec import remap_site_problem  # imports torch: only when checked

    return remap_site_problem(value, source or "cubemap", sources, gimbal)


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


def _lens_coefficients_problem(value: Any) -> str | None:
    """``data.camera.k``: the four Kannala-Brandt coefficients."""
    if (
        isinstance(value, Sequence)
        and not isinstance(value, str)
        and len(value) == 4
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    ):
        return None
    return "expected four numbers [k1, k2, k3, k4]"


def _camera_name_problem(value: Any) -> str | None:
    """``data.camera.camera``: which camera of a calibration file, by name or 0-based index."""
    if (isinstance(value, str) and value) or (
        isinstance(value, int) and not isinstance(value, bool) and value >= 0
    ):
        return None
    return "expected a camera name or a 0-based index"


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
    "data.camera.size": ValueRule("int", minimum=8, nullable=True, hint="pixels, the served image side"),
    "data.camera.fov_deg": ValueRule("number", minimum=1, nullable=True, hint="degrees; null: the release's"),
    "data.camera.k": ValueRule(
        "custom", check=_lens_coefficients_problem, nullable=True, hint="kannala_brandt; null: the release's"
    ),
    "data.camera.calibration": ValueRule(
        "custom",
        check=_calibration_problem,
        nullable=True,
        hint="a calibration file: OpenCV, ROS camera_info, Kalibr camchain, basalt, COLMAP cameras.txt, KITTI-360, "
        "WoodScape, OCamCalib or calib.yaml",
    ),
    "data.camera.camera": ValueRule(
        "custom", check=_camera_name_problem, nullable=True, hint="of a calibration file with several"
    ),
    "data.lidar.min_range": ValueRule(
        "number", minimum=0, nullable=True, hint="metres: closer returns are self-hits; null: the default"
    ),
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
    "task.module.loss": ValueRule(
        "custom", check=_loss_problem, nullable=True, hint="the training loss; null: the task's default"
    ),
    # Costly choices last: they import torch, then the task specs, the model zoo and Lightning.
    "data.source": ValueRule("choice", choices=_image_sources),
    "data.remap_on": ValueRule(
        "custom",
        check=_remap_site_problem,
        uses=("data.source", "data.sources", "data.gimbal"),
        hint="where the cube faces become the fisheye: the loader's workers or the model's device",
    ),
    "data.camera.model": ValueRule(
        "choice", choices=_lens_models, nullable=True, hint="null: the release's lens"
    ),
    "data.camera.fit": ValueRule(
        "choice", choices=_camera_fits, hint="a non-square calibration at size x size"
    ),
    "data.occlusion": ValueRule("choice", choices=_occlusion_methods, hint="the LiDAR occlusion correction"),
    "data.occlusion_options": ValueRule(
        "custom",
        check=_occlusion_options_problem,
        uses=("data.occlusion",),
        nullable=True,
        hint="see docs/design.md, LiDAR and occlusion",
    ),
    "data.gimbal": ValueRule(
        "custom",
        check=_gimbal_problem,
        uses=("data.source",),
        nullable=True,
        hint="docs/design.md, Virtual gimbal",
    ),
    "data.lidar.density": ValueRule(
        "choice",
        choices=_lidar_densities,
        hint="the sparse input's returns per pixel: the scan's, or the paper's",
    ),
    "data.format": ValueRule("choice", choices=_dataset_formats, hint="how data.root is laid out"),
    "data.root": ValueRule("custom", check=_root_problem, uses=("data.format",), nullable=True),
    "data.format_options": ValueRule(
        "custom",
        check=_format_options_problem,
        uses=("data.format",),
        nullable=True,
        hint="that format's options",
    ),
    "data.lidar.preset": ValueRule(
        "custom",
        check=_lidar_preset_problem,
        uses=("data.root",),
        nullable=True,
        hint="null: the release's LiDAR",
    ),
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
        problem = rule.problem(value, *(_plain(_select(cfg, other)) for other in rule.uses))
        if problem is not None:
            hint = f" ({rule.hint})" if rule.hint else ""
            error = MissingFileError if problem.startswith("no such") else ConfigError
            raise error(f"{key}={value!r}: {problem}{hint}")


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
