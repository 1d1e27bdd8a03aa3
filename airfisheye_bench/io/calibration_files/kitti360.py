"""camodocal's camera YAML (OpenCV FileStorage), as KITTI-360's fisheye calibrations ``calibration/image_02.yaml`` and
``image_03.yaml`` (MEI) and VINS-Fusion's configurations (MEI, KANNALA_BRANDT, PINHOLE) write it.

Layout (github:autonomousvision/kitti360Scripts ``kitti360scripts/helpers/project.py``, ``CameraFisheye``:
``readYAMLFile`` and ``cam2image``): ``model_type: MEI``, ``camera_name``, ``image_width``, ``image_height``,
``mirror_parameters.xi``, ``distortion_parameters.{k1, k2, p1, p2}``, ``projection_parameters.{gamma1, gamma2, u0,
v0}`` -> ``unified`` with fx = gamma1, fy = gamma2, cx = u0, cy = v0. The devkit's ``cam2image`` applies k1, k2
only; Mei's model (and ``cv2.omnidir``) also applies p1, p2, and so does the ``unified`` model. Pixel convention:
the devkit rounds projected coordinates and indexes the image with them: pixel centres at integers, the project's.

``model_type: KANNALA_BRANDT`` (github:hengli/camodocal ``src/camera_models/EquidistantCamera.cc``,
``readFromYamlFile`` and ``spaceToPlane``; ``r()`` in ``EquidistantCamera.h``): ``projection_parameters.{k2, k3, k4,
k5, mu, mv, u0, v0}``, ``theta_d = theta + k2 theta^3 + k3 theta^5 + k4 theta^7 + k5 theta^9``, ``u = mu theta_d
cos(phi) + u0``, ``v = mv theta_d sin(phi) + v0``: ``kannala_brandt`` with k1..k4 = k2..k5 (camodocal's k1 is the
fixed 1), fx = mu, fy = mv, cx = u0, cy = v0. ``model_type: PINHOLE`` (``PinholeCamera.cc``):
``distortion_parameters.{k1, k2, p1, p2}``, ``projection_parameters.{fx, fy, cx, cy}``: ``pinhole_radtan``. camodocal
works on OpenCV images (pixel centres at integers), as the project does. ``SCARAMUZZA`` is refused by name.

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

from airfisheye_bench.geometry.cameras import KannalaBrandt, PinholeRadtan, Unified
from airfisheye_bench.io.calibration_files._fields import CalibrationFormat, CameraEntry, Fields

__all__ = ["FORMAT", "MODEL_TYPES"]

#: The ``model_type`` values read (camodocal's own spelling; its CameraFactory also takes them in any case).
MODEL_TYPES = ("MEI", "KANNALA_BRANDT", "PINHOLE")


def _detect(text: str, doc: Any) -> bool:
    return isinstance(doc, dict) and "model_type" in doc


def _cameras(fields: Fields) -> dict[str, CameraEntry]:
    name = fields.data.get("camera_name")
    return {str(name) if isinstance(name, str) and name else "0": _read}


def _read(f: Fields) -> tuple[dict[str, Any], dict]:
    kind = f.get("model_type")
    if kind not in MODEL_TYPES:
        raise f.error("model_type", f"{kind!r} is not supported; supported: {', '.join(MODEL_TYPES)}")
    width, height = f.whole("image_width"), f.whole("image_height")
    if kind == "KANNALA_BRANDT":
        misplaced = f.get("distortion_parameters.k2", None)
        if misplaced is not None and f.get("projection_parameters.k2", None) is None:
            # Some converters write k2..k5 there; camodocal would read 0 for each and so ignore the distortion.
            raise f.error(
                "distortion_parameters.k2",
                "camodocal reads KANNALA_BRANDT's k2..k5 from projection_parameters; move them there",
            )
        p = {n: f.number(f"projection_parameters.{n}") for n in ("k2", "k3", "k4", "k5", "u0", "v0")}
        fx = f.number("projection_parameters.mu", positive=True)
        fy = f.number("projection_parameters.mv", positive=True)
        k = [
            p["k2"],
            p["k3"],
            p["k4"],
            p["k5"],
        ]  # camodocal's k1 is the fixed 1 of theta: its k2..k5 are k1..k4
        return KannalaBrandt.flat_dict(width, height, fx, fy, p["u0"], p["v0"], *k), {}
    if kind == "PINHOLE":
        k1, k2, p1, p2 = (f.number(f"distortion_parameters.{n}") for n in ("k1", "k2", "p1", "p2"))
        fx = f.number("projection_parameters.fx", positive=True)
        fy = f.number("projection_parameters.fy", positive=True)
        cx, cy = f.number("projection_parameters.cx"), f.number("projection_parameters.cy")
        return PinholeRadtan.flat_dict(width, height, fx, fy, cx, cy, k1, k2, p1, p2), {}
    xi = f.number("mirror_parameters.xi")
    k1, k2, p1, p2 = (f.number(f"distortion_parameters.{n}") for n in ("k1", "k2", "p1", "p2"))
    fx = f.number("projection_parameters.gamma1", positive=True)
    fy = f.number("projection_parameters.gamma2", positive=True)
    cx, cy = f.number("projection_parameters.u0"), f.number("projection_parameters.v0")
    return Unified.flat_dict(width, height, fx, fy, cx, cy, xi, k1, k2, p1, p2), {}


FORMAT = CalibrationFormat(
    name="kitti360",
    summary="camodocal YAML: KITTI-360 image_02.yaml / image_03.yaml, VINS-Fusion (model_type: MEI = unified, "
    "KANNALA_BRANDT = kannala_brandt, PINHOLE = pinhole_radtan)",
    source="github:autonomousvision/kitti360Scripts kitti360scripts/helpers/project.py (CameraFisheye); "
    "github:hengli/camodocal src/camera_models/EquidistantCamera.cc, PinholeCamera.cc",
    detect=_detect,
    cameras=_cameras,
)
