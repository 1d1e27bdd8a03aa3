"""COLMAP's camera models written out in numpy, line by line, to test the project's models against (not its code).

Source: github:colmap/colmap ``src/colmap/sensor/models.h`` (as of 2026-08): each model's ``ImgFromCam``,
``CamFromImg`` and ``Distortion`` (``FullOpenCVCameraModel``'s is OpenCV's rational model),
``BasePerspectiveFisheyeCameraModel::FisheyeFromNormal`` / ``NormalFromFisheye`` and
``BasePerspectiveCameraModel::IterativeUndistortion``. COLMAP's pixels: the image corner
is the origin, the top-left pixel's centre is (0.5, 0.5). ``IterativeUndistortion`` takes its Jacobian from ceres
Jets (exact derivatives); here central differences stand in for them (the point it converges to is the same).
"""

from __future__ import annotations

import numpy as np

EPS = np.finfo(np.float64).eps
#: Models with ``BasePerspectiveFisheyeCameraModel``'s plane of theta, and where their extra parameters start.
FISHEYE = {"OPENCV_FISHEYE": 4, "THIN_PRISM_FISHEYE": 4, "RAD_TAN_THIN_PRISM_FISHEYE": 4}


def fisheye_from_normal(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``FisheyeFromNormal``: ``(u, v) theta / r``, ``theta = atan(r)`` (left alone while ``r <= eps``)."""
    r = np.sqrt(u * u + v * v)
    big = r > EPS
    scale = np.where(big, np.arctan(r) / np.where(big, r, 1.0), 1.0)
    return u * scale, v * scale


def normal_from_fisheye(uu: np.ndarray, vv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``NormalFromFisheye``: ``(uu, vv) sin(theta) / (theta cos(theta))``, ``theta = |(uu, vv)|``."""
    theta = np.sqrt(uu * uu + vv * vv)
    theta_cos_theta = theta * np.cos(theta)
    big = theta_cos_theta > EPS
    scale = np.where(big, np.sin(theta) / np.where(big, theta_cos_theta, 1.0), 1.0)
    return uu * scale, vv * scale


def distortion(model: str, extra: list[float], u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Distortion(extra_params, u, v, &du, &dv)`` of each model with one."""
    if model == "FULL_OPENCV":
        k1, k2, p1, p2, k3, k4, k5, k6 = extra
        u2, uv, v2 = u * u, u * v, v * v
        r2 = u2 + v2
        r4 = r2 * r2
        r6 = r4 * r2
        radial = (1 + k1 * r2 + k2 * r4 + k3 * r6) / (1 + k4 * r2 + k5 * r4 + k6 * r6)
        du = u * radial + 2 * p1 * uv + p2 * (r2 + 2 * u2) - u
        dv = v * radial + 2 * p2 * uv + p1 * (r2 + 2 * v2) - v
        return du, dv
    if model == "OPENCV_FISHEYE":
        k1, k2, k3, k4 = extra
        theta2 = u * u + v * v
        radial = k1 * theta2 + k2 * theta2**2 + k3 * theta2**3 + k4 * theta2**4
        return u * radial, v * radial
    if model == "THIN_PRISM_FISHEYE":
        k1, k2, p1, p2, k3, k4, sx1, sy1 = extra
        u2, uv, v2 = u * u, u * v, v * v
        r2 = u2 + v2
        r4 = r2 * r2
        r6 = r4 * r2
        r8 = r6 * r2
        radial = k1 * r2 + k2 * r4 + k3 * r6 + k4 * r8
        du = u * radial + 2 * p1 * uv + p2 * (r2 + 2 * u2) + sx1 * r2
        dv = v * radial + 2 * p2 * uv + p1 * (r2 + 2 * v2) + sy1 * r2
        return du, dv
    if model == "RAD_TAN_THIN_PRISM_FISHEYE":
        radial_coeffs, (p0, p1, s0, s1, s2, s3) = extra[:6], extra[6:]
        theta2 = u * u + v * v
        th_radial = np.ones_like(u)
        theta_power = np.ones_like(u)
        for k in radial_coeffs:
            theta_power = theta_power * theta2
            th_radial = th_radial + k * theta_power
        x, y = th_radial * u, th_radial * v
        x2, y2, xy = x * x, y * y, x * y
        r2 = x2 + y2
        r4 = r2 * r2
        dx_tang = 2 * p1 * xy + p0 * (r2 + 2 * x2)
        dy_tang = 2 * p0 * xy + p1 * (r2 + 2 * y2)
        dx_tp = s0 * r2 + s1 * r4
        dy_tp = s2 * r2 + s3 * r4
        return x + dx_tang + dx_tp - u, y + dy_tang + dy_tp - v
    raise AssertionError(model)


def iterative_undistortion(model: str, extra: list[float], u: float, v: float) -> tuple[float, float, bool]:
    """``IterativeUndistortion``: Newton steps in a trust region, at most 100, until a step's squared norm is below
    1e-10; ``(u, v, converged)``."""
    x0 = np.array([u, v])
    x = x0.copy()
    h = 1e-7
    for _ in range(100):
        du, dv = distortion(model, extra, np.array([x[0]]), np.array([x[1]]))
        dx = np.array([du[0], dv[0]])
        jac = np.empty((2, 2))
        for j in range(2):
            e = np.zeros(2)
            e[j] = h
            plus = distortion(model, extra, np.array([x[0] + e[0]]), np.array([x[1] + e[1]]))
            minus = distortion(model, extra, np.array([x[0] - e[0]]), np.array([x[1] - e[1]]))
            jac[0, j] = (plus[0][0] - minus[0][0]) / (2 * h)
            jac[1, j] = (plus[1][0] - minus[1][0]) / (2 * h)
        jac += np.eye(2)
        step = np.linalg.solve(jac, x + dx - x0)
        radius_sqr = max(x @ x * 0.1 * 0.1, 0.1 * 0.1)
        if step @ step > radius_sqr:
            step *= np.sqrt(radius_sqr / (step @ step))
        x -= step
        if step @ step < 1e-10:
            return float(x[0]), float(x[1]), True
    return float(x[0]), float(x[1]), False


def img_from_cam(model: str, p: list[float], points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``ImgFromCam(params, u, v, w, &x, &y)`` on ``points [N, 3]``: COLMAP's pixels ``[N, 2]`` and whether it
    returned true (``check_cheirality``: ``w >= eps``; the division models have no such test)."""
    u, v, w = points.T
    if model in ("SIMPLE_DIVISION", "DIVISION"):
        f1, f2, c1, c2, k = (p[0], p[0], p[1], p[2], p[3]) if model == "SIMPLE_DIVISION" else p
        rho = np.sqrt(u * u + v * v)
        disc_sq = w * w - 4 * rho * rho * k
        ok = disc_sq >= 0
        disc = np.sqrt(np.where(ok, disc_sq, 0.0))
        r = 2 / (w + disc)
        return np.stack([f1 * r * u + c1, f2 * r * v + c2], -1), ok
    if model in ("SIMPLE_FISHEYE", "FISHEYE"):
        f1, f2, c1, c2 = (p[0], p[0], p[1], p[2]) if model == "SIMPLE_FISHEYE" else p[:4]
        uu, vv = fisheye_from_normal(u / w, v / w)
        return np.stack([f1 * uu + c1, f2 * vv + c2], -1), w >= EPS
    if model in FISHEYE:
        f1, f2, c1, c2 = p[:4]
        uu, vv = fisheye_from_normal(u / w, v / w)
        duu, dvv = distortion(model, p[4:], uu, vv)
        return np.stack([f1 * (uu + duu) + c1, f2 * (vv + dvv) + c2], -1), w >= EPS
    f1, f2, c1, c2 = p[:4]
    if model == "FULL_OPENCV":
        x, y = u / w, v / w
        dx, dy = distortion(model, p[4:], x, y)
        return np.stack([f1 * (x + dx) + c1, f2 * (y + dy) + c2], -1), w >= EPS
    if model == "FOV":  # Distortion's general branch (omega^2 and radius^2 >= 1e-4 on the points tested)
        omega = p[4]
        x, y = u / w, v / w
        radius = np.sqrt(x * x + y * y)
        factor = np.arctan(radius * 2 * np.tan(omega / 2)) / (radius * omega)
        return np.stack([f1 * x * factor + c1, f2 * y * factor + c2], -1), w >= EPS
    if model == "EUCM":
        alpha, beta = p[4:]
        den = alpha * np.sqrt(beta * (u * u + v * v) + w * w) + (1 - alpha) * w
        return np.stack([f1 * u / den + c1, f2 * v / den + c2], -1), (w >= EPS) & (den >= EPS)
    raise AssertionError(model)


def cam_from_img(model: str, p: list[float], xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``CamFromImg(params, x, y, &u, &v)`` on COLMAP pixels ``[N, 2]``: the points ``(u, v)`` of the plane
    ``w = 1`` ``[N, 2]`` and whether it returned true."""
    x, y = xy.T
    if model in ("SIMPLE_DIVISION", "DIVISION"):
        f1, f2, c1, c2, k = (p[0], p[0], p[1], p[2], p[3]) if model == "SIMPLE_DIVISION" else p
        x0, y0 = (x - c1) / f1, (y - c2) / f2
        denom = 1.0 + k * (x0 * x0 + y0 * y0)
        return np.stack([x0 / denom, y0 / denom], -1), np.ones(len(x), dtype=bool)
    if model in FISHEYE or model == "FULL_OPENCV":
        f1, f2, c1, c2 = p[:4]
        out, ok = np.empty((len(x), 2)), np.empty(len(x), dtype=bool)
        for i, (uu, vv) in enumerate(zip((x - c1) / f1, (y - c2) / f2, strict=True)):
            uu, vv, ok[i] = iterative_undistortion(model, p[4:], uu, vv)
            if model in FISHEYE:
                uu, vv = (c[0] for c in normal_from_fisheye(np.array([uu]), np.array([vv])))
            out[i] = uu, vv
        return out, ok
    raise AssertionError(model)
