"""COLMAP ``cameras.txt``: one line per camera, ``CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]``, ``#`` comments.

Models and parameter orders: github:colmap/colmap ``src/colmap/sensor/models.h`` (``InitializeParamsInfo`` of each
model); the text layout: COLMAP's documentation, "Output format". COLMAP's image origin is the upper-left image
*corner*: the centre of the upper-left pixel is (0.5, 0.5) (documentation, "Frequently asked questions"), so the
principal point moves by half a pixel: ``cx = cx_colmap - 0.5``, ``cy = cy_colmap - 0.5``.

=========================  =====================================  =========================================
COLMAP model               parameters                             model here
=========================  =====================================  =========================================
SIMPLE_PINHOLE             f, cx, cy                              pinhole_radtan
PINHOLE                    fx, fy, cx, cy                         pinhole_radtan
SIMPLE_RADIAL              f, cx, cy, k                           pinhole_radtan (k1 = k)
RADIAL                     f, cx, cy, k1, k2                      pinhole_radtan
OPENCV                     fx, fy, cx, cy, k1, k2, p1, p2         pinhole_radtan
FULL_OPENCV                fx, fy, cx, cy, k1, k2, p1, p2,        pinhole_radtan (k4..k6 must be 0)
                           k3, k4, k5, k6
OPENCV_FISHEYE             fx, fy, cx, cy, k1, k2, k3, k4         kannala_brandt
SIMPLE_RADIAL_FISHEYE      f, cx, cy, k                           kannala_brandt (k1 = k)
RADIAL_FISHEYE             f, cx, cy, k1, k2                      kannala_brandt (k1, k2)
=========================  =====================================  =========================================

COLMAP's ``RADIAL_FISHEYE`` distorts ``theta = atan(r)`` into ``theta (1 + k1 theta^2 + k2 theta^4)``: the
Kannala-Brandt polynomial. ``FOV``, ``THIN_PRISM_FISHEYE``, ``RAD_TAN_THIN_PRISM_FISHEYE`` and the division
models are not supported. Cameras are named by their ``CAMERA_ID``.

Example:
    >>> doc = _document("# Camera list\\n1 OPENCV_FISHEYE 1280 960 400 401 640 480 0.1 0.01 0 0\\n", None)
    >>> camera, _ = _cameras(Fields("cameras.txt", doc))["1"](Fields("cameras.txt", doc))
    >>> camera["model"], camera["cx"], camera["cy"]
    ('kannala_brandt', 639.5, 479.5)
"""

from __future__ import annotations

import re
from functools import partial
from typing import Any

from airfisheye_bench.io.calibration_files._camera_dicts import kannala_brandt, pinhole_radtan
from airfisheye_bench.io.calibration_files._fields import CalibrationFormat, CameraEntry, Fields

__all__ = ["FORMAT", "PARAMETERS"]

#: COLMAP model -> its parameter names (models.h order).
PARAMETERS = {
    "SIMPLE_PINHOLE": ("f", "cx", "cy"),
    "PINHOLE": ("fx", "fy", "cx", "cy"),
    "SIMPLE_RADIAL": ("f", "cx", "cy", "k"),
    "RADIAL": ("f", "cx", "cy", "k1", "k2"),
    "OPENCV": ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2"),
    "FULL_OPENCV": ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
    "OPENCV_FISHEYE": ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4"),
    "SIMPLE_RADIAL_FISHEYE": ("f", "cx", "cy", "k"),
    "RADIAL_FISHEYE": ("f", "cx", "cy", "k1", "k2"),
}
_LINE = re.compile(r"^\s*(\d+)\s+([A-Z][A-Z0-9_]*)\s+(\d+)\s+(\d+)((?:\s+\S+)*)\s*$")


def _data_lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]


def _detect(text: str, doc: Any) -> bool:
    lines = _data_lines(text)
    return bool(lines) and all(_LINE.match(line) for line in lines)


def _document(text: str, doc: Any) -> dict[str, Any]:
    """``{camera_id: {"model", "width", "height", "params"}}``; a parameter that is no number stays a string."""
    out: dict[str, Any] = {}
    for line in _data_lines(text):
        camera_id, model, width, height, rest = _LINE.match(line).groups()
        params: list[Any] = []
        for token in rest.split():
            try:
                params.append(float(token))
            except ValueError:
                params.append(token)
        out[camera_id] = {"model": model, "width": int(width), "height": int(height), "params": params}
    return out


def _cameras(fields: Fields) -> dict[str, CameraEntry]:
    return {camera_id: partial(_read, camera_id=camera_id) for camera_id in fields.data}


def _read(f: Fields, camera_id: str) -> tuple[dict[str, Any], dict]:
    model = f.str(f"{camera_id}.model")
    if model not in PARAMETERS:
        raise f.error(f"{camera_id}.model", f"{model} is not supported; supported: {', '.join(PARAMETERS)}")
    names = PARAMETERS[model]
    values = f.numbers(f"{camera_id}.params", len(names))
    p = dict(zip(names, values, strict=True))
    if "f" in p:
        p["fx"] = p["fy"] = p["f"]
    width, height = f.whole(f"{camera_id}.width"), f.whole(f"{camera_id}.height")
    # COLMAP's pixel centres are at half-integers (the image corner is the origin); ours at integers.
    fx, fy, cx, cy = p["fx"], p["fy"], p["cx"] - 0.5, p["cy"] - 0.5
    if model in ("OPENCV_FISHEYE", "SIMPLE_RADIAL_FISHEYE", "RADIAL_FISHEYE"):
        k = [p.get("k1", p.get("k", 0.0)), p.get("k2", 0.0), p.get("k3", 0.0), p.get("k4", 0.0)]
        return kannala_brandt(width, height, fx, fy, cx, cy, k), {}
    rational = [p.get(name, 0.0) for name in ("k4", "k5", "k6")]
    if any(rational):
        raise f.error(
            f"{camera_id}.params",
            "FULL_OPENCV with non-zero k4, k5, k6 (the rational model) is not supported; supported: k1, k2, p1, p2, k3",
        )
    k1 = p.get("k1", p.get("k", 0.0))
    return pinhole_radtan(
        width,
        height,
        fx,
        fy,
        cx,
        cy,
        k1,
        p.get("k2", 0.0),
        p.get("p1", 0.0),
        p.get("p2", 0.0),
        p.get("k3", 0.0),
    ), {}


FORMAT = CalibrationFormat(
    name="colmap",
    summary="COLMAP cameras.txt (OPENCV_FISHEYE, RADIAL_FISHEYE, SIMPLE_RADIAL_FISHEYE, OPENCV, FULL_OPENCV, "
    "PINHOLE, SIMPLE_PINHOLE, SIMPLE_RADIAL, RADIAL; principal point moved by -0.5 px)",
    source="github:colmap/colmap src/colmap/sensor/models.h; COLMAP documentation (Output format; FAQ: the centre "
    "of the upper-left pixel is (0.5, 0.5))",
    detect=_detect,
    cameras=_cameras,
    document=_document,
)
