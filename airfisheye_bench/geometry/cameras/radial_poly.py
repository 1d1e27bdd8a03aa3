"""WoodScape's ``radial_poly`` model (github:valeoai/WoodScape, ``scripts/calibration/projection.py``).

``rho(theta) = k1 theta + k2 theta^2 + k3 theta^3 + k4 theta^4`` (pixels) with ``theta`` the incidence angle;
``u = cx + rho x / n``, ``v = cy + aspect_ratio rho y / n`` (``n = sqrt(x^2 + y^2)``). WoodScape's JSON stores
``cx_offset``, ``cy_offset`` from the image centre; its ``Camera`` turns them into
``cx = W / 2 + cx_offset - 0.5`` (likewise cy), which is what the readers pass here. The valid region is
``theta`` up to where ``rho`` stops increasing (at most pi), or where it leaves the frame ``FAR_FRAME`` image sizes
around the image (``theta_limit``); back-projection inverts ``rho`` there by bounded Newton steps and is NaN beyond
(WoodScape itself takes the smallest real root of the polynomial, one pixel at a time).
"""

from __future__ import annotations

import math

import torch

from airfisheye_bench.geometry.cameras._solve import (
    PIXEL_TOL,
    image_inverse,
    increasing_limit,
    polyder,
    polyval,
    polyval_error,
)
from airfisheye_bench.geometry.cameras.base import CameraModel, ray_at_incidence
from airfisheye_bench.geometry.cameras.params import FOV_DEG, Param, positive


class RadialPoly(CameraModel):
    """WoodScape radial polynomial: ``k1..k4`` (pixels per radian^i), ``cx, cy``, ``aspect_ratio``.

    Example:
        >>> import numpy as np
        >>> cam = RadialPoly(1280, 966, k1=339.749, k2=-31.988, k3=48.275, k4=-7.201, cx=639.5, cy=482.5)
        >>> uv, valid = cam.project(np.array([[1.0, 0.0, 0.0]]))
        >>> round(float(uv[0, 0]) - 639.5, 3), bool(valid[0])
        (598.013, True)
    """

    model = "radial_poly"
    declaration = (
        Param("k1", scale="fx"),  # pixels per radian^i: pixel lengths
        *(Param(name, 0.0, scale="fx", distortion=True) for name in ("k2", "k3", "k4")),
        Param("cx", 0.0, scale="cx"),
        Param("cy", 0.0, scale="cy"),
        Param("aspect_ratio", 1.0, check=positive),
        FOV_DEG,
    )

    def _setup(self) -> None:
        self._coeffs = (0.0, self.k1, self.k2, self.k3, self.k4)
        self._dcoeffs = polyder(self._coeffs)
        monotone = increasing_limit(self._drho, math.pi, poly=self._dcoeffs)
        if monotone <= 0:
            raise ValueError(f"rho(theta) must increase from the optical axis (k1 > 0), got k1={self.k1}")
        if self.fov_deg is not None and self.max_theta > monotone + 1e-12:
            raise ValueError(
                f"rho(theta) stops increasing at {math.degrees(monotone):.1f} deg, below fov_deg/2="
                f"{self.fov_deg / 2:g} deg"
            )
        # Solved (and valid) while rho increases and stays within FAR_FRAME image sizes of the image.
        self._inverse = image_inverse(
            self.rho,
            self._drho,
            monotone,
            self._sensor,
            self.width,
            self.height,
            tol=PIXEL_TOL / max(1.0, self.aspect_ratio),
            f_err=self._rho_err,
        )
        #: Largest incidence angle of the valid region (radians): where rho stops increasing, at most pi.
        self.theta_limit = self._inverse.t_hi

    def rho(self, theta: torch.Tensor) -> torch.Tensor:
        """Image radius (pixels) at incidence angle ``theta``."""
        return polyval(self._coeffs, theta)

    def _drho(self, theta: torch.Tensor) -> torch.Tensor:
        return polyval(self._dcoeffs, theta)

    def _rho_err(self, theta: torch.Tensor) -> torch.Tensor:
        """A bound on float64's rounding of :meth:`rho`."""
        return polyval_error(self._coeffs, theta)

    def _project(self, x, y, z):
        n = torch.hypot(x, y)
        theta = torch.atan2(n, z)
        s = self.rho(theta) / n.clamp_min(1e-300)
        return self.cx + s * x, self.cy + self.aspect_ratio * s * y, theta <= self.theta_limit + 1e-12

    def _sensor(self, u: torch.Tensor, v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The pixel's offset from the centre with the aspect ratio removed (its norm is ``rho``)."""
        return u - self.cx, (v - self.cy) / self.aspect_ratio

    def _unproject(self, u, v):
        gx, gy = self._sensor(u, v)
        r = torch.hypot(gx, gy)
        theta = self._inverse(r)
        return ray_at_incidence(theta, gx, gy, r)


__all__ = ["RadialPoly"]
