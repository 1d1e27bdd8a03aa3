"""The project's own files: a dataset's ``calib.yaml`` (its ``camera`` section) and a camera file that
:func:`~airfisheye_bench.io.calibration_files.save_camera` writes (the camera's flat dict at the top level, YAML or
JSON).

The dict is the camera contract's ``to_dict()`` (``docs/design.md``, "Fisheye camera"): ``model``, ``width``,
``height`` and the model's parameters, pixel centres at integers. It is passed on unchanged: the camera registry
(``camera_from_dict``) checks it, including the older Kannala-Brandt dicts (``focal``, ``k``).

Example:
    >>> _cameras(Fields("calib.yaml", {"camera": {"model": "equidistant", "width": 64, "height": 64}}))
    {'0': <function _read at ...>}
"""

from __future__ import annotations

from typing import Any

from airfisheye_bench.io.calibration_files._fields import CalibrationFormat, CameraEntry, Fields

__all__ = ["FORMAT"]


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
