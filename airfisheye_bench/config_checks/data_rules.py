"""The checks of the data options' values that need more than a type or a range: each choice list read from the
module that defines it, each rule across keys asked of its owner. :mod:`.data_options` declares which option uses
which; a check that imports its owner (torch, the task specs) does so inside the function, when its key is checked
(docs/design.md, "Layers")."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from airfisheye_bench.config_checks.value_rule import ValueRule

CALIBRATION_HINT = (
    "a calibration file: OpenCV, ROS camera_info, Kalibr camchain, basalt, COLMAP cameras.txt, KITTI-360, "
    "WoodScape, OCamCalib or calib.yaml"
)


def lens_models() -> tuple[str, ...]:
    from airfisheye_bench.geometry.cameras.ideal import LENS_MODELS  # imports torch: only when checked

    return LENS_MODELS


def lens_fov_problem(value: Any, model: Any) -> str | None:
    """``data.camera.fov_deg``: degrees the lens of ``data.camera.model`` can have (the model's own check: a pinhole's
    is below 180, an orthographic lens's at most 180, ...)."""
    from airfisheye_bench.geometry.cameras.ideal import (  # imports torch: only when checked
        LENS_MODELS,
        ideal_camera,
    )

    problem = ValueRule("number", minimum=1).problem(value)
    if problem is not None or model not in LENS_MODELS:
        return problem  # an unknown model is data.camera.model's to refuse
    try:
        ideal_camera(8, 8, fov_deg=float(value), model=str(model))
    except ValueError as err:
        return f"{err} (data.camera.model={model})"
    return None


def camera_fits() -> tuple[str, ...]:
    from airfisheye_bench.geometry.serving import FITS  # imports torch: only when checked

    return FITS


def occlusion_methods() -> tuple[str, ...]:
    from airfisheye_bench.geometry.occlusion import SPARSE_INPUTS  # imports torch: only when checked

    return SPARSE_INPUTS


def occlusion_options_problem(value: Any, method: Any) -> str | None:
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


def gimbal_problem(value: Any, source: Any) -> str | None:
    """``data.gimbal``: the forms of ``geometry.gimbal`` (its own parser), on a remap source."""
    from airfisheye_bench.geometry.gimbal import Gimbal  # imports torch: only when checked

    try:
        Gimbal.parse(value)
    except ValueError as err:
        return str(err).removeprefix("data.gimbal: ")
    if source == "fisheye":
        return "needs data.source=cubemap or equirect (pre-rendered fisheye images have a fixed orientation)"
    return None


def lenses_problem(value: Any, source: Any) -> str | None:
    """``data.camera.lenses``: a list of lens specs (``geometry.lens_draws``' own parser), on a remap source."""
    from airfisheye_bench.geometry.lens_draws import parse_lenses  # imports torch: only when checked

    try:
        parse_lenses(value)
    except ValueError as err:
        return str(err).removeprefix("data.camera.lenses: ").removeprefix("data.camera.")
    return _lens_source_problem(source)


def jitter_problem(value: Any, source: Any) -> str | None:
    """``data.camera.jitter``: ``{focal, principal_point_px, distortion}`` (``geometry.lens_draws``' own parser), on
    a remap source."""
    from airfisheye_bench.geometry.lens_draws import LensJitter  # imports torch: only when checked

    try:
        LensJitter.parse(value)
    except ValueError as err:
        return str(err).removeprefix("data.camera.jitter: ").removeprefix("data.camera.")
    return _lens_source_problem(source)


def _lens_source_problem(source: Any) -> str | None:
    if source == "fisheye":
        return "needs data.source=cubemap or equirect (pre-rendered fisheye images have the release's lens)"
    return None


def lidar_densities() -> tuple[str, ...]:
    from airfisheye_bench.geometry.lidar_density import LIDAR_DENSITIES  # imports torch: only when checked

    return LIDAR_DENSITIES


def dataset_formats() -> tuple[str, ...]:
    from airfisheye_bench.io.datasets import DATASET_FORMATS  # imports torch: only when checked

    return tuple(DATASET_FORMATS)


def format_options_problem(value: Any, format_name: Any) -> str | None:
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


def root_problem(value: Any, format_name: Any) -> str | None:
    """``data.root``: a folder, described as ``data.format`` lays it out (the formats' own description)."""
    from airfisheye_bench.io.datasets import root_description  # imports torch: only when checked

    problem = ValueRule("folder").problem(value)
    return None if problem is None else f"{problem} ({root_description(str(format_name or 'airfisheye'))})"


def lidar_preset_problem(value: Any, root: Any) -> str | None:
    """``data.lidar.preset``: the LiDAR's own rule (a named sensor, or with ``data.root`` a spec file)."""
    from airfisheye_bench.io.lidar_spec import lidar_preset_problem  # imports torch: only when checked

    return lidar_preset_problem(value, synthetic=root is None)


def image_sources() -> tuple[str, ...]:
    from airfisheye_bench.io.dataset_spec import IMAGE_SOURCES  # imports torch: only when checked

    return IMAGE_SOURCES


def remap_site_problem(value: Any, source: Any, sources: Any, gimbal: Any) -> str | None:
    """``data.remap_on``: a site the data can be remapped at (``io.dataset_spec``'s own check)."""
    from airfisheye_bench.io.dataset_spec import remap_site_problem  # imports torch: only when checked

    return remap_site_problem(value, source or "cubemap", sources, gimbal)


def camera_inputs() -> tuple[str, ...]:
    from airfisheye_bench.geometry.ray_maps import CAMERA_INPUTS  # imports torch: only when checked

    return CAMERA_INPUTS


def tasks() -> tuple[str, ...]:
    from airfisheye_bench.specs import task_names  # imports torchmetrics: only when checked

    return tuple(task_names())


def calibration_problem(value: Any) -> str | None:
    """``data.camera.calibration``: an existing file (its contents are read, once, by the datamodule), or the camera
    dict an ONNX model's data config carries in its place."""
    if isinstance(value, Mapping):
        return None
    path = Path(str(value)).expanduser()
    if path.is_file():
        return None
    return "is a folder, expected a calibration file" if path.is_dir() else "no such file"


def lens_coefficients_problem(value: Any) -> str | None:
    """``data.camera.k``: the four Kannala-Brandt coefficients."""
    if (
        isinstance(value, Sequence)
        and not isinstance(value, str)
        and len(value) == 4
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    ):
        return None
    return "expected four numbers [k1, k2, k3, k4]"


def camera_name_problem(value: Any) -> str | None:
    """``data.camera.camera``: which camera of a calibration file, by name or 0-based index."""
    if (isinstance(value, str) and value) or (
        isinstance(value, int) and not isinstance(value, bool) and value >= 0
    ):
        return None
    return "expected a camera name or a 0-based index"
