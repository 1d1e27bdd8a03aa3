"""The flat camera dicts of the camera contract (``CameraModel.to_dict()``), one builder per model, so that every
reader writes the same keys in the same order (``docs/design.md``, "Fisheye camera").

All pixel quantities are in the project's convention: the centre of pixel (row i, col j) is at (u=j, v=i).

Example:
    >>> kannala_brandt(512, 512, 190.0, 190.1, 254.9, 256.8, [0.01, 0.0, 0.0, 0.0])["k4"]
    0.0
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

__all__ = [
    "division",
    "double_sphere",
    "eucm",
    "fov",
    "kannala_brandt",
    "ocam",
    "pinhole_radtan",
    "rad_tan_thin_prism_fisheye",
    "radial_poly",
    "thin_prism_fisheye",
    "unified",
]


def _base(model: str, width: int, height: int) -> dict[str, Any]:
    return {"model": model, "width": int(width), "height": int(height)}


def kannala_brandt(
    width: int, height: int, fx: float, fy: float, cx: float, cy: float, k: Sequence[float], skew: float = 0.0
) -> dict[str, Any]:
    """OpenCV fisheye / KB4: ``r(theta) = theta (1 + k1 t^2 + k2 t^4 + k3 t^6 + k4 t^8)``; ``skew`` is OpenCV's
    alpha (``u = fx (x + alpha y) + cx``)."""
    k1, k2, k3, k4 = (float(v) for v in k)
    return {
        **_base("kannala_brandt", width, height),
        "fx": float(fx),
        "fy": float(fy),
        "cx": float(cx),
        "cy": float(cy),
        "k1": k1,
        "k2": k2,
        "k3": k3,
        "k4": k4,
        "skew": float(skew),
    }


def pinhole_radtan(
    width: int,
    height: int,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    k1: float = 0.0,
    k2: float = 0.0,
    p1: float = 0.0,
    p2: float = 0.0,
    k3: float = 0.0,
) -> dict[str, Any]:
    """Pinhole with OpenCV's radial-tangential (plumb_bob) distortion, coefficients in OpenCV's order."""
    values = (fx, fy, cx, cy, k1, k2, p1, p2, k3)
    names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    return {
        **_base("pinhole_radtan", width, height),
        **{n: float(v) for n, v in zip(names, values, strict=True)},
    }


def unified(
    width: int,
    height: int,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    xi: float,
    k1: float = 0.0,
    k2: float = 0.0,
    p1: float = 0.0,
    p2: float = 0.0,
) -> dict[str, Any]:
    """Mei's unified model with radial-tangential distortion (KITTI-360 gamma1=fx, gamma2=fy, u0=cx, v0=cy)."""
    values = (fx, fy, cx, cy, xi, k1, k2, p1, p2)
    names = ("fx", "fy", "cx", "cy", "xi", "k1", "k2", "p1", "p2")
    return {**_base("unified", width, height), **{n: float(v) for n, v in zip(names, values, strict=True)}}


def double_sphere(
    width: int, height: int, fx: float, fy: float, cx: float, cy: float, xi: float, alpha: float
) -> dict[str, Any]:
    """Double Sphere (Usenko et al. 2018)."""
    values = (fx, fy, cx, cy, xi, alpha)
    names = ("fx", "fy", "cx", "cy", "xi", "alpha")
    return {
        **_base("double_sphere", width, height),
        **{n: float(v) for n, v in zip(names, values, strict=True)},
    }


def eucm(
    width: int, height: int, fx: float, fy: float, cx: float, cy: float, alpha: float, beta: float
) -> dict[str, Any]:
    """Extended Unified Camera Model (Khomutenko et al. 2016)."""
    values = (fx, fy, cx, cy, alpha, beta)
    names = ("fx", "fy", "cx", "cy", "alpha", "beta")
    return {**_base("eucm", width, height), **{n: float(v) for n, v in zip(names, values, strict=True)}}


def fov(width: int, height: int, fx: float, fy: float, cx: float, cy: float, omega: float) -> dict[str, Any]:
    """FOV / ATAN (Devernay and Faugeras 2001; COLMAP ``FOV``): ``r_d = atan(2 r tan(omega / 2)) / omega``."""
    values = (fx, fy, cx, cy, omega)
    names = ("fx", "fy", "cx", "cy", "omega")
    return {**_base("fov", width, height), **{n: float(v) for n, v in zip(names, values, strict=True)}}


def division(width: int, height: int, fx: float, fy: float, cx: float, cy: float, k: float) -> dict[str, Any]:
    """Fitzgibbon's division model (COLMAP ``DIVISION``): the pixel's normalised point ``m`` is the ray
    ``(m, 1 + k |m|^2)``."""
    values = (fx, fy, cx, cy, k)
    names = ("fx", "fy", "cx", "cy", "k")
    return {**_base("division", width, height), **{n: float(v) for n, v in zip(names, values, strict=True)}}


def thin_prism_fisheye(
    width: int, height: int, fx: float, fy: float, cx: float, cy: float, coefficients: Sequence[float]
) -> dict[str, Any]:
    """COLMAP ``THIN_PRISM_FISHEYE``: ``coefficients`` = ``k1, k2, p1, p2, k3, k4, sx1, sy1`` (COLMAP's order)."""
    names = ("k1", "k2", "p1", "p2", "k3", "k4", "sx1", "sy1")
    return {
        **_base("thin_prism_fisheye", width, height),
        **{n: float(v) for n, v in zip(("fx", "fy", "cx", "cy"), (fx, fy, cx, cy), strict=True)},
        **{n: float(v) for n, v in zip(names, coefficients, strict=True)},
    }


def rad_tan_thin_prism_fisheye(
    width: int, height: int, fx: float, fy: float, cx: float, cy: float, coefficients: Sequence[float]
) -> dict[str, Any]:
    """COLMAP ``RAD_TAN_THIN_PRISM_FISHEYE`` (Fisheye624): ``coefficients`` = ``k0..k5, p0, p1, s0..s3``."""
    names = ("k0", "k1", "k2", "k3", "k4", "k5", "p0", "p1", "s0", "s1", "s2", "s3")
    return {
        **_base("rad_tan_thin_prism_fisheye", width, height),
        **{n: float(v) for n, v in zip(("fx", "fy", "cx", "cy"), (fx, fy, cx, cy), strict=True)},
        **{n: float(v) for n, v in zip(names, coefficients, strict=True)},
    }


def ocam(
    width: int,
    height: int,
    cx: float,
    cy: float,
    c: float,
    d: float,
    e: float,
    cam2world: Sequence[float],
    world2cam: Sequence[float],
) -> dict[str, Any]:
    """Scaramuzza's OCam: ``cx`` the column and ``cy`` the row of the centre (OCamCalib's ``yc`` and ``xc``);
    ``c, d, e`` and both polynomials as OCamCalib writes them (``ss`` and ``invpol``, constant term first)."""
    return {
        **_base("ocam", width, height),
        "cx": float(cx),
        "cy": float(cy),
        "c": float(c),
        "d": float(d),
        "e": float(e),
        "cam2world": [float(v) for v in cam2world],
        "world2cam": [float(v) for v in world2cam],
    }


def radial_poly(
    width: int, height: int, k: Sequence[float], cx: float, cy: float, aspect_ratio: float
) -> dict[str, Any]:
    """WoodScape: ``rho(theta) = k1 t + k2 t^2 + k3 t^3 + k4 t^4`` pixels, ``v`` scaled by ``aspect_ratio``."""
    k1, k2, k3, k4 = (float(v) for v in k)
    return {
        **_base("radial_poly", width, height),
        "k1": k1,
        "k2": k2,
        "k3": k3,
        "k4": k4,
        "cx": float(cx),
        "cy": float(cy),
        "aspect_ratio": float(aspect_ratio),
    }
