"""Vectorised, bounded inverses shared by the models that have no closed-form back-projection.

- :class:`MonotoneInverse`: solve ``f(t) = y`` for an increasing 1-D function on ``[0, t_hi]`` (Kannala-Brandt's
  ``theta_d(theta)``, WoodScape's ``rho(theta)``, OCam's world-to-image polynomial). A dense table brackets every
  root; linear interpolation inside the bracket starts within ~1e-9 of it and a few Newton steps clamped to the
  bracket polish it to machine precision, whatever the coefficients.
- :func:`undistort_radtan`: invert OpenCV's radial-tangential distortion with Newton's method on the 2x2 system,
  a fixed number of iterations at most, NaN where it has not converged.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import torch

_TABLE_SIZE = 1 << 14


def polyval(coeffs: Sequence[float], t: torch.Tensor) -> torch.Tensor:
    """``c0 + c1 t + c2 t^2 + ...`` (Horner)."""
    out = torch.full_like(t, float(coeffs[-1]))
    for c in reversed(coeffs[:-1]):
        out = out * t + float(c)
    return out


def polyder(coeffs: Sequence[float]) -> tuple[float, ...]:
    """Coefficients of the derivative of :func:`polyval`'s polynomial."""
    return tuple(i * float(c) for i, c in enumerate(coeffs))[1:] or (0.0,)


def increasing_limit(df: Callable[[torch.Tensor], torch.Tensor], hi: float, samples: int = 8193) -> float:
    """Largest ``t <= hi`` up to which ``f`` keeps increasing (``df > 0`` on a dense grid from 0)."""
    t = torch.linspace(0.0, hi, samples, dtype=torch.float64)
    bad = (df(t) <= 0).nonzero()
    if not len(bad):
        return hi
    return float(t[max(int(bad[0, 0]) - 1, 0)])


class MonotoneInverse:
    """``t = f^-1(y)`` for ``f`` increasing on ``[0, t_hi]``; NaN outside ``[f(0), f(t_hi)]``.

    Args:
        f: The function (float64 tensors in and out).
        df: Its derivative.
        t_hi: Upper end of the domain where ``f`` increases.
    """

    def __init__(
        self,
        f: Callable[[torch.Tensor], torch.Tensor],
        df: Callable[[torch.Tensor], torch.Tensor],
        t_hi: float,
    ) -> None:
        self.f, self.df, self.t_hi = f, df, float(t_hi)
        self.table_t = torch.linspace(0.0, self.t_hi, _TABLE_SIZE, dtype=torch.float64)
        self.table_y = f(self.table_t)

    @property
    def y_range(self) -> tuple[float, float]:
        return float(self.table_y[0]), float(self.table_y[-1])

    def __call__(self, y: torch.Tensor, steps: int = 3) -> torch.Tensor:
        ty, tt = self.table_y, self.table_t
        lo_y, hi_y = self.y_range
        solvable = (y >= lo_y) & (y <= hi_y)
        idx = torch.searchsorted(ty, y.clamp(lo_y, hi_y).contiguous()).clamp(1, len(ty) - 1)
        lo, hi = tt[idx - 1], tt[idx]
        y0, y1 = ty[idx - 1], ty[idx]
        t = lo + (hi - lo) * (y - y0) / (y1 - y0)
        for _ in range(steps):
            t = (t - (self.f(t) - y) / self.df(t)).clamp(lo, hi)
        return torch.where(solvable, t, torch.nan)


def radtan(
    x: torch.Tensor, y: torch.Tensor, k1: float, k2: float, p1: float, p2: float, k3: float = 0.0
) -> tuple[torch.Tensor, torch.Tensor]:
    """OpenCV's radial-tangential (plumb_bob) distortion of normalised coordinates."""
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xy = x * y
    xd = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy
    return xd, yd


def radial_limit(k1: float, k2: float, k3: float = 0.0) -> float:
    """Largest undistorted radius up to which ``r (1 + k1 r^2 + k2 r^4 + k3 r^6)`` increases (inf if always)."""
    # d/dr = 1 + 3 k1 s + 5 k2 s^2 + 7 k3 s^3 with s = r^2: its smallest positive real root, if any.
    coeffs = np.trim_zeros(np.array([7.0 * k3, 5.0 * k2, 3.0 * k1, 1.0]), "f")
    roots = np.roots(coeffs) if len(coeffs) > 1 else np.array([])
    positive = [r.real for r in roots if abs(r.imag) <= 1e-12 * max(1.0, abs(r)) and r.real > 0]
    return math.sqrt(min(positive)) if positive else math.inf


def undistort_radtan(
    xd: torch.Tensor,
    yd: torch.Tensor,
    k1: float,
    k2: float,
    p1: float,
    p2: float,
    k3: float = 0.0,
    r_max: float = math.inf,
    iterations: int = 20,
    tol: float = 1e-13,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Invert :func:`radtan` by Newton's method (analytic 2x2 Jacobian), at most ``iterations`` steps.

    Starts from the distorted point; stops early once every residual is below ``tol``. Where the result has not
    converged or lies beyond ``r_max`` (where the radial factor stops increasing), NaN.
    """
    x, y = xd.clone(), yd.clone()
    for _ in range(iterations):
        fx, fy = radtan(x, y, k1, k2, p1, p2, k3)
        ex, ey = fx - xd, fy - yd
        if not bool(((ex.abs() > tol) | (ey.abs() > tol)).any()):
            break
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        d_radial = 2.0 * (k1 + r2 * (2.0 * k2 + r2 * 3.0 * k3))  # d radial / d (r^2) times 2
        j11 = radial + x * x * d_radial + 2.0 * p1 * y + 6.0 * p2 * x
        j12 = x * y * d_radial + 2.0 * p1 * x + 2.0 * p2 * y
        j21 = x * y * d_radial + 2.0 * p1 * x + 2.0 * p2 * y
        j22 = radial + y * y * d_radial + 6.0 * p1 * y + 2.0 * p2 * x
        det = j11 * j22 - j12 * j21
        x = x - (j22 * ex - j12 * ey) / det
        y = y - (-j21 * ex + j11 * ey) / det
    fx, fy = radtan(x, y, k1, k2, p1, p2, k3)
    scale = 1.0 + torch.hypot(xd, yd)
    ok = ((fx - xd).abs() <= 1e-9 * scale) & ((fy - yd).abs() <= 1e-9 * scale) & (torch.hypot(x, y) <= r_max)
    return torch.where(ok, x, torch.nan), torch.where(ok, y, torch.nan)


__all__ = [
    "MonotoneInverse",
    "increasing_limit",
    "polyder",
    "polyval",
    "radial_limit",
    "radtan",
    "undistort_radtan",
]
