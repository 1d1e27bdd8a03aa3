"""COLMAP ``cameras.txt``: one line per camera, ``CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]``, ``#`` comments.

Models and parameter orders: github:colmap/colmap ``src/colmap/sensor/models.h`` (``InitializeParamsInfo`` of each
model); the text layout: COLMAP's documentation, "Output format". COLMAP's image origin is the upper-left image
*corner*: the centre of the upper-left pixel is (0.5, 0.5) (documentation, "Frequently asked questions"), so the
principal point moves by half a pixel: ``cx = cx_colmap - 0.5``, ``cy = cy_colmap - 0.5``.

==========================  ==========================================  =========================================
COLMAP model                parameters                                  model here
==========================  ==========================================  =========================================
SIMPLE_PINHOLE              f, cx, cy                                   pinhole_radtan
PINHOLE                     fx, fy, cx, cy                              pinhole_radtan
SIMPLE_RADIAL               f, cx, cy, k                                pinhole_radtan (k1 = k)
RADIAL                      f, cx, cy, k1, k2                           pinhole_radtan
OPENCV                      fx, fy, cx, cy, k1, k2, p1, p2              pinhole_radtan
FULL_OPENCV                 fx, fy, cx, cy, k1, k2, p1, p2, k3..k6      pinhole_radtan (k4..k6: the rational model)
OPENCV_FISHEYE              fx, fy, cx, cy, k1, k2, k3, k4              kannala_brandt
SIMPLE_RADIAL_FISHEYE       f, cx, cy, k                                kannala_brandt (k1 = k)
RADIAL_FISHEYE              f, cx, cy, k1, k2                           kannala_brandt (k1, k2)
SIMPLE_FISHEYE, FISHEYE     f, cx, cy / fx, fy, cx, cy                  kannala_brandt (k = 0: equidistant)
THIN_PRISM_FISHEYE          fx, fy, cx, cy, k1, k2, p1, p2, k3, k4,     thin_prism_fisheye (kannala_brandt when
                            sx1, sy1                                    p1, p2, sx1, sy1 are 0)
RAD_TAN_THIN_PRISM_FISHEYE  fx, fy, cx, cy, k0..k5, p0, p1, s0..s3      rad_tan_thin_prism_fisheye (kannala_brandt,
                                                                        k1..k4 = k0..k3, when k4, k5, p0, p1,
                                                                        s0..s3 are 0)
SIMPLE_DIVISION, DIVISION   f, cx, cy, k / fx, fy, cx, cy, k            division
FOV                         fx, fy, cx, cy, omega                       fov (omega = 0: pinhole_radtan)
EUCM                        fx, fy, cx, cy, alpha, beta                 eucm
==========================  ==========================================  =========================================

COLMAP's fisheye models all distort ``theta = atan(r)`` (``FisheyeFromNormal``): ``RADIAL_FISHEYE`` into ``theta (1
+ k1 theta^2 + k2 theta^4)``, ``THIN_PRISM_FISHEYE`` adds tangential and thin-prism terms to that, and
``RAD_TAN_THIN_PRISM_FISHEYE`` a radial polynomial to theta^13 and then such terms: without those extra terms each
is the Kannala-Brandt polynomial, and is read as ``kannala_brandt``; with them as its own model
(``geometry/cameras/thin_prism.py``). ``FOV``'s map is even in omega (``|omega|`` is read). ``EQUIRECTANGULAR``, a
360 x 180 deg panorama described by its size alone, is no lens: refused. Cameras are named by their ``CAMERA_ID``.

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

from airfisheye_bench.geometry.cameras import (
    EUCM,
    Division,
    Fov,
    KannalaBrandt,
    PinholeRadtan,
    RadTanThinPrismFisheye,
    ThinPrismFisheye,
)
from airfisheye_bench.io.calibration_files._fields import CalibrationFormat, CameraEntry, Fields

__all__ = ["FORMAT", "PARAMETERS", "REFUSED"]

#: COLMAP model -> its parameter names (models.h ``InitializeParamsInfo`` order), for the models read.
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
    "SIMPLE_FISHEYE": ("f", "cx", "cy"),
    "FISHEYE": ("fx", "fy", "cx", "cy"),
    "THIN_PRISM_FISHEYE": ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "sx1", "sy1"),
    "RAD_TAN_THIN_PRISM_FISHEYE": (
        "fx", "fy", "cx", "cy", "k0", "k1", "k2", "k3", "k4", "k5", "p0", "p1", "s0", "s1", "s2", "s3",
    ),
    "SIMPLE_DIVISION": ("f", "cx", "cy", "k"),
    "DIVISION": ("fx", "fy", "cx", "cy", "k"),
    "FOV": ("fx", "fy", "cx", "cy", "omega"),
    "EUCM": ("fx", "fy", "cx", "cy", "alpha", "beta"),
}  # fmt: skip
#: COLMAP's models that have no model here, and why.
REFUSED = {
    "EQUIRECTANGULAR": "is a 360 x 180 deg panorama (COLMAP's spherical model, no focal length), not a lens: "
    "no fisheye image is served through it",
}
#: Kannala-Brandt models -> (names of the polynomial's k1..k4, terms beyond it: with any of them non-zero the model
#: is its own, ``_OWN_MODEL``'s, whose parameters are COLMAP's in COLMAP's order).
_KB_FAMILY = {
    "OPENCV_FISHEYE": (("k1", "k2", "k3", "k4"), ()),
    "SIMPLE_RADIAL_FISHEYE": (("k",), ()),
    "RADIAL_FISHEYE": (("k1", "k2"), ()),
    "SIMPLE_FISHEYE": ((), ()),
    "FISHEYE": ((), ()),
    "THIN_PRISM_FISHEYE": (("k1", "k2", "k3", "k4"), ("p1", "p2", "sx1", "sy1")),
    "RAD_TAN_THIN_PRISM_FISHEYE": (
        ("k0", "k1", "k2", "k3"),
        ("k4", "k5", "p0", "p1", "s0", "s1", "s2", "s3"),
    ),
}
_OWN_MODEL = {
    "THIN_PRISM_FISHEYE": ThinPrismFisheye,
    "RAD_TAN_THIN_PRISM_FISHEYE": RadTanThinPrismFisheye,
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
    if model in REFUSED:
        raise f.error(f"{camera_id}.model", f"{model} {REFUSED[model]}")
    if model not in PARAMETERS:
        raise f.error(
            f"{camera_id}.model",
            f"{model} is not a COLMAP camera model; supported: every model of COLMAP's models.h but "
            f"{', '.join(REFUSED)}",
        )
    names = PARAMETERS[model]
    values = f.numbers(f"{camera_id}.params", len(names))
    p = dict(zip(names, values, strict=True))
    if "f" in p:
        p["fx"] = p["fy"] = p["f"]
    width, height = f.whole(f"{camera_id}.width"), f.whole(f"{camera_id}.height")
    # COLMAP's pixel centres are at half-integers (the image corner is the origin); ours at integers.
    fx, fy, cx, cy = p["fx"], p["fy"], p["cx"] - 0.5, p["cy"] - 0.5
    if model in _KB_FAMILY:
        k_names, beyond = _KB_FAMILY[model]
        if any(p[name] != 0 for name in beyond):
            return _OWN_MODEL[model].flat_dict(width, height, fx, fy, cx, cy, *values[4:]), {}
        k = [p[name] for name in k_names]  # k1, k2, ... in order; the rest default to 0
        return KannalaBrandt.flat_dict(width, height, fx, fy, cx, cy, *k), {}
    if model in ("SIMPLE_DIVISION", "DIVISION"):
        return Division.flat_dict(width, height, fx, fy, cx, cy, k=p["k"]), {}
    if model == "FOV":
        if p["omega"] == 0:  # COLMAP's limit: the undistorted pinhole
            return PinholeRadtan.flat_dict(width, height, fx, fy, cx, cy), {}
        return Fov.flat_dict(width, height, fx, fy, cx, cy, omega=abs(p["omega"])), {}
    if model == "EUCM":
        return EUCM.flat_dict(width, height, fx, fy, cx, cy, alpha=p["alpha"], beta=p["beta"]), {}
    k1 = p.get("k1", p.get("k", 0.0))
    radtan = {name: p[name] for name in ("k2", "p1", "p2", "k3", "k4", "k5", "k6") if name in p}
    return PinholeRadtan.flat_dict(width, height, fx, fy, cx, cy, k1=k1, **radtan), {}


FORMAT = CalibrationFormat(
    name="colmap",
    summary="COLMAP cameras.txt (every model of models.h but EQUIRECTANGULAR; principal point moved by -0.5 px)",
    source="github:colmap/colmap src/colmap/sensor/models.h; COLMAP documentation (Output format; FAQ: the centre "
    "of the upper-left pixel is (0.5, 0.5))",
    detect=_detect,
    cameras=_cameras,
    document=_document,
)
