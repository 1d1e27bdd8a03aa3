"""basalt's calibration JSON (cereal): ``value0.intrinsics[i]`` = ``{camera_type, intrinsics: {...}}``,
``value0.resolution[i]`` = ``[width, height]``, ``value0.T_imu_cam[i]`` = ``{px, py, pz, qx, qy, qz, qw}`` (read as ``T_imu_cam`` and its inverse ``T_cam_imu``).

Layout and names: github:VladyslavUsenko/basalt-headers ``include/basalt/serialization/headers_serialization.h``
(the cereal ``save``/``load`` of each camera) and ``include/basalt/camera/*.hpp`` (``getName()``):

=============  ===================================  ==============================================================
camera_type    intrinsics                           model here
=============  ===================================  ==============================================================
ds             fx, fy, cx, cy, xi, alpha            double_sphere
eucm           fx, fy, cx, cy, alpha, beta          eucm
kb4            fx, fy, cx, cy, k1, k2, k3, k4       kannala_brandt
ucm            fx, fy, cx, cy, alpha                unified: xi = alpha / (1 - alpha), fx, fy / (1 - alpha)
pinhole        fx, fy, cx, cy                       pinhole_radtan without distortion
=============  ===================================  ==============================================================

basalt's UCM divides by ``alpha d + (1 - alpha) z`` (``unified_camera.hpp``), which is Mei's ``z + xi d`` times
``1 - alpha``: hence the conversion. ``fov`` and ``bal`` are not supported. Cameras are named by their index
(``"0"``, ``"1"``). Pixel convention: OpenCV's, the project's. Evidence: the same TUM-VI camera calibrated by
basalt (ds, eucm) and by Kalibr (pinhole-equi, OpenCV's convention) has principal points within 0.03 px of each
other (cam0: cx 254.96 / 254.93, cy 256.89 / 256.90), where a half-pixel convention would differ by 0.5.

Example:
    >>> doc = {"value0": {"intrinsics": [{"camera_type": "ucm", "intrinsics": {
    ...     "fx": 100.0, "fy": 100.0, "cx": 255.5, "cy": 255.5, "alpha": 0.5}}], "resolution": [[512, 512]]}}
    >>> camera, _ = _read(Fields("calib.json", doc), 0)
    >>> camera["model"], camera["xi"], camera["fx"]
    ('unified', 1.0, 200.0)
"""

from __future__ import annotations

from functools import partial
from typing import Any

import numpy as np

from airfisheye_bench.geometry.cameras import EUCM, DoubleSphere, KannalaBrandt, PinholeRadtan, Unified
from airfisheye_bench.io.calibration_files._fields import (
    CalibrationFormat,
    CameraEntry,
    Fields,
    quaternion_pose,
    rigid_both_ways,
)

__all__ = ["FORMAT", "PARAMETERS"]

#: basalt camera_type -> its intrinsics' names, in cereal's order.
PARAMETERS = {
    "ds": ("fx", "fy", "cx", "cy", "xi", "alpha"),
    "eucm": ("fx", "fy", "cx", "cy", "alpha", "beta"),
    "kb4": ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4"),
    "ucm": ("fx", "fy", "cx", "cy", "alpha"),
    "pinhole": ("fx", "fy", "cx", "cy"),
}


def _detect(text: str, doc: Any) -> bool:
    return isinstance(doc, dict) and isinstance(doc.get("value0"), dict) and "intrinsics" in doc["value0"]


def _cameras(fields: Fields) -> dict[str, CameraEntry]:
    return {str(i): partial(_read, index=i) for i in range(len(fields.seq("value0.intrinsics")))}


def _read(f: Fields, index: int) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    key = f"value0.intrinsics[{index}]"
    kind = f.str(f"{key}.camera_type")
    if kind not in PARAMETERS:
        raise f.error(f"{key}.camera_type", f"{kind!r} is not supported; supported: {', '.join(PARAMETERS)}")
    p = {name: f.number(f"{key}.intrinsics.{name}") for name in PARAMETERS[kind]}
    width, height = f.size(f"value0.resolution[{index}]")
    if kind == "ds":
        camera = DoubleSphere.flat_dict(width, height, **p)
    elif kind == "eucm":
        camera = EUCM.flat_dict(width, height, **p)
    elif kind == "kb4":
        camera = KannalaBrandt.flat_dict(width, height, **p)
    elif kind == "ucm":
        alpha = p["alpha"]
        if not 0 <= alpha < 1:
            raise f.error(
                f"{key}.intrinsics.alpha", f"expected 0 <= alpha < 1 for the unified model, got {alpha}"
            )
        # basalt's UCM is the unified model without distortion, in another parametrisation.
        fx, fy = p["fx"] / (1 - alpha), p["fy"] / (1 - alpha)
        camera = Unified.flat_dict(width, height, fx, fy, p["cx"], p["cy"], xi=alpha / (1 - alpha))
    else:
        camera = PinholeRadtan.flat_dict(width, height, **p)
    extrinsics = {}
    pose = f.get(f"value0.T_imu_cam[{index}]", None)
    if pose is not None:
        pkey = f"value0.T_imu_cam[{index}]"
        q = [f.number(f"{pkey}.{n}") for n in ("qx", "qy", "qz", "qw")]
        t = [f.number(f"{pkey}.{n}") for n in ("px", "py", "pz")]
        extrinsics = rigid_both_ways(f, pkey, quaternion_pose(q, t), "imu", "cam")
    return camera, extrinsics


FORMAT = CalibrationFormat(
    name="basalt",
    summary="basalt calibration JSON (value0.intrinsics[i].camera_type ds | eucm | kb4 | ucm | pinhole, "
    "value0.resolution)",
    source="github:VladyslavUsenko/basalt-headers include/basalt/serialization/headers_serialization.h and "
    "include/basalt/camera/",
    detect=_detect,
    cameras=_cameras,
)
