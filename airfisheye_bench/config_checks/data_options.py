"""The data options (``data.*``), each declared once: its default, its rule and one line of documentation.

:data:`DATA_OPTIONS` is the one place a data option is stated, as :class:`~airfisheye_bench.geometry.cameras.params.Param`
is for a camera model's parameters. What comes from it:

- the check of each value a config sets: the ``data.*`` rules of :data:`airfisheye_bench.config_checks.RULES`;
- the defaults of ``AirFisheyeDataModule`` (``datamodules/datamodule.py``): each parameter's default is
  :func:`default` of its key, and a group (``camera``, ``lidar``, ``augment``) is completed by :func:`group`;
- ``configs/data/synthetic.yaml`` states the same defaults (``tests/datamodules/test_data_options.py`` fails when
  the two disagree);
- the table of ``docs/datasets.md`` ("Data options"), written by ``python scripts/data_options.py`` and tested
  against this table.

A rule that imports to answer (its choices come from the module that defines them) states its ``cost``:
:data:`~airfisheye_bench.config_checks.RULES` checks the cheap keys first, then those that import torch, then
those that import the task specs, so that a mistyped number is answered at once.

Example:
    >>> default("batch_size"), default("lidar.density")
    (8, 'paper')
    >>> group("lidar", {"density": "native"})
    {'preset': None, 'min_range': 1.0, 'density': 'native'}
    >>> group("lidar", {"densty": "native"})
    Traceback (most recent call last):
    ...
    airfisheye_bench.errors.ConfigError: unknown data.lidar keys ['densty']; expected some of density, min_range, preset
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from airfisheye_bench.config_checks import data_rules as r
from airfisheye_bench.config_checks.value_rule import ValueRule
from airfisheye_bench.errors import ConfigError


@dataclass(frozen=True)
class DataOption:
    """One data option.

    Attributes:
        key: Its path under ``data`` (``camera.size``).
        default: What it is when unset: the datamodule's default and ``configs/data/synthetic.yaml``'s value.
        doc: One line: what it means.
        rule: What a config may set it to (``None``: its owner checks it, named in ``doc``).
        cost: What ``rule`` imports to answer: 0 nothing, 1 torch, 2 the task specs (checked in that order).
        yaml: The interpolation ``configs/data/synthetic.yaml`` binds it to instead of ``default``
            (``${task.name}``): the value comes from another key of the run.
    """

    key: str
    default: Any
    doc: str
    rule: ValueRule | None = None
    cost: int = 0
    yaml: str | None = None

    @property
    def group(self) -> str | None:
        """``camera`` for ``camera.size``; ``None`` for a top-level option."""
        return self.key.rpartition(".")[0] or None


def _o(key: str, default: Any, doc: str, rule: ValueRule | None = None, **kwargs: Any) -> DataOption:
    return DataOption(key, default, doc, rule, **kwargs)


DATA_OPTIONS: tuple[DataOption, ...] = (
    _o(
        "task",
        None,
        "the task served: seg, depth or completion",
        ValueRule("choice", choices=r.tasks),
        cost=2,
        yaml="${task.name}",
    ),
    _o(
        "camera_input",
        "none",
        "what the model takes of the camera besides the image: none, or rays (each sample's ray map, the key "
        'rays; docs/design.md, "Ray map"); bound to model.camera_input',
        ValueRule("choice", choices=r.camera_inputs, hint="bound to model.camera_input"),
        cost=1,
        yaml="${oc.select:model.camera_input,none}",
    ),
    # Where the data come from.
    _o(
        "root",
        None,
        "the dataset folder; null: the synthetic preset, generated on first use",
        ValueRule("custom", check=r.root_problem, uses=("data.format",), nullable=True),
        cost=1,
    ),
    _o(
        "format",
        "airfisheye",
        "how data.root is laid out: airfisheye, tartanair, kitti360, woodscape, omni360",
        ValueRule("choice", choices=r.dataset_formats, hint="how data.root is laid out"),
        cost=1,
    ),
    _o(
        "format_options",
        None,
        "that format's options (each dataset's config lists them)",
        ValueRule(
            "custom",
            check=r.format_options_problem,
            uses=("data.format",),
            nullable=True,
            hint="that format's options",
        ),
        cost=1,
    ),
    _o("preset", "quickstart", "the synthetic dataset when data.root is null (tiny, quickstart, paper, ...)"),
    _o(
        "cache_dir",
        None,
        "where synthetic datasets are generated and cached (null: $AIRFISHEYE_DATA or "
        "~/.cache/airfisheye-bench)",
        yaml="${paths.data_dir}",
    ),
    _o(
        "dataset_seed",
        0,
        "the synthetic dataset itself (0: the canonical one)",
        ValueRule("int", minimum=0, hint="0: the canonical synthetic dataset"),
    ),
    _o("splits", ("train", "val", "test"), "the names of the train, val and test splits in dataset.yaml"),
    _o(
        "sources",
        None,
        'several datasets in one run: a list of source names (docs/design.md, "More than one '
        'source"; checked by datamodules/sources.py)',
    ),
    _o("source_options", None, "each source's settings by name (checked by datamodules/sources.py)"),
    # How an image is made.
    _o(
        "source",
        "cubemap",
        "the image source: cubemap or equirect (remapped on the fly), or fisheye (pre-rendered)",
        ValueRule("choice", choices=r.image_sources),
        cost=1,
    ),
    _o(
        "remap_on",
        "worker",
        "where the cube faces become the fisheye: the loader's workers (worker) or the model's device (device)",
        ValueRule(
            "custom",
            check=r.remap_site_problem,
            uses=("data.source", "data.sources", "data.gimbal"),
            hint="where the cube faces become the fisheye: the loader's workers or the model's device",
        ),
        cost=1,
    ),
    _o(
        "camera.size",
        128,
        "the served image side in pixels (paper: 512); null: the lens's own size",
        ValueRule("int", minimum=8, nullable=True, hint="pixels, the served image side"),
    ),
    _o(
        "camera.model",
        None,
        "the lens model (null: the release's lens); pinhole: perspective views of the same data",
        ValueRule("choice", choices=r.lens_models, nullable=True, hint="null: the release's lens"),
        cost=1,
    ),
    _o(
        "camera.fov_deg",
        None,
        "the lens's field of view in degrees (null: the release's); pinhole: across the width, below 180 (null: 90)",
        ValueRule(
            "custom",
            check=r.lens_fov_problem,
            uses=("data.camera.model",),
            nullable=True,
            hint="degrees; null: the release's",
        ),
        cost=1,
    ),
    _o(
        "camera.k",
        None,
        "the four Kannala-Brandt coefficients (null: the release's)",
        ValueRule(
            "custom",
            check=r.lens_coefficients_problem,
            nullable=True,
            hint="kannala_brandt; null: the release's",
        ),
    ),
    _o(
        "camera.calibration",
        None,
        'a calibration file whose lens is served (docs/design.md, "Calibration files")',
        ValueRule("custom", check=r.calibration_problem, nullable=True, hint=r.CALIBRATION_HINT),
    ),
    _o(
        "camera.camera",
        None,
        "the camera of a calibration file with several: a name or a 0-based index",
        ValueRule(
            "custom", check=r.camera_name_problem, nullable=True, hint="of a calibration file with several"
        ),
    ),
    _o(
        "camera.fit",
        "pad",
        "a non-square calibration at size x size: pad (the whole frame) or crop (fill the square)",
        ValueRule("choice", choices=r.camera_fits, hint="a non-square calibration at size x size"),
        cost=1,
    ),
    _o(
        "camera.lenses",
        None,
        "lenses drawn per training sample: a list of specs {model, fov_deg, k} or {calibration, camera}, each "
        "with an optional weight; evaluation serves sample i through lens i mod n",
        ValueRule(
            "custom",
            check=r.lenses_problem,
            uses=("data.source",),
            nullable=True,
            hint="docs/design.md, Lenses drawn per sample",
        ),
        cost=1,
    ),
    _o(
        "camera.jitter",
        None,
        "each training sample's lens perturbed: {focal: r, principal_point_px: p, distortion: d, pool: n} (pool: lenses "
        "an epoch draws, null: one per sample)",
        ValueRule(
            "custom",
            check=r.jitter_problem,
            uses=("data.source",),
            nullable=True,
            hint="docs/design.md, Lenses drawn per sample",
        ),
        cost=1,
    ),
    _o(
        "gimbal",
        None,
        "a virtual gimbal: a view [yaw, pitch(, roll)], a list of views, or ranges drawn per training sample",
        ValueRule(
            "custom",
            check=r.gimbal_problem,
            uses=("data.source",),
            nullable=True,
            hint="docs/design.md, Virtual gimbal",
        ),
        cost=1,
    ),
    # The LiDAR.
    _o(
        "lidar.preset",
        None,
        "the LiDAR: a preset or, with data.root, a spec file; null: the release's",
        ValueRule(
            "custom",
            check=r.lidar_preset_problem,
            uses=("data.root",),
            nullable=True,
            hint="null: the release's LiDAR",
        ),
        cost=1,
    ),
    _o(
        "lidar.min_range",
        1.0,
        "returns closer than this (m) are self-hits: removed and counted",
        ValueRule(
            "number", minimum=0, nullable=True, hint="metres: closer returns are self-hits; null: the default"
        ),
    ),
    _o(
        "lidar.density",
        "paper",
        "the sparse input's returns per pixel: paper_1536 (the paper sensor's on its 1536^2 image; paper is "
        "paper_1536), paper_512 (on the 512^2 image it trained on) or native (every return)",
        ValueRule(
            "choice",
            choices=r.lidar_densities,
            hint="the sparse input's returns per pixel: the scan's, or the paper's under one of its readings",
        ),
        cost=1,
    ),
    _o(
        "occlusion",
        "ordering",
        "the LiDAR occlusion correction: ordering (paper), zbuffer, hpr, none or oracle (exact visibility)",
        ValueRule("choice", choices=r.occlusion_methods, hint="the LiDAR occlusion correction"),
        cost=1,
    ),
    _o(
        "occlusion_options",
        None,
        "that method's options (null: its defaults)",
        ValueRule(
            "custom",
            check=r.occlusion_options_problem,
            uses=("data.occlusion",),
            nullable=True,
            hint="see docs/design.md, LiDAR and occlusion",
        ),
        cost=1,
    ),
    _o(
        "motion_compensation",
        True,
        "the camera-LiDAR transform from both sensors' poses at their own timestamps",
        ValueRule("bool"),
    ),
    _o(
        "max_depth",
        120.0,
        "depth beyond this (m) is invalid (paper: 120)",
        ValueRule("number", minimum=0, hint="metres"),
    ),
    # Training-time augmentation.
    _o(
        "augment.hflip",
        0.5,
        "probability of a horizontal flip",
        ValueRule("number", minimum=0, maximum=1, hint="a probability"),
    ),
    _o(
        "augment.rotate_deg",
        0.0,
        "largest rotation about the optical axis (degrees)",
        ValueRule("number", minimum=0, hint="degrees"),
    ),
    _o(
        "augment.color_jitter",
        (0.2, 0.2, 0.2, 0.05),
        "brightness, contrast, saturation, hue jitter (null: none; checked by datamodules/augment.py)",
    ),
    # Loading.
    _o("batch_size", 8, "training batch size per process", ValueRule("int", minimum=1)),
    _o(
        "eval_batch_size",
        16,
        "evaluation batch size per process (null: batch_size)",
        ValueRule("int", minimum=1, nullable=True),
    ),
    _o(
        "num_workers", 2, "loader worker processes (0: load in the main process)", ValueRule("int", minimum=0)
    ),
    _o("pin_memory", False, "pin host memory (GPU training)", ValueRule("bool")),
    _o("persistent_workers", True, "keep the workers between epochs", ValueRule("bool")),
    _o(
        "skip_bad_frames",
        False,
        "skip (and count) frames that fail to load instead of stopping",
        ValueRule("bool"),
    ),
    _o("seed", 0, "shuffling and augmentation", ValueRule("int"), yaml="${seed}"),
)
"""Every data option, in the order of ``configs/data/synthetic.yaml``."""

OPTIONS: dict[str, DataOption] = {option.key: option for option in DATA_OPTIONS}
GROUPS: tuple[str, ...] = tuple(dict.fromkeys(o.group for o in DATA_OPTIONS if o.group is not None))


def default(key: str) -> Any:
    """The default of ``data.<key>`` (immutable: a list is declared as a tuple)."""
    return OPTIONS[key].default


def group(name: str, given: Mapping[str, Any] | None) -> dict[str, Any]:
    """The options of group ``data.<name>`` (``camera``, ``lidar``, ``augment``): ``given`` over the declared
    defaults; an unknown key is refused, naming the group."""
    declared = {o.key.rpartition(".")[2]: o for o in DATA_OPTIONS if o.group == name}
    given = dict(given or {})
    unknown = sorted(set(given) - set(declared))
    if unknown:
        raise ConfigError(
            f"unknown data.{name} keys {unknown}; expected some of {', '.join(sorted(declared))}"
        )
    return {key: given.get(key, default(option.key)) for key, option in declared.items()}


def check(key: str, value: Any) -> None:
    """Refuse ``data.<key>=value`` by its declared rule: the check a library caller's argument gets (the datamodule's
    door), the same as a config's (:data:`~airfisheye_bench.config_checks.RULES`). Only for a rule that reads no
    other key.

    Raises:
        ConfigError: as :meth:`ValueRule.enforce`.
    """
    rule = OPTIONS[key].rule
    if rule is not None:
        rule.enforce(f"data.{key}", value)


def data_rules(cost: int) -> dict[str, ValueRule]:
    """The rules of the data options of one ``cost``, dotted from the config root, in declaration order."""
    return {f"data.{o.key}": o.rule for o in DATA_OPTIONS if o.rule is not None and o.cost == cost}


def markdown_table() -> str:
    """The table of ``docs/datasets.md`` ("Data options"): key, default, meaning."""

    def shown(option: DataOption) -> str:
        return f"`{option.yaml if option.yaml is not None else _yaml_text(option.default)}`"

    rows = [f"| `data.{o.key}` | {shown(o)} | {_cell(o.doc)} |" for o in DATA_OPTIONS]
    return "\n".join(["| key | default | what it is |", "|---|---|---|", *rows])


def _yaml_text(value: Any) -> str:
    """``value`` as a YAML scalar or flow list (``null``, ``true``, ``[train, val, test]``)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_yaml_text(v) for v in value) + "]"
    return str(value)


def _cell(text: str) -> str:
    """``text`` safe in a Markdown table cell."""
    return text.replace("|", r"\|")
