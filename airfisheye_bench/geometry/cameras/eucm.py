"""Extended Unified camera model (Khomutenko, Garcia and Martinet, RA-L 2016): basalt ``eucm``, Kalibr ``eucm``.

Closed forms as in basalt's ``include/basalt/camera/extended_camera.hpp``: ``rho = sqrt(beta (x^2 + y^2) + z^2)``,
``u = fx x / (alpha rho + (1 - alpha) z) + cx`` (v likewise), valid where ``z > -w rho``; back-projection
``(m_x, m_y, (1 - alpha^2 beta r^2) / (alpha sqrt(1 - (2 alpha - 1) beta r^2) + 1 - alpha))``, valid where
``alpha <= 0.5`` or ``r^2 < 1 / ((2 alpha - 1) beta)``.
"""

from __future__ import annotations

import torch

from airfisheye_bench.geometry.cameras.base import CameraModel
from airfisheye_bench.geometry.cameras.params import FOV_DEG, PINHOLE, Param, interval, positive


class EUCM(CameraModel):
    """Extended Unified: ``fx, fy, cx, cy, alpha, beta``.

    Example:
        >>> import numpy as np
        >>> cam = EUCM(512, 512, fx=191.148, fy=191.132, cx=254.959, cy=256.882, alpha=0.6291, beta=1.0418)
        >>> uv, valid = cam.project(np.array([[1.0, 0.5, -0.2]]))
        >>> bool(valid[0]), bool(np.allclose(cam.unproject(uv), np.array([[1.0, 0.5, -0.2]]) / np.sqrt(1.29)))
        (True, True)
    """

    model = "eucm"
    declaration = (*PINHOLE, Param("alpha", check=interval(0.0, 1.0)), Param("beta", check=positive), FOV_DEG)

    def _setup(self) -> None:
        self._w = (1.0 - self.alpha) / self.alpha if self.alpha > 0.5 else self.alpha / (1.0 - self.alpha)

    def _project(self, x, y, z):
        rho = torch.sqrt(self.beta * (x * x + y * y) + z * z)
        norm = self.alpha * rho + (1.0 - self.alpha) * z
        return self.fx * x / norm + self.cx, self.fy * y / norm + self.cy, z > -self._w * rho

    def _unproject(self, u, v):
        mx, my = (u - self.cx) / self.fx, (v - self.cy) / self.fy
        r2 = mx * mx + my * my
        a, b = self.alpha, self.beta
        mz = (1.0 - a * a * b * r2) / (a * torch.sqrt(1.0 - (2.0 * a - 1.0) * b * r2) + 1.0 - a)
        if a > 0.5:
            mz = torch.where(r2 < 1.0 / ((2.0 * a - 1.0) * b), mz, torch.nan)
        return mx, my, mz


__all__ = ["EUCM"]
