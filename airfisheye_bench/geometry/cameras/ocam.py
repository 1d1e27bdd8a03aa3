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

``invpol`` is fitted only over the calibration's data (OCamCalib's ``findinvpoly``: up to the image's half diagonal);
a long fit may turn back or blow up beyond, and its value on the axis may be slightly negative. The valid region is
therefore found from the polynomial itself: from ``theta_start`` (where ``rho`` turns >= 0; 0 for most fits) to
``theta_limit`` (where ``rho`` stops increasing, or leaves the frame ``FAR_FRAME`` image sizes around the image),
never a nominal 180 deg; ``unproject`` is NaN outside it.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from airfisheye_bench.geometry.cameras._solve import (
    FAR_FRAME,
    PIXEL_TOL,
    MonotoneInverse,
    frame_reach,
    increasing_limit,
    polyder,
    polyval,
)
from airfisheye_bench.geometry.cameras.base import CameraModel
from airfisheye_bench.geometry.cameras.params import CX, CY, FOV_DEG, Param, numbers


def _scaled_cam2world(cam2world: tuple[float, ...], sx: float, sy: float) -> list[float]:
    # Radii scale by s: rho'(theta) = s rho(theta) and r' = s r, so cam2world's a_i scale by s^(1 - i).
    return [a * sx ** (1 - i) for i, a in enumerate(cam2world)]


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
    declaration = (
        CX,
        CY,
        Param("c"),
        Param("d"),
        Param("e"),
        Param("cam2world", check=numbers(2), scale=_scaled_cam2world),
        Param("world2cam", check=numbers(2), scale="fx"),  # radii in pixels
        FOV_DEG,
    )

    def _setup(self) -> None:
        if self.c - self.d * self.e == 0:
            raise ValueError(
                f"the affine matrix [[c, d], [e, 1]] must be invertible, got c={self.c}, d={self.d}, e={self.e}"
            )
        self._dw2c = polyder(self.world2cam)
        # The valid region is where world2cam is invertible: from where its radius is >= 0 (a fit may give a
        # slightly negative radius on the axis, which would mirror a ray to the far side of the centre) to where
        # it stops increasing or leaves the frame FAR_FRAME image sizes around the image (a long fit may blow up
        # past its calibration's data). Not a nominal 180 deg.
        monotone = increasing_limit(self._drho, math.pi, poly=self._dw2c, shift=math.pi / 2)
        if monotone <= 0:
            raise ValueError("world2cam's radius does not increase away from the optical axis")
        #: Smallest incidence angle > 0 of the valid region (0 unless world2cam is negative on the axis).
        self.theta_start = self._zero_crossing(monotone)
        affine_norm = float(np.linalg.norm(np.array([[1.0, self.e], [self.d, self.c]]), 2))
        self._inverse = MonotoneInverse(
            self._rho,
            self._drho,
            monotone,
            y_cap=frame_reach(self._sensor, self.width, self.height, FAR_FRAME),
            t_lo=self.theta_start,
            y_near=frame_reach(self._sensor, self.width, self.height, 1.0),
            tol=PIXEL_TOL / max(1.0, affine_norm),
        )
        #: Largest incidence angle of the valid region (radians).
        self.theta_limit = self._inverse.t_hi

    def _zero_crossing(self, hi: float) -> float:
        """The incidence angle in ``[0, hi]`` where world2cam's radius (increasing there) turns >= 0."""
        if self._rho(torch.zeros(1, dtype=torch.float64))[0] >= 0:
            return 0.0
        if self._rho(torch.tensor([hi], dtype=torch.float64))[0] <= 0:
            raise ValueError(
                "world2cam's radius stays negative wherever it increases: no ray reaches the image"
            )
        lo = 0.0
        for _ in range(80):  # bisection: rho(lo) < 0 < rho(hi)
            mid = 0.5 * (lo + hi)
            if mid in (lo, hi):
                break
            if self._rho(torch.tensor([mid], dtype=torch.float64))[0] < 0:
                lo = mid
            else:
                hi = mid
        return hi

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
        # The axis maps to the centre; other rays below theta_start would land mirrored (negative radius).
        in_region = (theta <= self.theta_limit + 1e-12) & ((theta >= self.theta_start) | on_axis)
        return u, v, in_region

    def _unproject(self, u, v):
        gx, gy = self._sensor(u, v)
        r = torch.hypot(gx, gy)
        # NaN beyond the valid region, and below world2cam's radius at theta_start (a fit's value on the axis, a
        # fraction of a pixel): no ray lands there. The centre itself is the axis.
        on_axis = r == 0
        theta = torch.where(on_axis, 0.0, self._inverse(r))
        s = torch.sin(theta) / r.clamp_min(1e-300)
        return torch.where(on_axis, 0.0, s * gx), torch.where(on_axis, 0.0, s * gy), torch.cos(theta)

    def cam2world_rays(self, uv: torch.Tensor) -> torch.Tensor:
        """Unit rays ``[..., 3]`` (float64) of pixels by OCamCalib's own ``cam2world`` (the ``ss`` polynomial)."""
        uv = torch.as_tensor(uv, dtype=torch.float64)
        gx, gy = self._sensor(uv[..., 0], uv[..., 1])
        zp = polyval(self.cam2world, torch.hypot(gx, gy))
        rays = torch.stack([gx, gy, -zp], -1)  # OCamCalib's z looks backwards
        return rays / rays.norm(dim=-1, keepdim=True)


__all__ = ["Ocam"]
