"""Random calibrations of every camera family (seeded), over each family's realistic range: polynomials that turn back
or blow up inside or beyond the image, mirrors past the sphere's rim, distortions that fold. The exact-unprojection
property (``tests/geometry/test_unproject_exact.py``) is checked on them, and the deployment tests carry one of each
through the ONNX metadata (``tests/export/test_deploy.py``)."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable

import numpy as np

from airfisheye_bench.geometry.cameras import CameraModel, camera_from_dict

#: Random calibrations per family.
PER_FAMILY = 30


# ---------------------------------------------------------------------------------------------- random calibrations
def _frame(rng: np.random.Generator) -> dict:
    """A small image (the lens scales with it) with its principal point near the centre; its dense grid stays
    below torch's grain size (32768), whose larger tensors are split over threads."""
    w = int(rng.choice([48, 64, 80]))
    h = int(w * rng.choice([1.0, 0.75]))
    return {
        "width": w,
        "height": h,
        "cx": (w - 1) / 2 + rng.uniform(-0.05, 0.05) * w,
        "cy": (h - 1) / 2 + rng.uniform(-0.05, 0.05) * h,
    }


def _focal(rng: np.random.Generator, frame: dict, lo: float, hi: float) -> dict:
    fx = rng.uniform(lo, hi) * frame["width"]
    return {"fx": fx, "fy": fx * rng.uniform(0.98, 1.02)}


def _ideal(model: str, max_fov: float) -> Callable[[np.random.Generator], dict]:
    def draw(rng: np.random.Generator) -> dict:
        d = {"model": model, **_frame(rng), "fov_deg": rng.uniform(60.0, max_fov)}
        if rng.random() < 0.5:  # else the default focal, which inscribes the image circle
            d["focal"] = rng.uniform(0.15, 0.5) * d["width"]
        return d

    return draw


def _kannala_brandt(rng: np.random.Generator) -> dict:
    # OpenCV fisheye / Kalibr pinhole-equi ranges: many of these turn back before 180 deg, some inside the image.
    frame = _frame(rng)
    k = rng.uniform([-0.1, -0.05, -0.02, -0.005], [0.1, 0.05, 0.02, 0.005])
    skew = rng.uniform(-0.003, 0.003) if rng.random() < 0.3 else 0.0
    d = {"model": "kannala_brandt", **frame, **_focal(rng, frame, 0.25, 0.45), "skew": skew}
    d.update(zip(("k1", "k2", "k3", "k4"), k.tolist(), strict=True))
    if rng.random() < 0.3:  # an image circle, inside the range where theta_d increases
        limit = camera_from_dict(d).theta_limit
        d["fov_deg"] = min(rng.uniform(150.0, 230.0), 2 * math.degrees(limit))
    return d


def _unified(rng: np.random.Generator) -> dict:
    # MEI: xi from a perspective lens to a mirror (KITTI-360's 2.2-2.6, with k2 up to 4.5).
    frame = _frame(rng)
    xi = rng.uniform(0.0, 3.0)
    fx = (1.0 + xi) * rng.uniform(0.25, 0.45) * frame["width"]
    k2 = rng.uniform(-0.1, 0.5) + (rng.uniform(0.0, 4.5) if xi > 1.5 else 0.0)
    return {
        "model": "unified",
        **frame,
        "fx": fx,
        "fy": fx * rng.uniform(0.98, 1.02),
        "xi": xi,
        "k1": rng.uniform(-0.3, 0.1),
        "k2": k2,
        "p1": rng.uniform(-2e-3, 2e-3),
        "p2": rng.uniform(-2e-3, 2e-3),
    }


def _double_sphere(rng: np.random.Generator) -> dict:
    frame = _frame(rng)
    return {
        "model": "double_sphere",
        **frame,
        **_focal(rng, frame, 0.2, 0.45),
        "xi": rng.uniform(-0.4, 0.4),
        "alpha": rng.uniform(0.4, 0.75),
    }


def _eucm(rng: np.random.Generator) -> dict:
    frame = _frame(rng)
    return {
        "model": "eucm",
        **frame,
        **_focal(rng, frame, 0.25, 0.5),
        "alpha": rng.uniform(0.4, 0.8),
        "beta": rng.uniform(0.6, 1.8),
    }


def _fov(rng: np.random.Generator) -> dict:
    # COLMAP FOV / ATAN: omega from nearly a pinhole to strong fisheyes; short focals put the limit of the
    # half-space (omega r_d = pi / 2) inside the image, where pixels have no ray.
    frame = _frame(rng)
    return {"model": "fov", **frame, **_focal(rng, frame, 0.2, 0.8), "omega": rng.uniform(0.01, 1.6)}


def _division(rng: np.random.Generator) -> dict:
    # COLMAP (SIMPLE_)DIVISION: barrel k < 0 reaches past 90 deg (1 + k t^2 < 0) and, with short focals, past
    # 180 deg of field inside the image; pincushion k > 0 folds at t = 1 / sqrt(k), inside the image for the largest.
    frame = _frame(rng)
    return {"model": "division", **frame, **_focal(rng, frame, 0.2, 0.8), "k": rng.uniform(-1.2, 0.35)}


def _thin_prism_fisheye(rng: np.random.Generator) -> dict:
    # COLMAP THIN_PRISM_FISHEYE: Kannala-Brandt's ranges, with tangential and thin-prism terms up to COLMAP's own
    # test values (p 1e-3, sx1 -0.02): they fold the map before the polynomial turns, on some inside the image.
    frame = _frame(rng)
    k = rng.uniform([-0.1, -0.05, -0.02, -0.005], [0.1, 0.05, 0.02, 0.005])
    d = {"model": "thin_prism_fisheye", **frame, **_focal(rng, frame, 0.25, 0.45)}
    d.update(zip(("k1", "k2", "k3", "k4"), k.tolist(), strict=True))
    d.update(zip(("p1", "p2"), rng.uniform(-3e-3, 3e-3, 2).tolist(), strict=True))
    d.update(zip(("sx1", "sy1"), rng.uniform(-0.03, 0.03, 2).tolist(), strict=True))
    if rng.random() < 0.3:  # an image circle, inside the disc where the distortion is one-to-one
        limit = camera_from_dict(d).theta_limit
        d["fov_deg"] = min(rng.uniform(150.0, 230.0), 2 * math.degrees(limit))
    return d


def _rad_tan_thin_prism_fisheye(rng: np.random.Generator) -> dict:
    # COLMAP RAD_TAN_THIN_PRISM_FISHEYE (Project Aria's Fisheye624): radial terms to theta^13 about COLMAP's test
    # values (an Aria camera's), tangential and thin-prism terms up to 1e-3 (Aria's are ~1e-4). Some of these turn
    # back or fold inside the image.
    frame = _frame(rng)
    colmap_test = np.array([-0.0232, 0.0924, -0.0591, 0.003, 0.0048, -0.0009])
    k = colmap_test + rng.uniform(-1.0, 1.0, 6) * np.array([0.05, 0.05, 0.03, 0.01, 0.004, 0.001])
    d = {"model": "rad_tan_thin_prism_fisheye", **frame, **_focal(rng, frame, 0.2, 0.45)}
    d.update(zip(("k0", "k1", "k2", "k3", "k4", "k5"), k.tolist(), strict=True))
    d.update(zip(("p0", "p1", "s0", "s1", "s2", "s3"), rng.uniform(-1e-3, 1e-3, 6).tolist(), strict=True))
    return d


def _radial_poly(rng: np.random.Generator) -> dict:
    # WoodScape's front camera has k = (0.265, -0.025, 0.038, -0.0056) image widths per radian^i.
    frame = _frame(rng)
    w = frame["width"]
    k = w * rng.uniform([0.2, -0.05, 0.0, -0.012], [0.32, 0.01, 0.05, 0.002])
    return {
        "model": "radial_poly",
        **frame,
        **dict(zip(("k1", "k2", "k3", "k4"), k.tolist(), strict=True)),
        "aspect_ratio": rng.uniform(0.98, 1.02),
    }


def _pinhole_radtan(rng: np.random.Generator) -> dict:
    frame = _frame(rng)
    return {
        "model": "pinhole_radtan",
        **frame,
        **_focal(rng, frame, 0.5, 1.2),
        "k1": rng.uniform(-0.4, 0.2),
        "k2": rng.uniform(-0.1, 0.3),
        "p1": rng.uniform(-3e-3, 3e-3),
        "p2": rng.uniform(-3e-3, 3e-3),
        "k3": rng.uniform(-0.05, 0.05),
    }


def _pinhole_rational(rng: np.random.Generator) -> dict:
    """OpenCV's rational model (CALIB_RATIONAL_MODEL, COLMAP FULL_OPENCV): small denominators, or the large, nearly
    cancelling numerator and denominator that wide lenses calibrate to (k1 ~ k4, k2 ~ k5), some with a pole."""
    cam = _pinhole_radtan(rng)
    if rng.random() < 0.5:
        k4, k5, k6 = rng.uniform(-0.1, 0.3), rng.uniform(-0.05, 0.05), rng.uniform(-0.01, 0.01)
    else:
        k4, k5, k6 = rng.uniform(0.5, 3.0), rng.uniform(0.0, 1.0), rng.uniform(0.0, 0.1)
        cam["k1"], cam["k2"], cam["k3"] = k4 + rng.uniform(-0.6, 0.1), k5 + rng.uniform(-0.3, 0.1), k6
    return {**cam, "k4": k4, "k5": k5, "k6": k6}


def _pinhole(rng: np.random.Generator) -> dict:
    """The ideal pinhole from a long lens to nearly a hemisphere across the width (its corners beyond)."""
    return {"model": "pinhole", **_frame(rng), "fov_deg": rng.uniform(10.0, 170.0)}


def _ocam(rng: np.random.Generator) -> dict:
    """A lens ``r = f theta (1 + a theta^2 + b theta^4)`` fitted as OCamCalib does: world2cam of 6-16 terms in
    ``theta - pi/2`` over the calibrated range only (then written with six decimals, as export_data.m does), so
    beyond it the fit may turn back or blow up. In half the draws the fit is also off on the axis, the end of its
    data, by ``c0 ((pi/2 - theta) / (pi/2))^n`` (either sign; up to 1.5 times the ``c0`` that makes it flat there, so
    some decrease at first). cam2world (unused by project / unproject) is a matching ss."""
    frame = _frame(rng)
    f = rng.uniform(0.25, 0.4) * frame["width"]
    a, b = rng.uniform(-0.06, 0.06), rng.uniform(-0.01, 0.01)
    theta = np.linspace(0.0, math.radians(rng.uniform(95.0, 130.0)), 200)
    r = f * theta * (1 + a * theta**2 + b * theta**4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", np.exceptions.RankWarning)
        coeffs = np.polynomial.polynomial.polyfit(theta - math.pi / 2, r, int(rng.integers(5, 16)))
    if rng.random() < 0.5:  # c0 ((pi/2 - theta) / (pi/2))^n = c0 (-x / (pi/2))^n, x = theta - pi/2
        n = int(rng.integers(12, 17))
        c0 = rng.uniform(-1.0, 1.5) * f * (math.pi / 2) / n
        coeffs = np.polynomial.polynomial.polyadd(coeffs, [0.0] * n + [c0 * (-1) ** n / (math.pi / 2) ** n])
    return {
        "model": "ocam",
        **frame,
        "c": 1.0 + rng.uniform(-1e-3, 1e-3),
        "d": rng.uniform(-1e-3, 1e-3),
        "e": rng.uniform(-1e-3, 1e-3),
        "cam2world": [-f, 0.0, 1.0 / (2 * f), 0.0, 0.0],
        "world2cam": [round(float(c), 6) for c in coeffs],
    }


FAMILIES: dict[str, Callable[[np.random.Generator], dict]] = {
    "equidistant": _ideal("equidistant", 360.0),
    "equisolid": _ideal("equisolid", 360.0),
    "stereographic": _ideal("stereographic", 300.0),
    "orthographic": _ideal("orthographic", 180.0),
    "kannala_brandt": _kannala_brandt,
    "unified": _unified,
    "double_sphere": _double_sphere,
    "eucm": _eucm,
    "fov": _fov,
    "division": _division,
    "thin_prism_fisheye": _thin_prism_fisheye,
    "rad_tan_thin_prism_fisheye": _rad_tan_thin_prism_fisheye,
    "ocam": _ocam,
    "radial_poly": _radial_poly,
    "pinhole_radtan": _pinhole_radtan,
    "pinhole_rational": _pinhole_rational,
    "pinhole": _pinhole,
}


def random_cameras(family: str, n: int = PER_FAMILY) -> list[CameraModel]:
    """``n`` cameras of one family, the same ones every run (the family's name seeds the generator)."""
    rng = np.random.default_rng([35, *family.encode()])  # a family's name, not its model's
    return [camera_from_dict(FAMILIES[family](rng)) for _ in range(n)]


# ---------------------------------------------------------------------------------------------- independent checks
