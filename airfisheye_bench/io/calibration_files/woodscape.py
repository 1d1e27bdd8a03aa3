"""WoodScape calibration JSON (``calibration/*.json``): ``intrinsic`` and ``extrinsic`` of one camera.

Layout and meaning: github:valeoai/WoodScape ``scripts/calibration/projection.py`` (``read_cam_from_json``,
``Camera``, ``RadialPolyCamProjection``) and ``scripts/calibration/front.json``:

- ``intrinsic``: ``model: radial_poly``, ``k1..k4`` (``rho(theta) = k1 t + k2 t^2 + k3 t^3 + k4 t^4`` pixels),
  ``cx_offset``, ``cy_offset``, ``aspect_ratio``, ``width``, ``height`` (written as floats, ``1280.0``).
  ``Camera`` puts the principal point at ``0.5 * size + offset - 0.5`` and projects ``u = cx + rho x / chi``,
  ``v = cy + aspect_ratio rho y / chi``; its remap tables are built on pixel indices (pixel centres at integers,
  the project's convention), so ``cx = width / 2 + cx_offset - 0.5`` and ``cy = height / 2 + cy_offset - 0.5``.
- ``extrinsic``: ``quaternion`` ``(x, y, z, w)`` (read with scipy's ``Rotation.from_quat``, scalar last) and
  ``translation``: the camera's pose in the vehicle frame -> ``T_vehicle_cam`` (maps camera points to the vehicle).

The camera frame of ``projection.py`` is the project's (z forward, x to increasing u, y to increasing v).

Example:
    >>> doc = {"intrinsic": {"model": "radial_poly", "k1": 339.749, "k2": -31.988, "k3": 48.275, "k4": -7.201,
    ...        "cx_offset": 3.942, "cy_offset": -3.093, "aspect_ratio": 1.0, "width": 1280.0, "height": 966.0}}
    >>> camera, _ = _read(Fields("front.json", doc))
    >>> camera["model"], round(camera["cx"], 3), round(camera["cy"], 3), camera["width"]
    ('radial_poly', 643.442, 479.407, 1280)
"""

from __future__ import annotations

from typing import Any

import numpy as np

from airfisheye_bench.geometry.cameras import RadialPoly
from airfisheye_bench.io.calibration_files._fields import (
    CalibrationFormat,
    CameraEntry,
    Fields,
    quaternion_pose,
)

__all__ = ["FORMAT"]


def _detect(text: str, doc: Any) -> bool:
    return isinstance(doc, dict) and isinstance(doc.get("intrinsic"), dict)


def _cameras(fields: Fields) -> dict[str, CameraEntry]:
    name = fields.data.get("name")
    return {str(name) if isinstance(name, str) and name else "0": _read}


def _read(f: Fields) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    kind = f.get("intrinsic.model")
    if kind != "radial_poly":
        raise f.error("intrinsic.model", f"{kind!r} is not supported; supported: radial_poly")
    order = f.get("intrinsic.poly_order", 4)
    if order != 4:
        raise f.error("intrinsic.poly_order", f"expected 4 (k1..k4), got {order!r}")
    k = [f.number(f"intrinsic.k{i}") for i in range(1, 5)]
    width, height = f.whole("intrinsic.width"), f.whole("intrinsic.height")
    cx = width / 2 + f.number("intrinsic.cx_offset") - 0.5
    cy = height / 2 + f.number("intrinsic.cy_offset") - 0.5
    aspect = f.number("intrinsic.aspect_ratio", positive=True)
    extrinsics = {}
    if "extrinsic" in f.data:
        q = f.numbers("extrinsic.quaternion", 4)
        t = f.numbers("extrinsic.translation", 3)
        if not np.linalg.norm(q) > 0:
            raise f.error("extrinsic.quaternion", "expected a non-zero quaternion (x, y, z, w)")
        extrinsics["T_vehicle_cam"] = quaternion_pose(q, t)
    return RadialPoly.flat_dict(width, height, *k, cx=cx, cy=cy, aspect_ratio=aspect), extrinsics


FORMAT = CalibrationFormat(
    name="woodscape",
    summary="WoodScape calibration JSON (intrinsic.model radial_poly: k1..k4, cx_offset, cy_offset, aspect_ratio; "
    "extrinsic quaternion + translation)",
    source="github:valeoai/WoodScape scripts/calibration/projection.py (read_cam_from_json, Camera)",
    detect=_detect,
    cameras=_cameras,
)
