"""Double Sphere camera model (Usenko, Demmel and Cremers, 3DV 2018): basalt ``ds``, Kalibr ``ds``, TartanAir V2.

Projection and its valid region, back-projection and its valid region in closed form, as in basalt's
``include/basalt/camera/double_sphere_camera.hpp``:
``d1 = |p|``, ``d2 = |(x, y, xi d1 + z)|``, ``u = fx x / (alpha d2 + (1 - alpha)(xi d1 + z)) + cx`` (v likewise),
valid where ``z > -w2 d1``; back-projection valid where ``alpha <= 0.5`` or ``r^2 < 1 / (2 alpha - 1)``, and (unlike
basalt) only where its ray lies in the projection's region, so that the two agree on every pixel.
"""

from __future__ import annotations

import math

import torch

from airfisheye_bench.geometry.cameras.base import CameraModel
from airfisheye_bench.geometry.cameras.params import FOV_DEG, PINHOLE, Param, interval


class DoubleSphere(CameraModel):
    """Double Sphere: ``fx, fy, cx, cy, xi, alpha``.

    Example:
        >>> import numpy as np
        >>> cam = DoubleSphere(512, 512, fx=158.286, fy=158.274, cx=254.961, cy=256.889, xi=-0.1721, alpha=0.5931)
        >>> uv, valid = cam.project(np.array([[1.0, 0.0, -0.2]]))  # 101 deg off-axis
        >>> bool(valid[0]), bool(np.allclose(cam.unproject(uv), np.array([[1.0, 0.0, -0.2]]) / np.hypot(1, 0.2)))
        (True, True)
    """

    model = "double_sphere"
    declaration = (*PINHOLE, Param("xi"), Param("alpha", check=interval(0.0, 1.0)), FOV_DEG)

    def _setup(self) -> None:
        w1 = (1.0 - self.alpha) / self.alpha if self.alpha > 0.5 else self.alpha / (1.0 - self.alpha)
        self._w2 = (w1 + self.xi) / math.sqrt(2.0 * w1 * self.xi + self.xi * self.xi + 1.0)

    def _project(self, x, y, z):
        r2 = x * x + y * y
        d1 = torch.sqrt(r2 + z * z)
        k = self.xi * d1 + z
        d2 = torch.sqrt(r2 + k * k)
        norm = self.alpha * d2 + (1.0 - self.alpha) * k
        return self.fx * x / norm + self.cx, self.fy * y / norm + self.cy, z > -self._w2 * d1

    def _unproject(self, u, v):
        mx, my = (u - self.cx) / self.fx, (v - self.cy) / self.fy
        r2 = mx * mx + my * my
        a, xi = self.alpha, self.xi
        mz = (1.0 - a * a * r2) / (a * torch.sqrt(1.0 - (2.0 * a - 1.0) * r2) + 1.0 - a)
        k = (mz * xi + torch.sqrt(mz * mz + (1.0 - xi * xi) * r2)) / (mz * mz + r2)
        x, y, z = k * mx, k * my, k * mz - xi
        ok = z > -self._w2 * torch.sqrt(x * x + y * y + z * z)
        if a > 0.5:
            # basalt's back-projection condition; past the projection's region (z > -w2 d1) the formula still
            # gives rays for a thin ring of pixels (up to 1 deg wide): no ray there, as project() says.
            ok &= r2 < 1.0 / (2.0 * a - 1.0)
        return tuple(torch.where(ok, c, torch.nan) for c in (x, y, z))


__all__ = ["DoubleSphere"]
