"""Kalibr ``camchain.yaml`` (and ``camchain-imucam.yaml``): one block per camera, ``cam0``, ``cam1``, ...

Each block (github:ethz-asl/kalibr ``aslam_offline_calibration/kalibr/python/kalibr_common/ConfigReader.py``,
``AslamCamera`` and ``CameraParameters``; the wiki's "Supported models"): ``camera_model``, ``intrinsics``,
``distortion_model``, ``distortion_coeffs``, ``resolution`` ``[width, height]``, and optionally ``T_cam_imu``
and ``T_cn_cnm1`` (4x4). Chains that other tools write store ``T_imu_cam`` / ``T_cnm1_cn`` instead: either direction
is read and the record holds both (the other inverted), logging which key was read; any other ``T_*`` key is named
in a warning rather than dropped silently.

==============  =========================================  ==================  =================================
camera_model    intrinsics                                 distortion_model    model here
==============  =========================================  ==================  =================================
pinhole         fu, fv, pu, pv                             equidistant         kannala_brandt (k1..k4)
pinhole         fu, fv, pu, pv                             radtan / none       pinhole_radtan (k1, k2, r1, r2)
omni            xi, fu, fv, pu, pv                         radtan / none       unified (k1, k2, p1, p2)
ds              xi, alpha, fu, fv, pu, pv                  none                double_sphere
eucm            alpha, beta, fu, fv, pu, pv                none                eucm
==============  =========================================  ==================  =================================

Kalibr itself refuses every other pair (``omni`` + ``equidistant`` raises "not yet supported"); ``fov``
distortion is not a model here. Pixel convention: OpenCV's, the project's: nothing to convert (Kalibr's
checkerboard corners come from OpenCV's ``findChessboardCorners`` / ``cornerSubPix`` on pixel indices,
``aslam_cv/aslam_cameras/src/GridCalibrationTargetCheckerboard.cpp``, and its projections are valid on
``[0, W) x [0, H)``, ``PinholeProjection::isValid``).

Example:
    >>> doc = {"cam0": {"camera_model": "ds", "intrinsics": [-0.17, 0.59, 158.3, 158.3, 254.9, 256.9],
    ...                 "distortion_model": "none", "distortion_coeffs": [], "resolution": [512, 512]}}
    >>> camera, _ = _cameras(Fields("camchain.yaml", doc))["cam0"](Fields("camchain.yaml", doc))
    >>> camera["model"], camera["xi"], camera["cx"]
    ('double_sphere', -0.17, 254.9)
"""

from __future__ import annotations

import logging
from functools import partial
from typing import Any

import numpy as np

from airfisheye_bench.geometry.cameras import EUCM, DoubleSphere, KannalaBrandt, PinholeRadtan, Unified
from airfisheye_bench.io.calibration_files._fields import (
    CalibrationFormat,
    CameraEntry,
    Fields,
    rigid_both_ways,
)

__all__ = ["EXTRINSICS", "FORMAT", "SUPPORTED"]

log = logging.getLogger(__name__)

#: (camera_model, distortion_model) pairs this reader takes.
SUPPORTED = (
    ("pinhole", "equidistant"),
    ("pinhole", "radtan"),
    ("pinhole", "none"),
    ("omni", "radtan"),
    ("omni", "none"),
    ("ds", "none"),
    ("eucm", "none"),
)
#: Extrinsics keys read, either direction (Kalibr writes T_cam_imu and T_cn_cnm1; other tools' chains the inverses).
EXTRINSICS = {
    "T_cam_imu": ("cam", "imu"),
    "T_imu_cam": ("imu", "cam"),
    "T_cn_cnm1": ("cn", "cnm1"),
    "T_cnm1_cn": ("cnm1", "cn"),
}
_INTRINSICS = {"pinhole": 4, "omni": 5, "ds": 6, "eucm": 6}
_COEFFICIENTS = {"equidistant": 4, "radtan": 4, "none": 0}


def _is_camera(block: Any) -> bool:
    return isinstance(block, dict) and "camera_model" in block and "intrinsics" in block


def _detect(text: str, doc: Any) -> bool:
    return isinstance(doc, dict) and (_is_camera(doc) or any(_is_camera(v) for v in doc.values()))


def _cameras(fields: Fields) -> dict[str, CameraEntry]:
    if _is_camera(fields.data):  # a single camera's block (Kalibr's camera.yaml) rather than a chain
        return {"cam0": partial(_read, prefix="")}
    return {
        str(name): partial(_read, prefix=f"{name}.")
        for name, block in fields.data.items()
        if _is_camera(block)
    }


def _read(f: Fields, prefix: str) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    model = f.str(prefix + "camera_model")
    distortion = f.str(prefix + "distortion_model", "none")
    if (model, distortion) not in SUPPORTED:
        pairs = ", ".join(f"{m}-{d}" for m, d in SUPPORTED)
        key = prefix + ("camera_model" if model not in _INTRINSICS else "distortion_model")
        raise f.error(
            key, f"{model}-{distortion} is not supported; supported (camera_model-distortion_model): {pairs}"
        )
    values = f.numbers(prefix + "intrinsics", _INTRINSICS[model])
    coefficients = (
        f.numbers(prefix + "distortion_coeffs", _COEFFICIENTS[distortion]) if distortion != "none" else []
    )
    if distortion == "none":
        extra = f.get(prefix + "distortion_coeffs", [])
        if any(v != 0 for v in f.check_numbers(prefix + "distortion_coeffs", extra)):
            raise f.error(
                prefix + "distortion_coeffs", "distortion_model none takes no (non-zero) coefficients"
            )
    width, height = f.size(prefix + "resolution")
    if model == "pinhole":
        fx, fy, cx, cy = values
        # Kalibr's coefficients are in the models' own order: k1..k4 (equidistant), k1, k2, p1, p2 (radtan).
        lens = KannalaBrandt if distortion == "equidistant" else PinholeRadtan
        camera = lens.flat_dict(width, height, fx, fy, cx, cy, *coefficients)
    elif model == "omni":
        xi, fx, fy, cx, cy = values
        camera = Unified.flat_dict(width, height, fx, fy, cx, cy, xi, *coefficients)
    elif model == "ds":
        xi, alpha, fx, fy, cx, cy = values
        camera = DoubleSphere.flat_dict(width, height, fx, fy, cx, cy, xi=xi, alpha=alpha)
    else:
        alpha, beta, fx, fy, cx, cy = values
        camera = EUCM.flat_dict(width, height, fx, fy, cx, cy, alpha=alpha, beta=beta)
    return camera, _extrinsics(f, prefix)


def _extrinsics(f: Fields, prefix: str) -> dict[str, np.ndarray]:
    """The block's transforms in both directions, whichever the file stores; an unknown ``T_*`` key is warned about,
    never dropped silently; both directions stored must agree."""
    block = f.get(prefix[:-1]) if prefix else f.data
    out: dict[str, np.ndarray] = {}
    for key in (k for k in block if isinstance(k, str) and k.startswith("T_")):
        if key not in EXTRINSICS:
            log.warning(
                "%s: key %r is not read (extrinsics read: %s)", f.path, prefix + key, ", ".join(EXTRINSICS)
            )
            continue
        read = rigid_both_ways(f, prefix + key, f.matrix(prefix + key, (4, 4)), *EXTRINSICS[key])
        for name, T in read.items():
            if name in out and not np.allclose(out[name], T, atol=1e-6):
                raise f.error(
                    prefix + key, f"disagrees with the inverse of the block's other direction ({name})"
                )
            out.setdefault(name, T)
    return out


FORMAT = CalibrationFormat(
    name="kalibr",
    summary="Kalibr camchain.yaml (cam0, cam1, ...: camera_model pinhole | omni | ds | eucm x distortion_model "
    "equidistant | radtan | none)",
    source="github:ethz-asl/kalibr aslam_offline_calibration/kalibr/python/kalibr_common/ConfigReader.py "
    "(AslamCamera) and the wiki's supported models",
    detect=_detect,
    cameras=_cameras,
)
