"""Pinhole with OpenCV's radial-tangential distortion (plumb_bob: ``k1, k2, p1, p2, k3``; with ``k4, k5, k6`` the
rational model): the perspective baseline, ROS ``plumb_bob`` / ``rational_polynomial``, Kalibr ``pinhole-radtan``,
COLMAP ``OPENCV`` / ``FULL_OPENCV``, and the cube faces (``fx = fy = S / 2``, no distortion).

``m = (x, y) / z`` distorted as in OpenCV's ``projectPoints`` (``calib3d/src/calibration.cpp``; COLMAP's
``FullOpenCVCameraModel::Distortion`` is the same map): the radial factor ``(1 + k1 r^2 + k2 r^4 + k3 r^6) /
(1 + k4 r^2 + k5 r^4 + k6 r^6)`` (``CALIB_RATIONAL_MODEL``; k4..k6 = 0: plumb_bob, evaluated as it always was)
and the tangential terms. Valid in front of the camera (``z > 0``) while the distortion is one-to-one (the radius
``r g(r^2)`` increases, before any pole of the denominator, and the tangential terms do not fold it; ``_solve_planar.py``'s
``RadtanInverse.r_valid``, here ``theta_limit``); back-projection by bounded Newton steps on the distortion
(``_solve_planar.py``), NaN where they do not reproduce the pixel.
"""

from __future__ import annotations

import math

from airfisheye_bench.geometry.cameras._solve_planar import RadtanInverse, radial_limit, radtan
from airfisheye_bench.geometry.cameras.base import CameraModel
from airfisheye_bench.geometry.cameras.params import FOV_DEG, PINHOLE, zeros


class PinholeRadtan(CameraModel):
    """Pinhole camera, OpenCV distortion order ``k1, k2, p1, p2, k3, k4, k5, k6``.

    ``k4, k5, k6`` (the rational model's denominator) came later: left out of ``to_dict`` while 0, so a plumb_bob
    camera's dict, files and identity are what they were.

    Example:
        >>> import numpy as np
        >>> cam = PinholeRadtan(640, 480, fx=500.0, fy=500.0, cx=319.5, cy=239.5)
        >>> uv, valid = cam.project(np.array([[0.1, -0.2, 1.0], [0.0, 0.0, -1.0]]))
        >>> uv[0].tolist(), valid.tolist()
        ([369.5, 139.5], [True, False])
        >>> rational = PinholeRadtan(640, 480, 500.0, 500.0, 319.5, 239.5, k1=-0.3, k2=0.1, k4=0.05, k5=0.01)
        >>> uv, _ = rational.project(np.array([[0.3, -0.2, 1.0]]))
        >>> bool(np.allclose(rational.unproject(uv), np.array([[0.3, -0.2, 1.0]]) / np.sqrt(1.13)))
        True
    """

    model = "pinhole_radtan"
    declaration = (
        *PINHOLE,
        *zeros("k1", "k2", "p1", "p2", "k3"),
        *zeros("k4", "k5", "k6", omit_default=True),
        FOV_DEG,
    )

    def _setup(self) -> None:
        self._rational = (self.k4, self.k5, self.k6)
        self._m_max = radial_limit(self.k1, self.k2, self.k3, *self._rational)
        coefficients = (self.k1, self.k2, self.p1, self.p2, self.k3, *self._rational)
        self._distorted = any(c != 0.0 for c in coefficients)
        self._undistort = RadtanInverse(
            self.k1, self.k2, self.p1, self.p2, self.k3, r_max=self._m_max, k4=self.k4, k5=self.k5, k6=self.k6
        )
        #: Largest incidence angle of the valid region (radians): where the distortion stops being one-to-one.
        self.theta_limit = math.atan(self._undistort.r_valid) if self._distorted else math.pi / 2

    def _project(self, x, y, z):
        mx, my = x / z, y / z
        in_region = z > 0
        if self._distorted:
            in_region &= mx.hypot(my) <= self._undistort.r_valid
            mx, my = radtan(mx, my, self.k1, self.k2, self.p1, self.p2, self.k3, *self._rational)
        return self.fx * mx + self.cx, self.fy * my + self.cy, in_region

    def _unproject(self, u, v):
        mx, my = (u - self.cx) / self.fx, (v - self.cy) / self.fy
        if self._distorted:
            mx, my = self._undistort(mx, my)
        return mx, my, mx * 0.0 + 1.0


__all__ = ["PinholeRadtan"]
