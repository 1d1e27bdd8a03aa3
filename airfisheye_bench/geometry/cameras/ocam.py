"""Scaramuzza's omnidirectional model (OCamCalib toolbox, ``calib_results.txt``; TartanAir V2's ``ocam``).

OCamCalib works in (row, column) image coordinates and a frame whose z axis points out of the back of the lens; in
this project's frame (x right, y down, z forward) its ``world2cam`` reads, with ``n = sqrt(x^2 + y^2)``:
``rho = world2cam(atan(-z / n))`` (``world2cam`` = OCamCalib's ``invpol``, lowest order first),
``X = rho x / n``, ``Y = rho y / n``, ``row = c Y + d X + cy``, ``col = e Y + X + cx``.
``cx`` is OCamCalib's ``yc`` (column) and ``cy`` its ``xc`` (row), in this project's pixel convention.
``cam2world`` (OCamCalib's ``ss``) is the calibrated back-projection; ``invpol`` is the toolbox's polynomial fit of
its inverse. ``project`` evaluates ``world2cam`` exactly as the toolbox does; ``unproject`` inverts that same
polynomial (bounded Newton, ``_solve.py``), so that the two are exact inverses of each other;
:meth:`Ocam.cam2world_rays` evaluates the toolbox's ``cam2world`` for comparison.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import torch

from airfisheye_bench.geometry.cameras._solve import MonotoneInverse, increasing_limit, polyder, polyval
from airfisheye_bench.geometry.cameras.base import CameraModel, finite_float, float_list, scaled_centre


class Ocam(CameraModel):
    """OCamCalib model: centre ``cx, cy``, affine ``c, d, e``, ``cam2world`` (ss) and ``world2cam`` (invpol).

    Example:
        >>> import numpy as np
        >>> cam = Ocam(64, 64, cx=31.5, cy=31.5, c=1.0, d=0.0, e=0.0, cam2world=[-20.0, 0.0, 0.001],
        ...            world2cam=[20.0, 12.7])
        >>> uv, valid = cam.project(np.array([[0.0, 0.0, 1.0]]))
        >>> uv.round(6).tolist(), valid.tolist()
        ([[31.5, 31.5]], [True])
    """

    model = "ocam"
    params: ClassVar[tuple[str, ...]] = ("cx", "cy", "c", "d", "e", "cam2world", "world2cam", "fov_deg")

    def __init__(
        self,
        width: int,
        height: int,
        cx: float,
        cy: float,
        c: float,
        d: float,
        e: float,
        cam2world: Any,
        world2cam: Any,
        fov_deg: float | None = None,
    ) -> None:
        super().__init__(width, height, fov_deg)
        self.cx, self.cy = finite_float("cx", cx), finite_float("cy", cy)
        self.c, self.d, self.e = finite_float("c", c), finite_float("d", d), finite_float("e", e)
        if self.c - self.d * self.e == 0:
            raise ValueError(
                f"the affine matrix [[c, d], [e, 1]] must be invertible, got c={c}, d={d}, e={e}"
            )
        self.cam2world = float_list("cam2world", cam2world, 2)
        self.world2cam = float_list("world2cam", world2cam, 2)
        self._dw2c = polyder(self.world2cam)
        #: Largest incidence angle up to which world2cam's radius increases (the model's valid region).
        self.theta_limit = increasing_limit(self._drho, math.pi)
        if self.theta_limit <= 0:
            raise ValueError("world2cam's radius does not increase away from the optical axis")
        self._inverse = MonotoneInverse(self._rho, self._drho, self.theta_limit)

    def _rho(self, theta: torch.Tensor) -> torch.Tensor:
        """Image radius (pixels, before the affine) at incidence angle ``theta`` from the optical axis."""
        return polyval(self.world2cam, theta - math.pi / 2)

    def _drho(self, theta: torch.Tensor) -> torch.Tensor:
        return polyval(self._dw2c, theta - math.pi / 2)

    def _affine(self, gx: torch.Tensor, gy: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(u, v)`` from the sensor-plane offsets (``gx`` along the columns, ``gy`` along the rows)."""
        return self.e * gy + gx + self.cx, self.c * gy + self.d * gx + self.cy

    def _sensor(self, u: torch.Tensor, v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Inverse of :meth:`_affine` (OCamCalib's ``cam2world`` first lines)."""
        dr, dc = v - self.cy, u - self.cx
        invdet = 1.0 / (self.c - self.d * self.e)
        return invdet * (-self.e * dr + self.c * dc), invdet * (dr - self.d * dc)

    def _project(self, x, y, z):
        n = torch.hypot(x, y)
        theta = torch.atan2(n, z)
        rho = self._rho(theta)
        s = rho / n.clamp_min(1e-300)
        on_axis = n == 0  # OCamCalib maps the axis to the centre
        gx, gy = torch.where(on_axis, 0.0, s * x), torch.where(on_axis, 0.0, s * y)
        u, v = self._affine(gx, gy)
        return u, v, theta <= self.theta_limit + 1e-12

    def _unproject(self, u, v):
        gx, gy = self._sensor(u, v)
        r = torch.hypot(gx, gy)
        lo, _ = self._inverse.y_range
        # world2cam is a fit: it may not pass exactly through 0 on the axis; radii below its value there look
        # along the axis.
        theta = torch.where(r <= lo, 0.0, self._inverse(r))
        s = torch.sin(theta) / r.clamp_min(1e-300)
        on_axis = r == 0
        return torch.where(on_axis, 0.0, s * gx), torch.where(on_axis, 0.0, s * gy), torch.cos(theta)

    def cam2world_rays(self, uv: torch.Tensor) -> torch.Tensor:
        """Unit rays ``[..., 3]`` (float64) of pixels by OCamCalib's own ``cam2world`` (the ``ss`` polynomial)."""
        uv = torch.as_tensor(uv, dtype=torch.float64)
        gx, gy = self._sensor(uv[..., 0], uv[..., 1])
        zp = polyval(self.cam2world, torch.hypot(gx, gy))
        rays = torch.stack([gx, gy, -zp], -1)  # OCamCalib's z looks backwards
        return rays / rays.norm(dim=-1, keepdim=True)

    def _scaled_params(self, sx: float, sy: float) -> dict[str, Any]:
        # Radii scale by s: rho'(theta) = s rho(theta) and r' = s r, so cam2world's a_i scale by s^(1 - i).
        return {
            **scaled_centre(self.cx, self.cy, sx, sy),
            "cam2world": [a * sx ** (1 - i) for i, a in enumerate(self.cam2world)],
            "world2cam": [b * sx for b in self.world2cam],
        }


__all__ = ["Ocam"]
