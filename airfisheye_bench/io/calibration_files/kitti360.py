"""KITTI-360 fisheye calibrations ``calibration/image_02.yaml`` and ``image_03.yaml`` (MEI, the camodocs / OpenCV
FileStorage layout that VINS and the KITTI-360 devkit read).

Layout (github:autonomousvision/kitti360Scripts ``kitti360scripts/helpers/project.py``, ``CameraFisheye``:
``readYAMLFile`` and ``cam2image``): ``model_type: MEI``, ``camera_name``, ``image_width``, ``image_height``,
``mirror_parameters.xi``, ``distortion_parameters.{k1, k2, p1, p2}``, ``projection_parameters.{gamma1, gamma2, u0,
v0}`` -> ``unified`` with fx = gamma1, fy = gamma2, cx = u0, cy = v0. The devkit's ``cam2image`` applies k1, k2
only; Mei's model (and ``cv2.omnidir``) also applies p1, p2, and so does the ``unified`` model. Pixel convention:
the devkit rounds projected coordinates and indexes the image with them: pixel centres at integers, the project's.

Other ``model_type`` values of the camodocs family (``PINHOLE``, ``KANNALA_BRANDT``, ``SCARAMUZZA``) are refused by
name.

Example:
    >>> doc = {"model_type": "MEI", "camera_name": "image_02", "image_width": 1400, "image_height": 1400,
    ...        "mirror_parameters": {"xi": 2.2}, "distortion_parameters": {"k1": 0.01, "k2": 1.6, "p1": 0.0,
    ...        "p2": 0.0}, "projection_parameters": {"gamma1": 1336.0, "gamma2": 1335.0, "u0": 717.0, "v0": 706.0}}
    >>> camera, _ = _read(Fields("image_02.yaml", doc))
    >>> camera["model"], camera["fy"], camera["xi"]
    ('unified', 1335.0, 2.2)
"""

from __future__ import annotations

from typing import Any

from airfisheye_bench.io.calibration_files._camera_dicts import unified
from airfisheye_bench.io.calibration_files._fields import CalibrationFormat, CameraEntry, Fields

__all__ = ["FORMAT"]


def _detect(text: str, doc: Any) -> bool:
    return isinstance(doc, dict) and "model_type" in doc


def _cameras(fields: Fields) -> dict[str, CameraEntry]:
    name = fields.data.get("camera_name")
    return {str(name) if isinstance(name, str) and name else "0": _read}


def _read(f: Fields) -> tuple[dict[str, Any], dict]:
    kind = f.get("model_type")
    if kind != "MEI":
        raise f.error("model_type", f"{kind!r} is not supported; supported: MEI")
    width, height = f.whole("image_width"), f.whole("image_height")
    xi = f.number("mirror_parameters.xi")
    k1, k2, p1, p2 = (f.number(f"distortion_parameters.{n}") for n in ("k1", "k2", "p1", "p2"))
    fx = f.number("projection_parameters.gamma1", positive=True)
    fy = f.number("projection_parameters.gamma2", positive=True)
    cx, cy = f.number("projection_parameters.u0"), f.number("projection_parameters.v0")
    return unified(width, height, fx, fy, cx, cy, xi, k1, k2, p1, p2), {}


FORMAT = CalibrationFormat(
    name="kitti360",
    summary="KITTI-360 image_02.yaml / image_03.yaml (model_type: MEI: mirror_parameters.xi, distortion_parameters "
    "k1 k2 p1 p2, projection_parameters gamma1 gamma2 u0 v0)",
    source="github:autonomousvision/kitti360Scripts kitti360scripts/helpers/project.py (CameraFisheye)",
    detect=_detect,
    cameras=_cameras,
)
