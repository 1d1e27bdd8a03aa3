"""The project's own files: a dataset's ``calib.yaml`` (its ``camera`` section) and a camera file that
:func:`save_camera` writes (the camera's flat dict at the top level, YAML or JSON): read (:data:`FORMAT`) and
written.

The dict is the camera contract's ``to_dict()`` (``docs/design.md``, "Fisheye camera"): ``model``, ``width``,
``height`` and the model's parameters, pixel centres at integers. It is passed on unchanged: the camera registry
(``camera_from_dict``) checks it, including the older Kannala-Brandt dicts (``focal``, ``k``).

Example:
    >>> _cameras(Fields("calib.yaml", {"camera": {"model": "equidistant", "width": 64, "height": 64}}))
    {'0': <function _read at ...>}
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.io.calibration_files._fields import CalibrationFormat, CameraEntry, Fields
from airfisheye_bench.io.yamlio import to_plain

__all__ = ["FORMAT", "save_camera"]


def _is_camera(node: Any) -> bool:
    return (
        isinstance(node, dict)
        and isinstance(node.get("model", "equidistant"), str)
        and {"width", "height"} <= set(node)
    )


def _detect(text: str, doc: Any) -> bool:
    return isinstance(doc, dict) and (
        (_is_camera(doc) and "model" in doc) or ("camera" in doc and _is_camera(doc["camera"]))
    )


def _cameras(fields: Fields) -> dict[str, CameraEntry]:
    return {"0": _read}


def _read(f: Fields) -> tuple[dict[str, Any], dict]:
    node = f.mapping("camera") if "camera" in f.data else f.data
    return dict(node), {}


FORMAT = CalibrationFormat(
    name="airfisheye",
    summary="the project's camera dict (save_camera's file) or a dataset's calib.yaml (its camera section)",
    source="docs/design.md (Fisheye camera, Calibration files); airfisheye_bench/io/calib_yaml.py",
    detect=_detect,
    cameras=_cameras,
)


def save_camera(camera: Any, path: str | Path) -> Path:
    """Write ``camera`` (anything with ``to_dict()``, or its flat dict) as the project's camera file.

    YAML (``.json``: JSON) with the flat dict at the top level, floats written so that they read back exactly;
    written to a temporary name, then renamed. :func:`load_camera` reads it back to an equal camera.

    Returns:
        The path written.
    """
    path = Path(path)
    data = camera.to_dict() if hasattr(camera, "to_dict") else dict(camera)
    if path.suffix.lower() == ".json":
        text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    else:
        header = "# Camera (airfisheye-bench camera dict; docs/design.md, Fisheye camera).\n"
        # Block style, one parameter a line; PyYAML writes floats as repr, which reads back to the same float.
        text = header + yaml.safe_dump(to_plain(data), sort_keys=False, default_flow_style=False, width=120)
    atomic_write_text(path, text)
    return path
