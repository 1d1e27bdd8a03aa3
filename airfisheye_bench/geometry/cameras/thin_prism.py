"""COLMAP's thin-prism fisheye models: a distortion of the plane of ``theta`` with radial, tangential and thin-prism
terms. ``THIN_PRISM_FISHEYE`` (Weng et al. 1992) and ``RAD_TAN_THIN_PRISM_FISHEYE`` (Project Aria's Fisheye624).

github:colmap/colmap ``src/colmap/sensor/models.h`` (``ThinPrismFisheyeCameraModel``, ``RadTanThinPrismFisheyeModel``:
``ImgFromCam``, ``Distortion``): the ray's point ``m = theta (x, y) / r`` (``FisheyeFromNormal``, ``|m| = theta``) is
distorted to ``m_d = m + D(m)`` and ``u = fx m_d,x + cx``, ``v = fy m_d,y + cy``. Without the tangential and
thin-prism terms both are the Kannala-Brandt polynomial (``kannala_brandt``), the second one to ``theta^13``.

As ``kannala_brandt`` the angle is ``atan2(r, z)``, the same as COLMAP's ``atan(r / z)`` in front of the camera,
so the model goes on past 90 deg. Its valid region is the disc ``theta <= theta_limit`` where ``m -> m_d`` is
one-to-one: the radial part increases, the Jacobian's determinant stays positive at every azimuth, the radius stays
within ``FAR_FRAME`` image sizes of the image, and ``theta <= pi``. Back-projection solves ``m_d(m)`` by Newton steps
on the 2x2 system (``_solve_planar.py``, ``DiscInverse``; COLMAP's ``IterativeUndistortion`` does the same) and is NaN
wherever it does not reproduce the pixel or leaves the disc.
"""

from __future__ import annotations

import math

import torch

from airfisheye_bench.geometry.cameras._solve import (
    FAR_FRAME,
    PIXEL_TOL,
    frame_reach,
    increasing_limit,
    polyval,
)
from airfisheye_bench.geometry.cameras._solve_planar import DiscInverse, one_to_one_radius
from airfisheye_bench.geometry.cameras.base import CameraModel, ray_at_incidence
from airfisheye_bench.geometry.cameras.params import FOV_DEG, PINHOLE, zeros


class _ThetaPlaneDistortion(CameraModel):
    """The shared part: ``fx, fy, cx, cy``, the plane of ``theta`` and its inverse; subclasses declare ``fx, fy, cx,
    cy``, their distortion coefficients and ``fov_deg``, and give the distortion ``m -> m_d``, its Jacobian and its
    radial part's odd coefficients."""

    @property
    def coefficients(self) -> tuple[str, ...]:
        """The distortion coefficients' names, in COLMAP's order (the parameters besides fx, fy, cx, cy, fov_deg)."""
        return tuple(p.name for p in self.declaration if p not in (*PINHOLE, FOV_DEG))

    def _setup(self) -> None:
        odd = self._radial_odd()  # theta_d = theta (c0 + c1 theta^2 + c2 theta^4 + ...)
        d_odd = tuple((2 * i + 1) * c for i, c in enumerate(odd))

        def radial(t: torch.Tensor) -> torch.Tensor:
            return t * polyval(odd, t * t)

        def d_radial(t: torch.Tensor) -> torch.Tensor:
            return polyval(d_odd, t * t)

        poly = [0.0] * (2 * len(d_odd) - 1)
        poly[::2] = d_odd  # the derivative's coefficients in theta, not theta^2
        monotone = increasing_limit(d_radial, math.pi, poly=poly)
        self._undistort = DiscInverse(
            self._distort,
            self._jacobian,
            radial,
            d_radial,
            monotone,
            y_cap=frame_reach(self._normalised, self.width, self.height, FAR_FRAME),
            y_near=frame_reach(self._normalised, self.width, self.height, 1.0),
            tol=PIXEL_TOL / max(self.fx, self.fy),
        )
        #: Largest incidence angle of the valid region (radians): the disc where the distortion is one-to-one.
        self.theta_limit = self._undistort.r_valid
        if self.fov_deg is not None and self.max_theta > self.theta_limit + 1e-12:
            # Only a fold refuses fov_deg: the frame's cap is no property of the lens (it moves with the image size).
            one_to_one = one_to_one_radius(self._undistort.min_det, monotone)
            if self.max_theta > one_to_one + 1e-12:
                raise ValueError(
                    f"the {self.model} distortion is one-to-one only up to {math.degrees(one_to_one):.1f} deg off "
                    f"the axis, not to fov_deg/2={self.fov_deg / 2:g} deg; reduce fov_deg or fix the coefficients"
                )

    def _radial_odd(self) -> tuple[float, ...]:
        raise NotImplementedError

    def _distort(self, a: torch.Tensor, b: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        raise NotImplementedError

    def _jacobian(self, a: torch.Tensor, b: torch.Tensor) -> tuple[torch.Tensor, ...]:
        raise NotImplementedError

    def _normalised(self, u: torch.Tensor, v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return (u - self.cx) / self.fx, (v - self.cy) / self.fy

    def _project(self, x, y, z):
        rho = torch.hypot(x, y)
        theta = torch.atan2(rho, z)
        scale = theta / rho.clamp_min(1e-300)  # the axis (x = y = 0) maps to the centre
        ad, bd = self._distort(x * scale, y * scale)
        return self.fx * ad + self.cx, self.fy * bd + self.cy, theta <= self.theta_limit + 1e-12

    def _unproject(self, u, v):
        a, b = self._undistort(*self._normalised(u, v))
        theta = torch.hypot(a, b)
        return ray_at_incidence(theta, a, b, theta)


class ThinPrismFisheye(_ThetaPlaneDistortion):
    """COLMAP ``THIN_PRISM_FISHEYE``: ``fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1``.

    With ``(a, b) = m`` and ``t2 = a^2 + b^2 = theta^2``, ``R = k1 t2 + k2 t2^2 + k3 t2^3 + k4 t2^4``:
    ``a_d = a (1 + R) + 2 p1 a b + p2 (t2 + 2 a^2) + sx1 t2``, ``b_d = b (1 + R) + 2 p2 a b + p1 (t2 + 2 b^2) + sy1 t2``.

    Example:
        >>> import numpy as np
        >>> cam = ThinPrismFisheye(772, 1022, 651.123, 655.123, 386.123, 511.123, k1=-0.471, k2=0.223,
        ...                        p1=-0.001, p2=0.001, k3=0.001, k4=0.02, sx1=-0.02, sy1=0.001)
        >>> uv, valid = cam.project(np.array([[0.4, -0.3, 1.0]]))
        >>> bool(valid[0]), bool(np.allclose(cam.unproject(uv), np.array([[0.4, -0.3, 1.0]]) / np.sqrt(1.25)))
        (True, True)
    """

    model = "thin_prism_fisheye"
    declaration = (*PINHOLE, *zeros("k1", "k2", "p1", "p2", "k3", "k4", "sx1", "sy1"), FOV_DEG)

    def _radial_odd(self) -> tuple[float, ...]:
        return (1.0, self.k1, self.k2, self.k3, self.k4)

    def _radial(self, t2: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``R(t2)`` and ``dR/dt2``."""
        k1, k2, k3, k4 = self.k1, self.k2, self.k3, self.k4
        r = t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))
        dr = k1 + t2 * (2.0 * k2 + t2 * (3.0 * k3 + t2 * 4.0 * k4))
        return r, dr

    def _distort(self, a, b):
        p1, p2, sx1, sy1 = self.p1, self.p2, self.sx1, self.sy1
        t2 = a * a + b * b
        r, _ = self._radial(t2)
        ab = a * b
        ad = a * (1.0 + r) + 2.0 * p1 * ab + p2 * (t2 + 2.0 * a * a) + sx1 * t2
        bd = b * (1.0 + r) + 2.0 * p2 * ab + p1 * (t2 + 2.0 * b * b) + sy1 * t2
        return ad, bd

    def _jacobian(self, a, b):
        p1, p2, sx1, sy1 = self.p1, self.p2, self.sx1, self.sy1
        r, dr = self._radial(a * a + b * b)
        cross = 2.0 * a * b * dr
        j11 = 1.0 + r + 2.0 * a * a * dr + 2.0 * p1 * b + 6.0 * p2 * a + 2.0 * sx1 * a
        j12 = cross + 2.0 * p1 * a + 2.0 * p2 * b + 2.0 * sx1 * b
        j21 = cross + 2.0 * p2 * b + 2.0 * p1 * a + 2.0 * sy1 * a
        j22 = 1.0 + r + 2.0 * b * b * dr + 2.0 * p2 * a + 6.0 * p1 * b + 2.0 * sy1 * b
        return j11, j12, j21, j22


class RadTanThinPrismFisheye(_ThetaPlaneDistortion):
    """COLMAP ``RAD_TAN_THIN_PRISM_FISHEYE`` (Project Aria's Fisheye624): ``fx, fy, cx, cy, k0..k5, p0, p1, s0..s3``.

    The radial part first, ``(x, y) = m (1 + k0 theta^2 + k1 theta^4 + ... + k5 theta^12)``, then with
    ``r2 = x^2 + y^2``: ``a_d = x + 2 p1 x y + p0 (r2 + 2 x^2) + s0 r2 + s1 r2^2``,
    ``b_d = y + 2 p0 x y + p1 (r2 + 2 y^2) + s2 r2 + s3 r2^2``.
    """

    model = "rad_tan_thin_prism_fisheye"
    declaration = (
        *PINHOLE,
        *zeros("k0", "k1", "k2", "k3", "k4", "k5", "p0", "p1", "s0", "s1", "s2", "s3"),
        FOV_DEG,
    )

    def _radial_odd(self) -> tuple[float, ...]:
        return (1.0, self.k0, self.k1, self.k2, self.k3, self.k4, self.k5)

    def _radial(self, t2: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The factor ``g = 1 + k0 t2 + ... + k5 t2^6`` and ``dg/dt2``."""
        k = (self.k0, self.k1, self.k2, self.k3, self.k4, self.k5)
        return 1.0 + t2 * polyval(k, t2), polyval(tuple((i + 1) * c for i, c in enumerate(k)), t2)

    def _tangential(self, x, y):
        """The tangential and thin-prism terms' share of the distorted point, and ``r2 = x^2 + y^2``."""
        r2 = x * x + y * y
        dx = 2.0 * self.p1 * x * y + self.p0 * (r2 + 2.0 * x * x) + r2 * (self.s0 + self.s1 * r2)
        dy = 2.0 * self.p0 * x * y + self.p1 * (r2 + 2.0 * y * y) + r2 * (self.s2 + self.s3 * r2)
        return dx, dy, r2

    def _distort(self, a, b):
        g, _ = self._radial(a * a + b * b)
        x, y = g * a, g * b
        dx, dy, _ = self._tangential(x, y)
        return x + dx, y + dy

    def _jacobian(self, a, b):
        g, dg = self._radial(a * a + b * b)
        x, y = g * a, g * b
        # d(x, y) / d(a, b): the radial part.
        cross = 2.0 * a * b * dg
        r11, r12, r22 = g + 2.0 * a * a * dg, cross, g + 2.0 * b * b * dg
        # d(x_d, y_d) / d(x, y): the tangential and thin-prism terms.
        r2 = x * x + y * y
        sx, sy = 2.0 * (self.s0 + 2.0 * self.s1 * r2), 2.0 * (self.s2 + 2.0 * self.s3 * r2)
        t11 = 1.0 + 2.0 * self.p1 * y + 6.0 * self.p0 * x + sx * x
        t12 = 2.0 * self.p1 * x + 2.0 * self.p0 * y + sx * y
        t21 = 2.0 * self.p0 * y + 2.0 * self.p1 * x + sy * x
        t22 = 1.0 + 2.0 * self.p0 * x + 6.0 * self.p1 * y + sy * y
        return t11 * r11 + t12 * r12, t11 * r12 + t12 * r22, t21 * r11 + t22 * r12, t21 * r12 + t22 * r22


__all__ = ["RadTanThinPrismFisheye", "ThinPrismFisheye"]
