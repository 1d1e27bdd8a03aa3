"""Vectorised, bounded inverses shared by the models that have no closed-form back-projection.

- :func:`increasing_limit`: where a 1-D function stops increasing (a dense grid, bisection, and for polynomials
  their derivative's roots), so a model's valid region and its inverse stop there, not at a nominal 180 deg.
- :class:`MonotoneInverse`: solve ``f(t) = y`` for an increasing 1-D function on ``[t_lo, t_hi]`` (Kannala-Brandt's
  ``theta_d(theta)``, WoodScape's ``rho(theta)``, OCam's world-to-image polynomial). A table uniform in ``y`` over
  the radii near the image brackets every root there (a dense grid's search the few far beyond); linear
  interpolation starts close to it and two Newton steps clamped to the bracket polish it. Each result is checked
  (``|f(t) - y| <= tol``); a miss is solved again by safeguarded Newton steps, and is NaN if it still misses by more
  than ``tol`` plus the bound on ``f``'s own float64 rounding there (``f_err``; :func:`polyval_error`).
- :func:`increasing_start` and :func:`origin_chord`: a radial function that does not start at the origin increasing
  (a fit's radius, off by a little on the axis) continued below a joint by the chord through the origin, so that its
  inverse is continuous down to the axis and the axis maps to the centre.
- :class:`RadtanInverse`: invert OpenCV's radial-tangential distortion (plumb_bob, or the rational model's radial
  factor, :func:`radial_factor`): the radial part as above, then Newton steps on the 2x2 system for the tangential
  terms, each point until it converges (at most 40; a numba loop on CPU), NaN where the result does not reproduce
  the input.
- :class:`DiscInverse`: invert a near-radial distortion of the plane (COLMAP's thin-prism fisheye models) on the disc
  where it is one-to-one (:func:`one_to_one_radius`): a start from its radial part's inverse, then Newton steps in a
  trust region, halved until they shrink the residual (steepest descent where no Newton step does), NaN where the
  result does not reproduce the input or leaves the disc.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import torch

from airfisheye_bench.geometry import numba_kernels

_TABLE_SIZE = 1 << 14
#: Samples of the dense grids behind :func:`increasing_limit` and :class:`MonotoneInverse` (no more than torch's
#: grain size, 32768: a larger tensor's element-wise ops are split over threads, slower than one on a busy CPU).
_DENSE = 1 << 15
#: How far beyond the image a polynomial model is solved at all, in image sizes on every side (the frame
#: ``[-50 W, 51 W] x [-50 H, 51 H]``): a polynomial fit has long left its calibration's data there (the Kodak SP360's
#: ``world2cam`` reaches 180 deg at 19 image widths; a long fit that blows up reaches 1e12 px), and float64 cannot
#: hold a 1e-6 px round trip much further out. The valid region ends where the radius leaves this frame.
FAR_FRAME = 50.0
#: Largest ``|f(t) - y|`` a :class:`MonotoneInverse` of a camera model accepts, in pixels: the round trip
#: pixel -> ray -> pixel is then exact to well below the 1e-6 px bar, even for a long polynomial whose float64
#: evaluation is itself only good to ~1e-8 px.
PIXEL_TOL = 1e-7
#: float64's unit roundoff.
_UNIT_ROUNDOFF = 2.0**-53


def polyval(coeffs: Sequence[float], t: torch.Tensor) -> torch.Tensor:
    """``c0 + c1 t + c2 t^2 + ...`` (Horner)."""
    out = torch.full_like(t, float(coeffs[-1]))
    for c in reversed(coeffs[:-1]):
        out = out * t + float(c)
    return out


def polyder(coeffs: Sequence[float]) -> tuple[float, ...]:
    """Coefficients of the derivative of :func:`polyval`'s polynomial."""
    return tuple(i * float(c) for i, c in enumerate(coeffs))[1:] or (0.0,)


def polyval_error(coeffs: Sequence[float], t: torch.Tensor) -> torch.Tensor:
    """A bound on the float64 rounding error of :func:`polyval` at ``t``: ``gamma(3n) sum |c_i| |t|^i`` for degree
    ``n``, ``gamma(k) = k u / (1 - k u)`` (Horner's rule: ``gamma(2n)``, Higham, *Accuracy and Stability of Numerical
    Algorithms*, 2nd ed., eq. (5.3); ``gamma(n)`` more for a ``t`` itself rounded once, as ``theta - pi/2`` is).

    Where the terms are far larger than the value they cancel to (OCamCalib's ``world2cam`` is a polynomial in
    ``theta - pi/2``: its terms are largest on the optical axis), the polynomial is only known to this bound, however
    its root is solved.
    """
    k = 3 * max(len(coeffs) - 1, 1)
    gamma = k * _UNIT_ROUNDOFF / (1.0 - k * _UNIT_ROUNDOFF)
    return gamma * polyval([abs(float(c)) for c in coeffs], t.abs())


def increasing_limit(
    df: Callable[[torch.Tensor], torch.Tensor],
    hi: float,
    lo: float = 0.0,
    poly: Sequence[float] | None = None,
    shift: float = 0.0,
) -> float:
    """Largest ``t`` in ``[lo, hi]`` such that ``df > 0`` on all of ``[lo, t]``: where ``f`` stops increasing.

    A dense grid finds the first sample with ``df <= 0`` and bisection narrows the sign change down. A polynomial
    ``df`` (``poly``: its coefficients in ``t - shift``, lowest order first) may dip below zero between two samples:
    every root of it near the real axis inside ``[lo, limit]`` is checked on a fine local grid too.
    """
    t = torch.linspace(lo, hi, _DENSE, dtype=torch.float64)
    bad = (~(df(t) > 0)).nonzero()
    limit = hi
    if len(bad):
        i = int(bad[0, 0])
        if i == 0:
            return lo
        limit = _sign_change(df, float(t[i - 1]), float(t[i]))
    coeffs = np.trim_zeros(np.asarray(poly if poly is not None else [], dtype=np.float64), "b")
    if len(coeffs) > 1:
        step = (hi - lo) / (_DENSE - 1)
        for root in np.polynomial.polynomial.polyroots(coeffs):
            centre, half = float(root.real) + shift, 4.0 * abs(float(root.imag)) + step
            if abs(root.imag) > 1e-3 or not lo < centre < limit + half:
                continue
            # From the grid sample before the root (where df > 0) to past it, 1024 steps.
            start = lo + math.floor(max(centre - half - lo, 0.0) / step) * step
            local = torch.linspace(start, min(limit, centre + half), 1025, dtype=torch.float64)
            bad = (~(df(local) > 0)).nonzero()
            if len(bad):
                i = int(bad[0, 0])
                limit = lo if i == 0 else _sign_change(df, float(local[i - 1]), float(local[i]))
    return limit


def _sign_change(df: Callable[[torch.Tensor], torch.Tensor], a: float, b: float) -> float:
    """The last ``t`` in ``[a, b]`` with ``df > 0`` found by bisection, given ``df(a) > 0 >= df(b)``."""
    for _ in range(60):
        mid = 0.5 * (a + b)
        if mid in (a, b):
            break
        if bool(df(torch.tensor([mid], dtype=torch.float64))[0] > 0):
            a = mid
        else:
            b = mid
    return a


def increasing_start(df: Callable[[torch.Tensor], torch.Tensor], hi: float) -> float | None:
    """Smallest ``t`` in ``[0, hi]`` from which ``f`` increases: 0 where ``df(0) > 0``, else the first sign change
    of ``df`` to positive (a dense grid, then bisection); None where ``df > 0`` nowhere on the grid. Where ``f``
    increases from there on, :func:`increasing_limit` (with ``lo`` this start) says."""
    t = torch.linspace(0.0, hi, _DENSE, dtype=torch.float64)
    good = (df(t) > 0).nonzero()
    if not len(good):
        return None
    i = int(good[0, 0])
    if i == 0:
        return 0.0
    a, b = float(t[i - 1]), float(t[i])  # df(a) <= 0 < df(b)
    for _ in range(60):
        mid = 0.5 * (a + b)
        if mid in (a, b):
            break
        if bool(df(torch.tensor([mid], dtype=torch.float64))[0] > 0):
            b = mid
        else:
            a = mid
    return b


def origin_chord(f: Callable[[torch.Tensor], torch.Tensor], start: float, hi: float) -> float:
    """Where a radial function ``f``, increasing on ``[start, hi]``, should leave the chord through the origin: 0
    when ``f`` is a lens's radius at the axis already (``f(0) = 0`` and ``start = 0``); else where ``f`` first reaches
    ``2 d``, with ``d`` the largest ``|f|`` on ``[0, start]`` (``|f(0)|``, or the depth of a dip: ``f`` decreases
    there).

    A fit's radius (OCamCalib's ``world2cam``) is fitted up to the axis, the end of its data, and rounded: it may be
    a little off there (negative, positive, or decreasing at first), where a lens's is 0 and increasing. Below the
    joint the chord from ``(0, 0)`` to the joint replaces it: increasing, continuous, the axis at the centre, and no
    further from the fit than ``d`` where the fit increases from the axis (``3 d`` where it dips first): no further
    than the fit is from a lens there. ``ValueError`` where ``f`` never reaches ``2 d`` on ``[start, hi]``.
    """
    ends = f(torch.tensor([0.0, start, hi], dtype=torch.float64))
    d = max(abs(float(ends[0])), abs(float(ends[1])))
    if d == 0.0:
        return 0.0
    if not float(ends[2]) > 2.0 * d:
        raise ValueError(
            f"the radius never reaches twice its value near the axis ({2.0 * d:.4g}) while it increases"
        )
    a, b = start, hi  # f(a) < 2 d <= f(b)
    for _ in range(80):
        mid = 0.5 * (a + b)
        if mid in (a, b):
            break
        if float(f(torch.tensor([mid], dtype=torch.float64))[0]) < 2.0 * d:
            a = mid
        else:
            b = mid
    return b


class OriginChord:
    """``f`` continued below ``joint`` (:func:`origin_chord`) by the chord through the origin; :meth:`derivative` is
    ``df``'s continuation. A class, not a closure, so that a camera holding it pickles (DataLoader workers)."""

    def __init__(
        self,
        f: Callable[[torch.Tensor], torch.Tensor],
        df: Callable[[torch.Tensor], torch.Tensor],
        joint: float,
    ) -> None:
        self.f, self.df, self.joint = f, df, float(joint)
        self.slope = float(f(torch.tensor([joint], dtype=torch.float64))[0]) / joint if joint > 0 else 0.0

    def __call__(self, t: torch.Tensor) -> torch.Tensor:
        if self.joint <= 0:
            return self.f(t)
        return torch.where(t < self.joint, self.slope * t, self.f(t))

    def derivative(self, t: torch.Tensor) -> torch.Tensor:
        if self.joint <= 0:
            return self.df(t)
        return torch.where(t < self.joint, self.slope, self.df(t))


def frame_reach(
    to_sensor: Callable[[torch.Tensor, torch.Tensor], tuple[torch.Tensor, torch.Tensor]],
    width: int,
    height: int,
    grow: float,
) -> float:
    """Largest radius, in a model's sensor units, of a pixel of the image frame grown by ``grow`` image sizes on
    every side. ``to_sensor(u, v)`` is the model's affine map from pixels to its radial plane; the radius is convex
    over the (convex) frame, so its corners bound it."""
    us = (-0.5 - grow * width, width - 0.5 + grow * width)
    vs = (-0.5 - grow * height, height - 0.5 + grow * height)
    u = torch.tensor([us[0], us[1], us[0], us[1]], dtype=torch.float64)
    v = torch.tensor([vs[0], vs[0], vs[1], vs[1]], dtype=torch.float64)
    gx, gy = to_sensor(u, v)
    return float(torch.hypot(gx, gy).max())


class MonotoneInverse:
    """``t = f^-1(y)`` for ``f`` increasing on ``[t_lo, t_hi]``; NaN outside ``[f(t_lo), f(t_hi)]`` and wherever no
    ``t`` reproduces ``y`` to ``tol``.

    Radii up to ``y_near`` (the image and its surroundings) find their bracket in a table uniform in ``y``: one
    multiply and two gathers, not a search; two Newton steps clamped to the bracket polish the interpolated start.
    The few beyond it (far outside the image) take their bracket from a search of a dense grid. A result that does
    not reproduce ``y`` to ``tol`` (a start far from the root, ``f`` nearly flat, ``f``'s own rounding) is solved
    again by safeguarded Newton steps (bisection whenever a step leaves the bracket) until the bracket closes, and
    is NaN if it still misses ``y`` by more than ``tol`` plus ``f_err(t)``: never a wrong ``t``. Where ``f``'s float64
    evaluation is coarser than ``tol`` (a polynomial whose terms cancel), no ``t`` reproduces ``y`` to ``tol``; the
    bracket then closes on the root as far as ``f`` can tell, and that is the answer, not NaN.

    Args:
        f: The function (float64 tensors in and out).
        df: Its derivative.
        t_hi: Upper end of the domain where ``f`` increases.
        y_cap: Largest ``y`` to solve for (the domain stops where ``f`` reaches it), if smaller than ``f(t_hi)``.
        t_lo: Lower end of the domain.
        y_near: ``y`` up to which the table reaches (default: all of ``[f(t_lo), f(t_hi)]``).
        tol: Largest ``|f(t) - y|`` aimed at (``y``'s units; default 1e-9 of the range).
        f_err: A bound on the float64 rounding of ``f`` at ``t`` (:func:`polyval_error`), added to ``tol`` when a
            result is accepted; default none.
    """

    def __init__(
        self,
        f: Callable[[torch.Tensor], torch.Tensor],
        df: Callable[[torch.Tensor], torch.Tensor],
        t_hi: float,
        y_cap: float = math.inf,
        t_lo: float = 0.0,
        y_near: float = math.inf,
        tol: float | None = None,
        f_err: Callable[[torch.Tensor], torch.Tensor] | None = None,
    ) -> None:
        self.f, self.df, self.t_lo, self.t_hi = f, df, float(t_lo), float(t_hi)
        self.f_err = f_err
        dense_t = torch.linspace(self.t_lo, self.t_hi, _DENSE, dtype=torch.float64)
        dense_y = f(dense_t)
        if dense_y[-1] > y_cap:
            # The domain ends at the last sample below the cap (then resampled: the grid keeps its density).
            end = int(torch.searchsorted(dense_y, torch.tensor([y_cap], dtype=torch.float64)))
            self.t_hi = float(dense_t[max(end - 1, 1)])
            dense_t = torch.linspace(self.t_lo, self.t_hi, _DENSE, dtype=torch.float64)
            dense_y = f(dense_t)
        self.dense_t, self.dense_y = dense_t, dense_y
        self.y_lo, self.y_hi = float(dense_y[0]), float(dense_y[-1])
        self.tol = 1e-9 * (self.y_hi - self.y_lo) if tol is None else float(tol)
        self.y_near = min(self.y_hi, max(float(y_near), self.y_lo))
        self.table_y = torch.linspace(self.y_lo, self.y_near, _TABLE_SIZE, dtype=torch.float64)
        # t at each table y: interpolate the dense grid (exact to within one dense step, so the brackets, widened
        # by one dense step, hold the root).
        idx = torch.searchsorted(dense_y, self.table_y).clamp(1, len(dense_y) - 1)
        y0, y1 = dense_y[idx - 1], dense_y[idx]
        frac = ((self.table_y - y0) / (y1 - y0).clamp_min(1e-300)).clamp(0.0, 1.0)
        self.table_t = dense_t[idx - 1] + (dense_t[idx] - dense_t[idx - 1]) * frac
        self._margin = float(dense_t[1] - dense_t[0])
        self._step = (self.y_near - self.y_lo) / (_TABLE_SIZE - 1)

    @property
    def y_range(self) -> tuple[float, float]:
        return self.y_lo, self.y_hi

    def __call__(self, y: torch.Tensor, steps: int = 2) -> torch.Tensor:
        """``t`` with ``f(t) = y`` (NaN where there is none); ``steps=0``: the table's interpolation alone, a start
        for a caller's own Newton steps."""
        solvable = (y >= self.y_lo) & (y <= self.y_hi)
        pos = ((y - self.y_lo) / max(self._step, 1e-300)).nan_to_num(0.0).clamp(0.0, _TABLE_SIZE - 1.000001)
        idx = pos.to(torch.int64)
        frac = pos - idx
        lo, hi = self.table_t[idx], self.table_t[idx + 1]
        t = lo + (hi - lo) * frac
        lo, hi = (lo - self._margin).clamp_min(self.t_lo), (hi + self._margin).clamp_max(self.t_hi)
        far = (solvable & (y > self.y_near)).nonzero().squeeze(1)
        if len(far):
            t[far], lo[far], hi[far] = self._dense_bracket(y[far])
        if steps == 0:
            return torch.where(solvable, t, torch.nan)
        for _ in range(steps):
            t = (t - (self.f(t) - y) / self.df(t)).clamp(lo, hi)
        missed = (solvable & ~self._converged(t, self.f(t) - y)).nonzero().squeeze(1)
        if len(missed):
            t[missed] = self._safeguarded(y[missed])
        return torch.where(solvable, t, torch.nan)

    def _converged(self, t: torch.Tensor, r: torch.Tensor) -> torch.Tensor:
        """``f(t) - y = r`` is solved: ``|r| <= tol`` (the pixel is exact), and ``t`` itself is within 1e-10 of the
        root (``|r| / f'``: where ``f`` is nearly flat a small residual still leaves ``t`` far off) or ``|r|`` is a
        thousandth of ``tol`` (the residual cannot shrink below ``f``'s own rounding)."""
        a = r.abs()
        return (a <= self.tol) & ((a <= 1e-3 * self.tol) | (a <= 1e-10 * self.df(t).abs()))

    def _dense_bracket(self, y: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``(start, lo, hi)`` from the dense grid: ``f(lo) < y <= f(hi)`` one dense step apart."""
        k = torch.searchsorted(self.dense_y, y).clamp(1, len(self.dense_y) - 1)
        y0, y1 = self.dense_y[k - 1], self.dense_y[k]
        lo, hi = self.dense_t[k - 1], self.dense_t[k]
        frac = ((y - y0) / (y1 - y0).clamp_min(1e-300)).clamp(0.0, 1.0)
        return lo + (hi - lo) * frac, lo, hi

    def _safeguarded(self, y: torch.Tensor, max_steps: int = 80) -> torch.Tensor:
        """Newton steps kept inside a shrinking bracket (bisection where a step leaves it) until ``y`` is reproduced
        to ``tol`` or the bracket closes; NaN where the result misses ``y`` by more than :meth:`_accepted` allows."""
        t, lo, hi = self._dense_bracket(y)
        for _ in range(max_steps):
            r = self.f(t) - y
            lo, hi = torch.where(r < 0, t, lo), torch.where(r > 0, t, hi)
            newton = t - r / self.df(t)
            nxt = torch.where((newton > lo) & (newton < hi), newton, 0.5 * (lo + hi))
            done = self._converged(t, r) | (nxt == t)
            if bool(done.all()):
                break
            t = torch.where(done, t, nxt)
        return torch.where(self._accepted(t, self.f(t) - y), t, torch.nan)

    def _accepted(self, t: torch.Tensor, r: torch.Tensor) -> torch.Tensor:
        """``f(t) - y = r`` reproduces ``y`` as well as ``f`` can: ``|r| <= tol``, plus ``f``'s rounding bound."""
        if self.f_err is None:
            return r.abs() <= self.tol
        return r.abs() <= self.tol + self.f_err(t)


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
    "FAR_FRAME",
    "PIXEL_TOL",
    "DiscInverse",
    "MonotoneInverse",
    "OriginChord",
    "RadtanInverse",
    "frame_reach",
    "increasing_limit",
    "increasing_start",
    "one_to_one_radius",
    "origin_chord",
    "polyder",
    "polyval",
    "polyval_error",
    "radial_factor",
    "radial_limit",
    "radtan",
]
