"""Fitzgibbon's one-parameter division model (2001, "Simultaneous linear estimation of multiple view geometry and
lens distortion"): COLMAP ``SIMPLE_DIVISION`` (``f, cx, cy, k``) and ``DIVISION`` (``fx, fy, cx, cy, k``).

github:colmap/colmap ``src/colmap/sensor/models.h`` (``DivisionCameraModel``): a pixel's normalised point ``m``
(``u = fx m_x + cx``, ``v = fy m_y + cy``, ``t = |m|``) is the ray ``(m_x, m_y, 1 + k t^2)`` (``CamFromImg``);
``ImgFromCam`` inverts it with the smaller root of ``k rho t^2 - z t + rho = 0`` (``rho = |(x, y)|``):
``t / rho = 2 / (z + sqrt(z^2 - 4 k rho^2))``.

- ``k < 0`` (barrel): ``theta`` increases with ``t`` all the way to 180 deg (``1 + k t^2`` turns negative past
  ``t = 1 / sqrt(-k)``, 90 deg), so every ray but the back axis projects, as COLMAP's ``ImgFromCam`` (which has no
  cheirality test) projects them. Behind the camera its root is computed as ``(sqrt(...) - z) / (-2 k rho^2)``, the
  same value without the cancellation. COLMAP's ``CamFromImg`` returns ``m / (1 + k t^2)`` on the plane ``z = 1``,
  which past 90 deg is the opposite ray; the ray here is the one ``ImgFromCam`` maps to the pixel.
- ``k >= 0``: in front of the camera while the root is real, ``4 k rho^2 <= z^2`` (``t <= 1 / sqrt(k)``, where
  ``t / (1 + k t^2)`` stops increasing); pixels beyond it have no ray (COLMAP's ray for them projects elsewhere).
  ``k = 0`` is the pinhole.
"""

from __future__ import annotations

import torch

from airfisheye_bench.geometry.cameras.base import CameraModel
from airfisheye_bench.geometry.cameras.params import FOV_DEG, PINHOLE, Param


class Division(CameraModel):
    """Division model: ``fx, fy, cx, cy, k`` (``k`` on the normalised plane, as COLMAP's).

    Example:
        >>> import numpy as np
        >>> cam = Division(772, 1022, fx=651.123, fy=655.123, cx=386.123, cy=511.123, k=-0.1)
        >>> uv, valid = cam.project(np.array([[0.4, -0.3, 1.0], [0.4, -0.3, -1.0]]))  # the second behind the camera
        >>> valid.tolist(), bool(np.allclose(cam.unproject(uv)[1], np.array([0.4, -0.3, -1.0]) / np.sqrt(1.25)))
        ([True, True], True)
    """

    model = "division"
    declaration = (*PINHOLE, Param("k", distortion=True), FOV_DEG)

    def _project(self, x, y, z):
        rho2 = x * x + y * y
        disc2 = z * z - 4.0 * self.k * rho2
        disc = torch.sqrt(disc2.clamp_min(0.0))
        scale = 2.0 / (z + disc)  # t / rho
        if self.k < 0:
            in_region = torch.ones_like(z, dtype=torch.bool)
            scale = torch.where(z >= 0, scale, (disc - z) / (-2.0 * self.k * rho2))
        else:
            # At the fold (t = 1 / sqrt(k)) disc2 is 0 up to rounding: a relative 1e-12 is let in, at the fold.
            in_region = (z > 0) & (disc2 >= -1e-12 * z * z)
        return self.fx * scale * x + self.cx, self.fy * scale * y + self.cy, in_region

    def _unproject(self, u, v):
        mx, my = (u - self.cx) / self.fx, (v - self.cy) / self.fy
        kt2 = self.k * (mx * mx + my * my)
        mz = torch.where(kt2 <= 1.0, 1.0 + kt2, torch.nan) if self.k > 0 else 1.0 + kt2
        return mx, my, mz


__all__ = ["Division"]
