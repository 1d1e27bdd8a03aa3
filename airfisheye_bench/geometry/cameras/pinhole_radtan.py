"""Pinhole with OpenCV's radial-tangential distortion (plumb_bob: ``k1, k2, p1, p2, k3``): the perspective
baseline, ROS ``plumb_bob``, Kalibr ``pinhole-radtan``, and the cube faces (``fx = fy = S / 2``, no distortion).

``m = (x, y) / z`` distorted as in OpenCV's ``projectPoints``; valid in front of the camera (``z > 0``) while the
distortion is one-to-one (the radial factor increases and the tangential terms do not fold it; ``_solve.py``'s
``RadtanInverse.r_valid``); back-projection by bounded Newton steps on the distortion (``_solve.py``).
"""

from __future__ import annotations

from airfisheye_bench.geometry.cameras._solve import RadtanInverse, radial_limit, radtan
from airfisheye_bench.geometry.cameras.base import CameraModel
from airfisheye_bench.geometry.cameras.params import FOV_DEG, PINHOLE, zeros


class PinholeRadtan(CameraModel):
    """Pinhole camera, OpenCV distortion order ``k1, k2, p1, p2, k3``.

    Example:
        >>> import numpy as np
        >>> cam = PinholeRadtan(640, 480, fx=500.0, fy=500.0, cx=319.5, cy=239.5)
        >>> uv, valid = cam.project(np.array([[0.1, -0.2, 1.0], [0.0, 0.0, -1.0]]))
        >>> uv[0].tolist(), valid.tolist()
        ([369.5, 139.5], [True, False])
    """

    model = "pinhole_radtan"
    declaration = (*PINHOLE, *zeros("k1", "k2", "p1", "p2", "k3"), FOV_DEG)

    def _setup(self) -> None:
        self._m_max = radial_limit(self.k1, self.k2, self.k3)
        self._distorted = any(c != 0.0 for c in (self.k1, self.k2, self.p1, self.p2, self.k3))
        self._undistort = RadtanInverse(self.k1, self.k2, self.p1, self.p2, self.k3, r_max=self._m_max)

    def _project(self, x, y, z):
        mx, my = x / z, y / z
        in_region = z > 0
        if self._distorted:
            in_region &= mx.hypot(my) <= self._undistort.r_valid
            mx, my = radtan(mx, my, self.k1, self.k2, self.p1, self.p2, self.k3)
        return self.fx * mx + self.cx, self.fy * my + self.cy, in_region

    def _unproject(self, u, v):
        mx, my = (u - self.cx) / self.fx, (v - self.cy) / self.fy
        if self._distorted:
            mx, my = self._undistort(mx, my)
        return mx, my, mx * 0.0 + 1.0


__all__ = ["PinholeRadtan"]
