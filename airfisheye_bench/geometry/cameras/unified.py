"""Unified camera model (MEI) with radial-tangential distortion: Kalibr ``omni`` / ``omni-radtan``,
opencv_contrib ``cv2.omnidir``, KITTI-360's fisheyes (``gamma1 = fx``, ``gamma2 = fy``, ``u0 = cx``, ``v0 = cy``).

A point is put on the unit sphere, projected from ``(0, 0, -xi)``: ``m = (x, y) / (z + xi d)`` with ``d = |p|``;
``m`` is distorted as OpenCV's plumb_bob (``k1, k2, p1, p2``) and ``u = fx m_x' + cx``, ``v = fy m_y' + cy``
(Mei and Rives, ICRA 2007; opencv_contrib ``ccalib/src/omnidir.cpp``). The valid region is basalt's
(``unified_camera.hpp``): ``z > -w d`` with ``w = xi`` for ``xi <= 1`` and ``1 / xi`` beyond, where the sphere
is seen from the projection centre, and the distortion must be one-to-one there (the radial factor increases and
the tangential terms do not fold it: ``RadtanInverse.r_valid`` in ``_solve_planar.py``).
Back-projection undoes the distortion with bounded Newton steps (``_solve_planar.py``), then lifts ``m`` to the sphere in
closed form: ``ray = (f m_x, f m_y, f - xi)``, ``f = (xi + sqrt(1 + (1 - xi^2) |m|^2)) / (1 + |m|^2)``.
"""

from __future__ import annotations

import math

import torch

from airfisheye_bench.geometry.cameras._solve_planar import RadtanInverse, radial_limit, radtan
from airfisheye_bench.geometry.cameras.base import CameraModel
from airfisheye_bench.geometry.cameras.params import FOV_DEG, PINHOLE, Param, interval, zeros


class Unified(CameraModel):
    """MEI unified model: mirror parameter ``xi``, focal lengths, principal point, ``k1, k2, p1, p2``.

    Example:
        >>> import numpy as np
        >>> cam = Unified(1400, 1400, fx=1336.3, fy=1335.8, cx=716.9, cy=705.8, xi=2.2134, k1=0.0168, k2=1.65)
        >>> uv, valid = cam.project(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, -0.4]]))
        >>> uv[0].tolist(), valid.tolist()  # the axis, and a ray 112 deg off-axis
        ([716.9, 705.8], [True, True])
        >>> bool(np.allclose(cam.unproject(uv)[1], np.array([1.0, 0.0, -0.4]) / np.hypot(1.0, 0.4)))
        True
    """

    model = "unified"
    declaration = (
        *PINHOLE,
        Param("xi", check=interval(0.0, math.inf, text="[0, inf) (the mirror parameter)")),
        *zeros("k1", "k2", "p1", "p2"),
        FOV_DEG,
    )

    def _setup(self) -> None:
        self._w = self.xi if self.xi <= 1.0 else 1.0 / self.xi
        self._m_max = radial_limit(self.k1, self.k2)  # where the radial distortion stops increasing
        self._distorted = any(c != 0.0 for c in (self.k1, self.k2, self.p1, self.p2))
        self._undistort = RadtanInverse(self.k1, self.k2, self.p1, self.p2, r_max=self._m_max)

    def _project(self, x, y, z):
        d = torch.sqrt(x * x + y * y + z * z)
        denom = z + self.xi * d
        mx, my = x / denom, y / denom
        in_region = z > -self._w * d
        if self._distorted:
            in_region &= torch.hypot(mx, my) <= self._undistort.r_valid
            mx, my = radtan(mx, my, self.k1, self.k2, self.p1, self.p2)
        return self.fx * mx + self.cx, self.fy * my + self.cy, in_region

    def _unproject(self, u, v):
        mx, my = (u - self.cx) / self.fx, (v - self.cy) / self.fy
        if self._distorted:
            mx, my = self._undistort(mx, my)
        r2 = mx * mx + my * my
        disc = 1.0 + (1.0 - self.xi * self.xi) * r2
        f = (self.xi + torch.sqrt(disc)) / (1.0 + r2)  # NaN where disc < 0: no ray reaches the pixel
        return f * mx, f * my, f - self.xi

    @property
    def region_theta(self) -> float:
        """Largest incidence angle of the valid region (without distortion limits): ``acos(-w)``."""
        return math.acos(-self._w)


__all__ = ["Unified"]
