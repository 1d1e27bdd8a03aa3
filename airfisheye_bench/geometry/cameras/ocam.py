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
a long fit may turn back or blow up beyond. The valid region is therefore found from the polynomial itself: up to
``theta_limit`` (where ``rho`` stops increasing, or leaves the frame ``FAR_FRAME`` image sizes around the image),
never a nominal 180 deg; ``unproject`` is NaN beyond it. The axis is the fit's other end, and there its radius is
often a little off (a fraction of a pixel to a few pixels, either sign, sometimes first decreasing; the coefficients
are also rounded to six decimals), where the lens's is 0 and increasing: up to ``theta_head`` the model follows the
chord from the principal point to the fit (``_solve.origin_chord``: about as far from the fit as the fit is from a
lens there), so the radius increases from the axis, which maps to the centre, and every pixel near the centre has
its ray. The terms in ``theta - pi/2`` are also largest on the axis, where a long fit's may cancel from 1e12 px to a
few pixels: there ``unproject`` is exact to the polynomial's own float64 rounding (``_solve.polyval_error``), no
further (the toolbox's own ``world2cam`` is no more exact there).
"""

from __future__ import annotations

import math

import numpy as np
import torch

from airfisheye_bench.geometry.cameras._solve import (
    PIXEL_TOL,
    OriginChord,
    image_inverse,
    increasing_limit,
    increasing_start,
    origin_chord,
    polyder,
    polyval,
    polyval_error,
)
from airfisheye_bench.geometry.cameras.base import CameraModel, ray_at_incidence
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
        # The valid region is where world2cam is invertible: from where its radius first increases to where it stops
        # increasing or leaves the frame FAR_FRAME image sizes around the image (a long fit may blow up past its
        # calibration's data). Not a nominal 180 deg.
        no_lens = "world2cam's radius does not increase away from the optical axis"
        start = increasing_start(self._drho_fit, math.pi)
        if start is None:
            raise ValueError(no_lens)
        monotone = increasing_limit(self._drho_fit, math.pi, lo=start, poly=self._dw2c, shift=math.pi / 2)
        if monotone <= start:
            raise ValueError(no_lens)
        #: Incidence angle (radians) up to which the model follows the chord from the principal point instead of
        #: world2cam (0 where world2cam is 0 on the axis and increases from it).
        self.theta_head = self._head(start, monotone)
        chord = OriginChord(self._rho_fit, self._drho_fit, self.theta_head)
        self._rho, self._drho = chord, chord.derivative
        affine_norm = float(np.linalg.norm(np.array([[1.0, self.e], [self.d, self.c]]), 2))
        self._inverse = image_inverse(
            self._rho,
            self._drho,
            monotone,
            self._sensor,
            self.width,
            self.height,
            tol=PIXEL_TOL / max(1.0, affine_norm),
            f_err=self._rho_err,
        )
        #: Largest incidence angle of the valid region (radians).
        self.theta_limit = self._inverse.t_hi

    def _head(self, start: float, monotone: float) -> float:
        """:attr:`theta_head`; ``ValueError`` where the chord would reach beyond a quarter of the image's shorter
        side (world2cam is then no calibration of a lens near its axis)."""
        rho0 = float(self._rho_fit(torch.zeros(1, dtype=torch.float64))[0])
        try:
            head = origin_chord(self._rho_fit, start, monotone)
        except ValueError as err:
            raise ValueError(f"world2cam is {rho0:.4g} px on the optical axis and {err}") from None
        reach = float(self._rho_fit(torch.tensor([head], dtype=torch.float64))[0])
        if reach > min(self.width, self.height) / 4:
            raise ValueError(
                f"world2cam's radius is {rho0:.4g} px on the optical axis (a lens's is 0) and first increases from "
                f"{math.degrees(start):.3g} deg: the model would bridge it to {reach:.4g} px from the principal "
                f"point, more than a quarter of the image's shorter side; check the calibration"
            )
        return head

    def _rho_fit(self, theta: torch.Tensor) -> torch.Tensor:
        """world2cam's image radius (pixels, before the affine) at incidence angle ``theta`` from the optical axis;
        the model's (``_rho``) follows the chord from the principal point below :attr:`theta_head`."""
        return polyval(self.world2cam, theta - math.pi / 2)

    def _drho_fit(self, theta: torch.Tensor) -> torch.Tensor:
        return polyval(self._dw2c, theta - math.pi / 2)

    def _rho_err(self, theta: torch.Tensor) -> torch.Tensor:
        """A bound on float64's rounding of :meth:`_rho_fit` (its terms are largest, and may cancel, on the axis)."""
        return polyval_error(self.world2cam, theta - math.pi / 2)

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
        on_axis = n == 0  # OCamCalib maps the axis to the centre (so does the chord)
        gx, gy = torch.where(on_axis, 0.0, s * x), torch.where(on_axis, 0.0, s * y)
        u, v = self._affine(gx, gy)
        return u, v, theta <= self.theta_limit + 1e-12

    def _unproject(self, u, v):
        gx, gy = self._sensor(u, v)
        r = torch.hypot(gx, gy)
        # NaN beyond the valid region only: the radius increases from 0 on the axis (the chord below theta_head).
        on_axis = r == 0
        theta = torch.where(on_axis, 0.0, self._inverse(r))
        return ray_at_incidence(theta, gx, gy, r)

    def cam2world_rays(self, uv: torch.Tensor) -> torch.Tensor:
        """Unit rays ``[..., 3]`` (float64) of pixels by OCamCalib's own ``cam2world`` (the ``ss`` polynomial)."""
        uv = torch.as_tensor(uv, dtype=torch.float64)
        gx, gy = self._sensor(uv[..., 0], uv[..., 1])
        zp = polyval(self.cam2world, torch.hypot(gx, gy))
        rays = torch.stack([gx, gy, -zp], -1)  # OCamCalib's z looks backwards
        return rays / rays.norm(dim=-1, keepdim=True)


__all__ = ["Ocam"]
