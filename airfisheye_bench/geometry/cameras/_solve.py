"""Vectorised, bounded 1-D inverses shared by the models that have no closed-form back-projection.

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

The inverses of distortions of the plane (radial-tangential, thin prism) are :mod:`._solve_planar`'s.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import torch

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


def image_inverse(
    f: Callable[[torch.Tensor], torch.Tensor],
    df: Callable[[torch.Tensor], torch.Tensor],
    t_hi: float,
    to_sensor: Callable[[torch.Tensor, torch.Tensor], tuple[torch.Tensor, torch.Tensor]],
    width: int,
    height: int,
    tol: float,
    f_err: Callable[[torch.Tensor], torch.Tensor] | None = None,
) -> MonotoneInverse:
    """The :class:`MonotoneInverse` of a radial model's ``f`` over its image: its table spans the radii of the
    image frame (``to_sensor``: the model's pixels to its radial plane), and it solves out to :data:`FAR_FRAME`
    image sizes around it (beyond, a ray's pixel is no sensor's and the polynomial's growth is no lens's)."""
    return MonotoneInverse(
        f,
        df,
        t_hi,
        y_cap=frame_reach(to_sensor, width, height, FAR_FRAME),
        y_near=frame_reach(to_sensor, width, height, 1.0),
        tol=tol,
        f_err=f_err,
    )


__all__ = [
    "FAR_FRAME",
    "PIXEL_TOL",
    "MonotoneInverse",
    "OriginChord",
    "frame_reach",
    "image_inverse",
    "increasing_limit",
    "increasing_start",
    "origin_chord",
    "polyder",
    "polyval",
    "polyval_error",
]
