"""ROS ``sensor_msgs/CameraInfo`` calibrations: the YAML that ``camera_calibration_parsers`` writes (what
``cameracalibrator.py`` saves and ``camera_info_manager`` loads) and a message dump (``rostopic echo`` /
``ros2 topic echo`` of a ``camera_info`` topic).

Layouts (github:ros-perception/image_common ``camera_calibration_parsers/src/parse_yml.cpp``; ``CameraInfo.msg``):

- parsers: ``image_width``, ``image_height``, ``camera_name``, ``camera_matrix`` / ``distortion_coefficients``
  as ``{rows, cols, data}``, ``distortion_model`` (absent: ``plumb_bob``, as the parser assumes).
- message: ``width``, ``height``, ``distortion_model``, ``K`` / ``D`` (ROS 1) or ``k`` / ``d`` (ROS 2), flat lists.

``distortion_model`` (``sensor_msgs/distortion_models.h``): ``equidistant`` -> ``kannala_brandt`` (D = k1..k4, the
``cv::fisheye`` model), ``plumb_bob`` and ``rational_polynomial`` (k1, k2, p1, p2, k3..k6) -> ``pinhole_radtan``. Pixel convention: OpenCV's, the project's.

Example:
    >>> doc = {"width": 848, "height": 800, "distortion_model": "equidistant", "D": [0.1, -0.02, 0.003, 0.0],
    ...        "K": [286.0, 0.0, 421.0, 0.0, 286.5, 399.0, 0.0, 0.0, 1.0]}
    >>> camera, _ = _read(Fields("info.yaml", doc))
    >>> camera["model"], camera["cx"], camera["k2"]
    ('kannala_brandt', 421.0, -0.02)
"""

from __future__ import annotations

from typing import Any

import numpy as np

from airfisheye_bench.io.calibration_files._fields import CalibrationFormat, CameraEntry, Fields
from airfisheye_bench.io.calibration_files.opencv import camera_from_matrices

__all__ = ["FORMAT"]

DISTORTION_MODELS = ("equidistant", "plumb_bob", "rational_polynomial")


def _message_keys(doc: dict) -> tuple[str, str] | None:
    for k, d in (("K", "D"), ("k", "d")):
        if isinstance(doc.get(k), list) and isinstance(doc.get(d), list):
            return k, d
    return None


def _detect(text: str, doc: Any) -> bool:
    if not isinstance(doc, dict):
        return False
    if "distortion_model" in doc:
        return True
    # A parsers file without distortion_model: ROS's {rows, cols, data} matrices carry no OpenCV `dt`.
    matrix = doc.get("camera_matrix")
    return "camera_name" in doc and isinstance(matrix, dict) and "dt" not in matrix


def _cameras(fields: Fields) -> dict[str, CameraEntry]:
    name = fields.data.get("camera_name")
    return {str(name) if isinstance(name, str) and name else "0": _read}


def _read(f: Fields) -> tuple[dict[str, Any], dict]:
    message = _message_keys(f.data)
    if message is not None:
        k_key, d_key = message
        width, height = f.whole("width"), f.whole("height")
        K = np.asarray(f.numbers(k_key, 9)).reshape(3, 3)
        D = f.numbers(d_key)
    else:
        k_key, d_key = "camera_matrix", "distortion_coefficients"
        width, height = f.whole("image_width"), f.whole("image_height")
        K = f.opencv_matrix(k_key, (3, 3))
        D = f.opencv_matrix(d_key).reshape(-1).tolist()
    model = f.get("distortion_model", "plumb_bob")
    if model not in DISTORTION_MODELS:
        raise f.error(
            "distortion_model", f"{model!r} is not supported; supported: {', '.join(DISTORTION_MODELS)}"
        )
    if model == "plumb_bob" and len(D) not in (4, 5):
        raise f.error(d_key, f"plumb_bob has 5 coefficients k1, k2, p1, p2, k3, got {len(D)}")
    if model == "rational_polynomial" and len(D) != 8:
        raise f.error(d_key, f"rational_polynomial has 8 coefficients k1, k2, p1, p2, k3..k6, got {len(D)}")
    return camera_from_matrices(f, width, height, K, D, model == "equidistant", k_key, d_key), {}


FORMAT = CalibrationFormat(
    name="ros",
    summary="ROS camera_info YAML (camera_calibration_parsers layout or a message dump; distortion_model "
    "equidistant = kannala_brandt, plumb_bob, rational_polynomial = pinhole_radtan)",
    source="github:ros-perception/image_common camera_calibration_parsers/src/parse_yml.cpp; "
    "sensor_msgs/CameraInfo.msg and distortion_models.h",
    detect=_detect,
    cameras=_cameras,
)
