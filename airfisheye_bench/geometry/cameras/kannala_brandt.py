"""Kannala-Brandt (KB4): OpenCV ``cv2.fisheye``, ROS ``equidistant``, Kalibr ``pinhole-equi``, COLMAP
``OPENCV_FISHEYE``, basalt ``kb4``.

``theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)`` with ``theta`` the incidence angle;
``u = fx (theta_d x / r + skew theta_d y / r) + cx``, ``v = fy theta_d y / r + cy`` (``r = sqrt(x^2 + y^2)``;
``skew`` is OpenCV's ``alpha``). Unlike OpenCV's ``projectPoints`` (``theta = atan(r / z)``, valid below 90 deg)
the angle is ``atan2(r, z)`` as in basalt, so the model covers lenses wider than 180 deg. The valid region is
``theta`` up to where ``theta_d`` stops increasing (at most pi), or where the image radius leaves the frame
``FAR_FRAME`` image sizes around the image (``theta_limit``); back-projection inverts ``theta_d`` there with the
bounded Newton solver of ``_solve.py`` and is NaN beyond.
"""

from __future__ import annotations

import math
from typing import Any

import torch

from airfisheye_bench.geometry.cameras._solve import (
    PIXEL_TOL,
    image_inverse,
    increasing_limit,
    polyval_error,
)
from airfisheye_bench.geometry.cameras.base import CameraModel, ray_at_incidence
from airfisheye_bench.geometry.cameras.params import FOV_DEG, PINHOLE, Param, finite_float, zeros


class KannalaBrandt(CameraModel):
    """Kannala-Brandt fisheye with two focal lengths and optional skew.

    Args:
        width: Image width in pixels.
        height: Image height in pixels.
        fx: Focal length along u (pixels).
        fy: Focal length along v (pixels).
        cx: Principal point column.
        cy: Principal point row.
        k1: Distortion coefficient of ``theta^3``; ``k2``, ``k3``, ``k4`` of ``theta^5, theta^7, theta^9``.
        skew: OpenCV's ``alpha`` (``u = fx (x_d + alpha y_d) + cx``).
        fov_deg: Optional field of view limiting the valid region (the image circle).

    Example:
        >>> import numpy as np
        >>> cam = KannalaBrandt(512, 512, fx=160.0, fy=160.0, cx=255.5, cy=255.5, k1=0.01)
        >>> uv, valid = cam.project(np.array([[1.0, 0.0, 0.0]]))  # 90 deg off-axis
        >>> round(float(uv[0, 0] - 255.5), 4) == round(160 * (math.pi / 2) * (1 + 0.01 * (math.pi / 2) ** 2), 4)
        True
    """

    model = "kannala_brandt"
    declaration = (*PINHOLE, *zeros("k1", "k2", "k3", "k4"), Param("skew", 0.0), FOV_DEG)

    def _setup(self) -> None:
        k1, k2, k3, k4 = self.k
        monotone = increasing_limit(
            self._dtheta_d, math.pi, poly=(1.0, 0.0, 3 * k1, 0.0, 5 * k2, 0.0, 7 * k3, 0.0, 9 * k4)
        )
        if self.fov_deg is not None and self.max_theta > monotone + 1e-12:
            raise ValueError(
                f"k={self.k}: the Kannala-Brandt polynomial is not increasing up to fov_deg/2={self.fov_deg / 2:g} deg"
                f" (only up to {math.degrees(monotone):.1f} deg), so it cannot be inverted there; reduce "
                "fov_deg or fix the coefficients"
            )
        # Solved (and valid) while theta_d increases and the image radius stays within FAR_FRAME image sizes of
        # the image: beyond, a ray's pixel is no sensor's and the polynomial's growth is no lens's.
        scale = max(self.fx, self.fy) * (1.0 + abs(self.skew))  # pixels per unit of theta_d, at most
        self._inverse = image_inverse(
            self.theta_d,
            self._dtheta_d,
            monotone,
            self._normalised,
            self.width,
            self.height,
            tol=PIXEL_TOL / scale,
            f_err=self._theta_d_err,
        )
        #: Largest incidence angle of the valid region (radians): where theta_d stops increasing, at most pi.
        self.theta_limit = self._inverse.t_hi

    @property
    def k(self) -> tuple[float, float, float, float]:
        """``(k1, k2, k3, k4)``."""
        return (self.k1, self.k2, self.k3, self.k4)

    def theta_d(self, theta: torch.Tensor) -> torch.Tensor:
        """The distorted angle ``theta (1 + k1 theta^2 + ... + k4 theta^8)``."""
        t2 = theta * theta
        return theta * (1.0 + t2 * (self.k1 + t2 * (self.k2 + t2 * (self.k3 + t2 * self.k4))))

    def _theta_d_err(self, theta: torch.Tensor) -> torch.Tensor:
        """A bound on float64's rounding of :meth:`theta_d`."""
        k1, k2, k3, k4 = self.k
        return polyval_error((0.0, 1.0, 0.0, k1, 0.0, k2, 0.0, k3, 0.0, k4), theta)

    def _dtheta_d(self, theta: torch.Tensor) -> torch.Tensor:
        t2 = theta * theta
        return 1.0 + t2 * (3 * self.k1 + t2 * (5 * self.k2 + t2 * (7 * self.k3 + t2 * 9 * self.k4)))

    def _project(self, x, y, z):
        rho = torch.hypot(x, y)
        theta = torch.atan2(rho, z)
        scale = self.theta_d(theta) / rho.clamp_min(1e-300)  # the axis (x = y = 0) maps to the centre
        mx, my = x * scale, y * scale
        return (
            self.fx * (mx + self.skew * my) + self.cx,
            self.fy * my + self.cy,
            theta <= self.theta_limit + 1e-12,
        )

    def _normalised(self, u: torch.Tensor, v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(m_x, m_y)``: the pixel's offset in units of the focal lengths, skew removed (``theta_d`` its norm)."""
        my = (v - self.cy) / self.fy
        return (u - self.cx) / self.fx - self.skew * my, my

    def _unproject(self, u, v):
        mx, my = self._normalised(u, v)
        td = torch.hypot(mx, my)
        theta = self._inverse(td)
        return ray_at_incidence(theta, mx, my, td)

    @classmethod
    def from_focal(
        cls,
        width: int,
        height: int,
        fov_deg: float = 190.0,
        cx: float | None = None,
        cy: float | None = None,
        focal: float | None = None,
        k: Any = None,
    ) -> KannalaBrandt:
        """The single-focal form of ``calib.yaml`` before issue #22 (``focal``, ``k: [k1..k4]``; the default focal
        inscribes the image circle ``theta = fov_deg / 2`` in the image)."""
        k = (0.0, 0.0, 0.0, 0.0) if k is None else k
        if isinstance(k, str) or not hasattr(k, "__len__") or len(k) != 4:
            raise ValueError(f"k must be four finite Kannala-Brandt coefficients (k1..k4), got {k}")
        k = tuple(finite_float(f"k[{i}]", v) for i, v in enumerate(k))
        fov_deg = finite_float("fov_deg", fov_deg)
        if not 0.0 < fov_deg <= 360.0:
            raise ValueError(f"fov_deg must be in (0, 360], got {fov_deg}")
        cx = (int(width) - 1) / 2.0 if cx is None else cx
        cy = (int(height) - 1) / 2.0 if cy is None else cy
        if focal is None:
            t = math.radians(fov_deg) / 2.0
            t2 = t * t
            r_unit = t * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))))
            if r_unit <= 0:  # the polynomial turned back before fov_deg / 2: let the constructor say so
                cls(width, height, 1.0, 1.0, cx, cy, *k, fov_deg=fov_deg)
            focal = (min(int(width), int(height)) / 2.0) / r_unit
        if not (isinstance(focal, int | float) and math.isfinite(focal) and focal > 0):
            raise ValueError(f"focal must be a positive number of pixels, got {focal}")
        return cls(width, height, focal, focal, cx, cy, *k, fov_deg=fov_deg)


__all__ = ["KannalaBrandt"]
