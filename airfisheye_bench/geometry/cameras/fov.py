"""FOV model (Devernay and Faugeras 2001, "Straight lines have to be straight"): COLMAP ``FOV``, the ATAN camera of
PTAM / DSO.

github:colmap/colmap ``src/colmap/sensor/models.h`` (``FOVCameraModel``): ``m = (x, y) / z``, ``r = |m|``,
``r_d = atan(2 r tan(omega / 2)) / omega``, ``u = fx m_x r_d / r + cx`` (v likewise). Valid in front of the camera
(``z > 0``, COLMAP's cheirality test); the back-projection is closed: ``r = tan(omega r_d) / (2 tan(omega / 2))``,
defined while ``omega r_d < pi / 2`` (the image of the whole half-space), NaN beyond. The map is even in ``omega``
and tends to the pinhole as ``omega -> 0``: ``0 < omega < pi`` here (readers map ``omega = 0`` to a pinhole).
"""

from __future__ import annotations

import math

import torch

from airfisheye_bench.geometry.cameras.base import CameraModel
from airfisheye_bench.geometry.cameras.params import FOV_DEG, PINHOLE, Param, interval


class Fov(CameraModel):
    """FOV / ATAN: ``fx, fy, cx, cy, omega`` (radians).

    Example:
        >>> import numpy as np
        >>> cam = Fov(772, 1022, fx=651.123, fy=655.123, cx=386.123, cy=511.123, omega=0.9)
        >>> uv, valid = cam.project(np.array([[0.4, -0.3, 1.0]]))
        >>> bool(valid[0]), bool(np.allclose(cam.unproject(uv), np.array([[0.4, -0.3, 1.0]]) / np.sqrt(1.25)))
        (True, True)
    """

    model = "fov"
    declaration = (
        *PINHOLE,
        Param("omega", check=interval(0.0, math.pi, open_lo=True, open_hi=True, text="(0, pi)")),
        FOV_DEG,
    )

    def _setup(self) -> None:
        self._two_tan = 2.0 * math.tan(self.omega / 2.0)

    def _project(self, x, y, z):
        rho = torch.hypot(x, y)
        # r_d / |(x, y)| as an angle, atan2 rather than atan(rho / z): exact for z -> 0+, and finite on the axis,
        # where it tends to 2 tan(omega / 2) / (omega z).
        scale = torch.where(
            rho > 0,
            torch.atan2(self._two_tan * rho, z) / (self.omega * rho),
            self._two_tan / (self.omega * z),
        )
        return self.fx * x * scale + self.cx, self.fy * y * scale + self.cy, z > 0

    def _unproject(self, u, v):
        mx, my = (u - self.cx) / self.fx, (v - self.cy) / self.fy
        angle = self.omega * torch.hypot(mx, my)  # omega r_d: the lens's angle, below pi / 2 in front of it
        # z = r_d / r (any positive length), from r = tan(omega r_d) / (2 tan(omega / 2)): no division on the axis.
        safe = torch.where(angle > 0, angle, 1.0)
        mz = torch.where(
            angle > 0, self._two_tan * safe / (self.omega * torch.tan(safe)), self._two_tan / self.omega
        )
        mz = torch.where(angle < math.pi / 2, mz, torch.nan)
        return mx, my, mz


__all__ = ["Fov"]
