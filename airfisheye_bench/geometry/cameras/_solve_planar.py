"""Vectorised, bounded inverses of distortions of the image plane, for the models without a closed-form
back-projection (the 1-D pieces they start from are :mod:`._solve`'s).

- :class:`RadtanInverse`: invert OpenCV's radial-tangential distortion (plumb_bob, or the rational model's radial
  factor, :func:`radial_factor`): the radial part first, then Newton steps on the 2x2 system for the tangential
  terms, each point until it converges (at most 40; a numba loop on CPU), NaN where the result does not reproduce
  the input.
- :class:`DiscInverse`: invert a near-radial distortion of the plane (COLMAP's thin-prism fisheye models) on the disc
  where it is one-to-one (:func:`one_to_one_radius`): a start from its radial part's inverse, then Newton steps in a
  trust region, halved until they shrink the residual (steepest descent where no Newton step does), NaN where the
  result does not reproduce the input or leaves the disc.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import torch

from airfisheye_bench.geometry import numba_kernels
from airfisheye_bench.geometry.cameras._solve import (
    MonotoneInverse,
)


def radial_factor(
    r2: torch.Tensor,
    k1: float,
    k2: float,
    k3: float = 0.0,
    k4: float = 0.0,
    k5: float = 0.0,
    k6: float = 0.0,
) -> tuple[torch.Tensor, torch.Tensor]:
    """OpenCV's radial factor ``g = (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)`` of ``r2 = r^2``
    and ``2 dg/d(r^2)``; without k4..k6 (plumb_bob) the numerator alone, evaluated as it always was."""
    g = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    dg = 2.0 * (k1 + r2 * (2.0 * k2 + r2 * 3.0 * k3))
    if k4 or k5 or k6:  # the rational model (CALIB_RATIONAL_MODEL, COLMAP's FULL_OPENCV)
        den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
        d_den = 2.0 * (k4 + r2 * (2.0 * k5 + r2 * 3.0 * k6))
        g = g / den
        dg = (dg - g * d_den) / den
    return g, dg


def radtan(
    x: torch.Tensor,
    y: torch.Tensor,
    k1: float,
    k2: float,
    p1: float,
    p2: float,
    k3: float = 0.0,
    k4: float = 0.0,
    k5: float = 0.0,
    k6: float = 0.0,
) -> tuple[torch.Tensor, torch.Tensor]:
    """OpenCV's radial-tangential distortion of normalised coordinates (plumb_bob; with k4..k6 the rational model)."""
    r2 = x * x + y * y
    if k4 or k5 or k6:
        radial, _ = radial_factor(r2, k1, k2, k3, k4, k5, k6)
    else:
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xy = x * y
    xd = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy
    return xd, yd


def radial_limit(
    k1: float, k2: float, k3: float = 0.0, k4: float = 0.0, k5: float = 0.0, k6: float = 0.0
) -> float:
    """Largest undistorted radius up to which ``r g(r^2)`` increases (inf if always); ``g`` is
    :func:`radial_factor`'s, whose denominator's first zero (a pole) ends it too."""
    if not (k4 or k5 or k6):
        # d/dr = 1 + 3 k1 s + 5 k2 s^2 + 7 k3 s^3 with s = r^2: its smallest positive real root, if any.
        coeffs = np.trim_zeros(np.array([7.0 * k3, 5.0 * k2, 3.0 * k1, 1.0]), "f")
        roots = np.roots(coeffs) if len(coeffs) > 1 else np.array([])
        positive = [r.real for r in roots if abs(r.imag) <= 1e-12 * max(1.0, abs(r)) and r.real > 0]
        return math.sqrt(min(positive)) if positive else math.inf
    # g = N / D in s = r^2: d(r g)/dr = (N D + 2 s (N' D - N D')) / D^2, whose sign is its numerator's.
    P = np.polynomial.Polynomial
    num, den, s = P([1.0, k1, k2, k3]), P([1.0, k4, k5, k6]), P([0.0, 1.0])
    slope = num * den + 2.0 * s * (num.deriv() * den - num * den.deriv())
    return math.sqrt(min(_first_positive_root(slope.coef), _first_positive_root(den.coef)))


def _first_positive_root(coeffs: np.ndarray) -> float:
    """Smallest positive real root of a polynomial (coefficients lowest order first), inf if none."""
    coeffs = np.trim_zeros(np.asarray(coeffs, dtype=np.float64), "b")
    roots = np.polynomial.polynomial.polyroots(coeffs) if len(coeffs) > 1 else np.array([])
    positive = [r.real for r in roots if abs(r.imag) <= 1e-12 * max(1.0, abs(r)) and r.real > 0]
    return min(positive) if positive else math.inf


def _circles(r: torch.Tensor, azimuths: int = 128) -> tuple[torch.Tensor, torch.Tensor]:
    """``(x, y) [len(r), azimuths]``: points spread evenly over the circle of each radius ``r``."""
    a = torch.linspace(0.0, 2.0 * math.pi, azimuths + 1, dtype=torch.float64)[:-1]
    return r[:, None] * torch.cos(a), r[:, None] * torch.sin(a)


def one_to_one_radius(
    min_det: Callable[[torch.Tensor], torch.Tensor], hi: float, samples: int = 256
) -> float:
    """Largest radius ``<= hi`` whose disc has a positive Jacobian determinant everywhere (a near-radial map whose
    boundary circle maps to a simple curve: one-to-one there). ``min_det(r)``: the determinant's smallest value
    over the circle of each radius; the first radius of ``samples`` where it is not positive is narrowed down by
    bisection."""
    r = torch.linspace(0.0, hi, samples + 1, dtype=torch.float64)[1:]
    bad = (~(min_det(r) > 0)).nonzero()
    if not len(bad):
        return hi
    i = int(bad[0, 0])
    a, b = (float(r[i - 1]) if i else 0.0), float(r[i])
    for _ in range(50):  # bisection on the first sign change
        mid = 0.5 * (a + b)
        if bool(min_det(torch.tensor([mid], dtype=torch.float64))[0] > 0):
            a = mid
        else:
            b = mid
    return a


class RadtanInverse:
    """Invert :func:`radtan` (plumb_bob or rational): the radial part by :class:`MonotoneInverse` on the radius, then
    Newton steps on the 2x2 system (analytic Jacobian) for the tangential terms, on the points not yet converged. NaN
    where the result does not reproduce the distorted point or lies beyond ``r_valid``.

    ``r_valid`` is the largest undistorted radius of the disc on which the distortion is one-to-one, so that a
    distorted point has one undistorted point in it, not two: the radius ``r g(r^2)`` still increases, short of any
    pole of the rational denominator (``r_max``, :func:`radial_limit`), the Jacobian's determinant stays positive at
    every azimuth (the tangential terms fold the map a little before ``r_max``), and the distorted radius stays
    within ``r_cap``. The camera models' valid regions end there too.

    Args:
        k1, k2, p1, p2, k3: OpenCV's plumb_bob coefficients.
        r_max: Largest undistorted radius where the radius ``r g(r^2)`` increases (:func:`radial_limit`).
        r_cap: Largest distorted radius solved for (normalised units; 10 is 84 deg off-axis for a pinhole).
        k4, k5, k6: The rational model's denominator (:func:`radial_factor`); 0: plumb_bob.
    """

    def __init__(
        self,
        k1: float,
        k2: float,
        p1: float,
        p2: float,
        k3: float = 0.0,
        r_max: float = math.inf,
        r_cap: float = 10.0,
        k4: float = 0.0,
        k5: float = 0.0,
        k6: float = 0.0,
    ) -> None:
        self.k = (k1, k2, p1, p2, k3)
        self.rational = (k4, k5, k6)
        self.r_max = r_max

        def f(r: torch.Tensor) -> torch.Tensor:  # r (1 + k1 r^2 + k2 r^4 + k3 r^6)
            s = r * r
            return r * (1.0 + s * (k1 + s * (k2 + s * k3)))

        def df(r: torch.Tensor) -> torch.Tensor:
            s = r * r
            return 1.0 + s * (3.0 * k1 + s * (5.0 * k2 + s * 7.0 * k3))

        if any(self.rational):

            def f(r: torch.Tensor) -> torch.Tensor:  # r g(r^2)
                return r * radial_factor(r * r, k1, k2, k3, k4, k5, k6)[0]

            def df(r: torch.Tensor) -> torch.Tensor:  # g + r^2 (2 dg/d(r^2))
                s = r * r
                g, dg = radial_factor(s, k1, k2, k3, k4, k5, k6)
                return g + s * dg

        t_hi = min(r_max, 1e3)
        if any(self.rational):
            # Short of a pole of the denominator (where r_max may end): rounding may put its root on the far side,
            # where the radius is hugely negative. The radius is far beyond r_cap there anyway.
            t_hi *= 1.0 - 1e-6
        self._radial = MonotoneInverse(f, df, t_hi, y_cap=r_cap)
        self._radial_cap = r_cap
        self.r_valid = self._one_to_one_radius(self._radial.t_hi)

    def _min_det(self, r: torch.Tensor) -> torch.Tensor:
        """Smallest determinant of :func:`radtan`'s Jacobian over the circle of each radius ``r``."""
        x, y = _circles(r)
        j11, j12, j22 = self._jacobian(x, y)
        return (j11 * j22 - j12 * j12).min(dim=1).values

    def _one_to_one_radius(self, hi: float) -> float:
        """Largest radius ``<= hi`` whose disc has a positive Jacobian determinant everywhere."""
        if not any(self.k[2:4]):
            return hi  # radial only: the determinant is f(r) f'(r) / r, positive up to r_max
        return one_to_one_radius(self._min_det, hi)

    def __call__(
        self, xd: torch.Tensor, yd: torch.Tensor, max_steps: int = 40, fused: bool = True
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Undistort flat ``[N]`` coordinates: on CPU (``fused``) a numba loop takes each point until it converges;
        otherwise each masked torch step runs only on the points not yet converged."""
        k1, k2, p1, p2, k3 = self.k
        k4, k5, k6 = self.rational
        distorted = any(self.k) or any(self.rational)
        rd = torch.hypot(xd, yd)
        # The table's interpolation alone starts within ~1e-7; the 2x2 Newton steps below polish the radial part
        # together with the tangential one. The tangential terms can carry a point inside r_max past the radial
        # part's largest radius: such a point starts from r_max (the check below still decides).
        _, radial_hi = self._radial.y_range
        rd_start = torch.where(rd <= self._radial_cap, rd.clamp(max=radial_hi), rd)
        scale = self._radial(rd_start, steps=0) / rd.clamp_min(1e-300)
        x, y = torch.where(rd == 0, xd, xd * scale), torch.where(rd == 0, yd, yd * scale)
        if distorted and fused and x.device.type == "cpu":
            # One fused loop, each point until it converges (several times faster than the masked steps below).
            xn, yn = x.numpy(), y.numpy()
            xdn, ydn = xd.contiguous().numpy(), yd.contiguous().numpy()
            numba_kernels.newton_radtan(xn, yn, xdn, ydn, k1, k2, p1, p2, k3, k4, k5, k6, 40)
        elif distorted:
            active = None  # all points
            for _ in range(max_steps):
                xa, ya = (x, y) if active is None else (x[active], y[active])
                xda, yda = (xd, yd) if active is None else (xd[active], yd[active])
                fx, fy = radtan(xa, ya, k1, k2, p1, p2, k3, k4, k5, k6)
                ex, ey = fx - xda, fy - yda
                todo = ((ex.abs() > 1e-15) | (ey.abs() > 1e-15)) & torch.isfinite(ex) & torch.isfinite(ey)
                if not bool(todo.any()):
                    break
                idx = todo.nonzero().squeeze(1)
                active = idx if active is None else active[idx]
                xn, yn = self._step(xa[idx], ya[idx], ex[idx], ey[idx])
                x[active], y[active] = xn, yn
        fx, fy = radtan(x, y, k1, k2, p1, p2, k3, k4, k5, k6)
        tol = 1e-9 * (1.0 + rd)
        ok = ((fx - xd).abs() <= tol) & ((fy - yd).abs() <= tol) & (torch.hypot(x, y) <= self.r_valid)
        return torch.where(ok, x, torch.nan), torch.where(ok, y, torch.nan)

    def _jacobian(self, x, y):
        """``(j11, j12, j22)`` of :func:`radtan`'s (symmetric) Jacobian at ``(x, y)``."""
        k1, k2, p1, p2, k3 = self.k
        r2 = x * x + y * y
        radial, d_radial = radial_factor(r2, k1, k2, k3, *self.rational)  # and 2 d(radial)/d(r^2)
        j11 = radial + x * x * d_radial + 2.0 * p1 * y + 6.0 * p2 * x
        j12 = x * y * d_radial + 2.0 * p1 * x + 2.0 * p2 * y
        j22 = radial + y * y * d_radial + 6.0 * p1 * y + 2.0 * p2 * x
        return j11, j12, j22

    def _step(self, x, y, ex, ey):
        """One Newton step of the 2x2 system, given the residuals ``ex, ey`` at ``(x, y)``."""
        j11, j12, j22 = self._jacobian(x, y)
        det = j11 * j22 - j12 * j12  # the Jacobian is symmetric
        return x - (j22 * ex - j12 * ey) / det, y - (j11 * ey - j12 * ex) / det


class DiscInverse:
    """Invert a near-radial distortion ``F`` of the plane (``F(0) = 0``, ``|F(m)|`` close to an increasing radial
    part ``g(|m|)``) on the disc ``|m| <= r_valid`` where it is one-to-one: COLMAP's thin-prism fisheye models in the
    plane of ``theta`` (``ThinPrismFisheyeCameraModel``, ``RadTanThinPrismFisheyeModel``).

    ``r_valid``: ``g`` still increases, stays within ``y_cap``, and ``F``'s Jacobian determinant is positive at every
    azimuth (:func:`one_to_one_radius`), so a distorted point has at most one undistorted point there. Each point
    starts from ``g``'s inverse (:class:`MonotoneInverse`'s table) along its own direction and takes Newton steps on
    the 2x2 system, each no longer than ``max(0.1 |m|, 0.1)`` (COLMAP's ``IterativeUndistortion`` trust region), kept
    on the disc and halved until it shrinks the residual, until the residual is float64's rounding of ``F``, no step
    shrinks it, or five steps in a row shrank it by less than a tenth (no solution on the disc: crawling to the
    residual's lowest point; Newton's steps shrink it far faster, by half even at a double root); at most
    ``max_steps``.
    NaN where the result does not reproduce the distorted point to ``tol`` per coordinate: never a wrong point, never
    one off the disc.

    Args:
        distort: ``(x, y) -> F(x, y)`` on float64 tensors.
        jacobian: ``(x, y) -> (dFx/dx, dFx/dy, dFy/dx, dFy/dy)``.
        radial: ``g`` (float64 tensors); ``d_radial`` its derivative.
        r_max: Where ``g`` stops increasing.
        y_cap: Largest ``g`` solved for.
        y_near: ``g`` up to which the start table reaches (the image and a frame around it).
        tol: Largest accepted residual, per coordinate.
    """

    def __init__(
        self,
        distort: Callable[[torch.Tensor, torch.Tensor], tuple[torch.Tensor, torch.Tensor]],
        jacobian: Callable[[torch.Tensor, torch.Tensor], tuple[torch.Tensor, ...]],
        radial: Callable[[torch.Tensor], torch.Tensor],
        d_radial: Callable[[torch.Tensor], torch.Tensor],
        r_max: float,
        y_cap: float = math.inf,
        y_near: float = math.inf,
        tol: float = 1e-12,
    ) -> None:
        self.distort, self.jacobian, self.tol = distort, jacobian, float(tol)
        self._radial = MonotoneInverse(radial, d_radial, r_max, y_cap=y_cap, y_near=y_near)
        self.r_valid = one_to_one_radius(self.min_det, self._radial.t_hi)
        # The disc's image lies within the largest distorted radius of its rim: beyond (with a margin for the
        # sampling) a point has no solution, and is not solved.
        rim = _circles(torch.tensor([self.r_valid], dtype=torch.float64), azimuths=4096)
        self._rd_max = 1.001 * float(torch.hypot(*self.distort(*rim)).max())

    def min_det(self, r: torch.Tensor) -> torch.Tensor:
        """Smallest determinant of ``F``'s Jacobian over the circle of each radius ``r``."""
        j11, j12, j21, j22 = self.jacobian(*_circles(r))
        return (j11 * j22 - j12 * j21).min(dim=1).values

    def __call__(
        self, xd: torch.Tensor, yd: torch.Tensor, max_steps: int = 50
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Undistort flat ``[N]`` coordinates; masked steps run only on the points not yet converged."""
        rd = torch.hypot(xd, yd)
        _, radial_hi = self._radial.y_range
        t = self._radial(rd.clamp(max=radial_hi), steps=0).clamp(max=self.r_valid)
        scale = t / rd.clamp_min(1e-300)
        x, y = torch.where(rd == 0, xd, xd * scale), torch.where(rd == 0, yd, yd * scale)
        # Converged once the residual is at float64's rounding of F (a few ulps of the distorted radius).
        floor = 4e-16 * (1.0 + rd)
        idx = (torch.isfinite(x) & torch.isfinite(y) & (rd <= self._rd_max)).nonzero().squeeze(1)
        ex, ey = self._residual(x[idx], y[idx], xd[idx], yd[idx])
        stalled = torch.zeros_like(idx)  # steps in a row that shrank the residual by less than a tenth
        for _ in range(max_steps):
            todo = (
                ((ex.abs() > floor[idx]) | (ey.abs() > floor[idx])) & torch.isfinite(ex) & torch.isfinite(ey)
            )
            todo &= stalled < 5
            keep = todo.nonzero().squeeze(1)
            idx, ex, ey, stalled = idx[keep], ex[keep], ey[keep], stalled[keep]
            if not len(idx):
                break
            xa, ya, xda, yda = x[idx], y[idx], xd[idx], yd[idx]
            j11, j12, j21, j22 = self.jacobian(xa, ya)
            det = j11 * j22 - j12 * j21
            sx, sy = (j22 * ex - j12 * ey) / det, (j11 * ey - j21 * ex) / det
            step = torch.hypot(sx, sy)
            trust = (torch.clamp_min(0.1 * torch.hypot(xa, ya), 0.1) / step).clamp(max=1.0)
            err = torch.hypot(ex, ey)
            # Backtracking: the step is halved until it shrinks the residual (near a fold the full one overshoots).
            lam = trust.clone()
            xn, yn, exn, eyn = self._moved(xa, ya, sx, sy, lam, xda, yda)
            worse = self._backtrack(xa, ya, sx, sy, lam, xda, yda, err, xn, yn, exn, eyn)
            w = worse.nonzero().squeeze(1)
            if len(w):
                # Where no Newton step helps (its direction is wrong next to a fold, where J is nearly singular):
                # the steepest descent of |F - m_d|^2, from its Cauchy point, with the same backtracking.
                ja, jb, jc, jd, ewx, ewy = j11[w], j12[w], j21[w], j22[w], ex[w], ey[w]
                gx, gy = ja * ewx + jc * ewy, jb * ewx + jd * ewy
                alpha = (gx * gx + gy * gy) / ((ja * gx + jb * gy) ** 2 + (jc * gx + jd * gy) ** 2)
                sx[w], sy[w], lam[w] = alpha * gx, alpha * gy, 1.0
                step[w] = torch.hypot(sx[w], sy[w])
                parts = self._moved(xa[w], ya[w], sx[w], sy[w], lam[w], xda[w], yda[w])
                xn[w], yn[w], exn[w], eyn[w] = parts
                lw = lam[w]
                still = self._backtrack(xa[w], ya[w], sx[w], sy[w], lw, xda[w], yda[w], err[w], *parts)
                lam[w], worse[w] = lw, still
                xn[w], yn[w], exn[w], eyn[w] = parts
            # No step shrinks it: float64's floor, or the residual's lowest point (no solution there). Done either way.
            moved = (~worse & (step * lam > 1e-16 * (1.0 + torch.hypot(xa, ya)))).nonzero().squeeze(1)
            idx, xn, yn, exn, eyn = idx[moved], xn[moved], yn[moved], exn[moved], eyn[moved]
            x[idx], y[idx] = xn, yn
            stalled = torch.where(torch.hypot(exn, eyn) > 0.9 * err[moved], stalled[moved] + 1, 0)
            ex, ey = exn, eyn
        fx, fy = self.distort(x, y)
        ok = ((fx - xd).abs() <= self.tol) & ((fy - yd).abs() <= self.tol)
        ok &= torch.hypot(x, y) <= self.r_valid
        return torch.where(ok, x, torch.nan), torch.where(ok, y, torch.nan)

    def _backtrack(
        self, x, y, sx, sy, lam, xd, yd, err, xn, yn, exn, eyn, halvings: int = 10
    ) -> torch.Tensor:
        """Halve ``lam`` (in place, as the candidates ``xn, yn, exn, eyn``) where the step does not shrink the
        residual below ``err``; returns where it still does not."""
        worse = ~(torch.hypot(exn, eyn) < err)
        for _ in range(halvings):
            w = worse.nonzero().squeeze(1)
            if not len(w):
                break
            lam[w] *= 0.5
            xn[w], yn[w], exn[w], eyn[w] = self._moved(x[w], y[w], sx[w], sy[w], lam[w], xd[w], yd[w])
            worse[w] = ~(torch.hypot(exn[w], eyn[w]) < err[w])
        return worse

    def _residual(self, x, y, xd, yd):
        fx, fy = self.distort(x, y)
        return fx - xd, fy - yd

    def _moved(self, x, y, sx, sy, lam, xd, yd):
        """``(x, y) - lam (sx, sy)``, kept on the disc, and its residual."""
        xn, yn = x - lam * sx, y - lam * sy
        pull = (self.r_valid / torch.hypot(xn, yn)).clamp(max=1.0)
        xn, yn = xn * pull, yn * pull
        return xn, yn, *self._residual(xn, yn, xd, yd)


__all__ = [
    "DiscInverse",
    "RadtanInverse",
    "one_to_one_radius",
    "radial_factor",
    "radial_limit",
    "radtan",
]
