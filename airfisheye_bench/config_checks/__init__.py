"""The schema of the config values a user sets, checked before any long work (dataset generation, model building).

A wrong type or range in a Hydra override (``trainer.max_epochs=abc``, ``data.camera.size=abc``) or a misspelt
option (``data.occlusion=zbufer``) would otherwise surface minutes later, deep inside Lightning or the remap code,
as a message that names neither the key nor the fix. :data:`RULES` is one table, dotted key -> :class:`ValueRule`
(type, range, choices, must-exist), and :func:`check_common_values` raises
:class:`~airfisheye_bench.errors.ConfigError` (a file or folder that does not exist:
:class:`~airfisheye_bench.errors.MissingFileError`) naming the key, the value given and what is expected. Keys
absent from the config are skipped, so the same table serves ``train.yaml``, ``evaluate.yaml`` and a run's
``data`` group.

The data options (``data.*``) are declared once, with their defaults and documentation, in
:data:`~airfisheye_bench.config_checks.data_options.DATA_OPTIONS`; their rules join :data:`RULES` from there.

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

from airfisheye_bench.config_checks.check import (
    check_common_values,
    check_extras,
    check_loss_arguments,
    check_train_config,
)
from airfisheye_bench.config_checks.data_options import DATA_OPTIONS, DataOption
from airfisheye_bench.config_checks.rules import EXTRAS, RULES
from airfisheye_bench.config_checks.value_rule import ValueRule

__all__ = [
    "DATA_OPTIONS",
    "EXTRAS",
    "RULES",
    "DataOption",
    "ValueRule",
    "check_common_values",
    "check_extras",
    "check_loss_arguments",
    "check_train_config",
]
