"""Vectorised, bounded inverses shared by the models that have no closed-form back-projection.

- :class:`MonotoneInverse`: solve ``f(t) = y`` for an increasing 1-D function on ``[0, t_hi]`` (Kannala-Brandt's
  ``theta_d(theta)``, WoodScape's ``rho(theta)``, OCam's world-to-image polynomial). A dense table brackets every
  root; linear interpolation inside the bracket starts within ~1e-9 of it and a few Newton steps clamped to the
  bracket polish it to machine precision, whatever the coefficients.
- :class:`RadtanInverse`: invert OpenCV's radial-tangential distortion: the radial part as above, then Newton
  steps on the 2x2 system for the tangential terms, each point until it converges (at most 40; a numba loop on
  CPU), NaN where the result does not reproduce the input.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import torch

from airfisheye_bench.geometry import _kernels

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

    The table is uniform in ``y`` (built once with a search over a dense ``t`` grid), so finding a root's bracket
    is one multiply and two gathers, not a search; Newton steps clamped to the bracket polish the interpolated
    start.

    Args:
        f: The function (float64 tensors in and out).
        df: Its derivative.
        t_hi: Upper end of the domain where ``f`` increases.
        y_cap: Largest ``y`` to solve for (the table stops where ``f`` reaches it), if smaller than ``f(t_hi)``.
    """

    def __init__(
        self,
        f: Callable[[torch.Tensor], torch.Tensor],
        df: Callable[[torch.Tensor], torch.Tensor],
        t_hi: float,
        y_cap: float = math.inf,
    ) -> None:
        self.f, self.df, self.t_hi = f, df, float(t_hi)
        dense_t = torch.linspace(0.0, self.t_hi, 4 * _TABLE_SIZE, dtype=torch.float64)
        dense_y = f(dense_t)
        if dense_y[-1] > y_cap:
            end = int(torch.searchsorted(dense_y, torch.tensor([y_cap], dtype=torch.float64))) + 1
            self.t_hi = float(dense_t[min(end, len(dense_t) - 1)])
            dense_t = torch.linspace(0.0, self.t_hi, 4 * _TABLE_SIZE, dtype=torch.float64)
            dense_y = f(dense_t)
        self.y_lo, self.y_hi = float(dense_y[0]), float(dense_y[-1])
        self.table_y = torch.linspace(self.y_lo, self.y_hi, _TABLE_SIZE, dtype=torch.float64)
        # t at each table y: interpolate the dense grid (then one Newton step there makes it exact enough to
        # serve as brackets; the brackets are widened by one dense step to stay safe).
        idx = torch.searchsorted(dense_y, self.table_y).clamp(1, len(dense_y) - 1)
        y0, y1 = dense_y[idx - 1], dense_y[idx]
        t = dense_t[idx - 1] + (dense_t[idx] - dense_t[idx - 1]) * (self.table_y - y0) / (y1 - y0).clamp_min(
            1e-300
        )
        self.table_t = t
        self._margin = float(dense_t[1] - dense_t[0])
        self._step = (self.y_hi - self.y_lo) / (_TABLE_SIZE - 1)

    @property
    def y_range(self) -> tuple[float, float]:
        return self.y_lo, self.y_hi

    def __call__(self, y: torch.Tensor, steps: int = 2) -> torch.Tensor:
        solvable = (y >= self.y_lo) & (y <= self.y_hi)
        pos = ((y - self.y_lo) / self._step).nan_to_num(0.0).clamp(0.0, _TABLE_SIZE - 1.000001)
        idx = pos.to(torch.int64)
        frac = pos - idx
        lo, hi = self.table_t[idx], self.table_t[idx + 1]
        t = lo + (hi - lo) * frac
        lo, hi = (lo - self._margin).clamp_min(0.0), (hi + self._margin).clamp_max(self.t_hi)
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


class RadtanInverse:
    """Invert :func:`radtan`: the radial part by :class:`MonotoneInverse` on the radius, then Newton steps on the
    2x2 system (analytic Jacobian) for the tangential terms, on the points not yet converged. NaN where the result does not
    reproduce the distorted point or lies beyond ``r_max`` (where the radial factor stops increasing).

    Args:
        k1, k2, p1, p2, k3: OpenCV's plumb_bob coefficients.
        r_max: Largest undistorted radius of the model's region.
        r_cap: Largest distorted radius solved for (normalised units; 10 is 84 deg off-axis for a pinhole).
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
    ) -> None:
        self.k = (k1, k2, p1, p2, k3)
        self.r_max = r_max

        def f(r: torch.Tensor) -> torch.Tensor:  # r (1 + k1 r^2 + k2 r^4 + k3 r^6)
            s = r * r
            return r * (1.0 + s * (k1 + s * (k2 + s * k3)))

        def df(r: torch.Tensor) -> torch.Tensor:
            s = r * r
            return 1.0 + s * (3.0 * k1 + s * (5.0 * k2 + s * 7.0 * k3))

        self._radial = MonotoneInverse(f, df, min(r_max, 1e3), y_cap=r_cap)

    def __call__(
        self, xd: torch.Tensor, yd: torch.Tensor, max_steps: int = 40, fused: bool = True
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Undistort flat ``[N]`` coordinates: on CPU (``fused``) a numba loop takes each point until it converges;
        otherwise each masked torch step runs only on the points not yet converged."""
        k1, k2, p1, p2, k3 = self.k
        rd = torch.hypot(xd, yd)
        # The table's interpolation alone starts within ~1e-7; the 2x2 Newton steps below polish the radial part
        # together with the tangential one.
        scale = self._radial(rd, steps=0) / rd.clamp_min(1e-300)
        x, y = torch.where(rd == 0, xd, xd * scale), torch.where(rd == 0, yd, yd * scale)
        if any(self.k) and fused and x.device.type == "cpu":
            # One fused loop, each point until it converges (several times faster than the masked steps below).
            xn, yn = x.numpy(), y.numpy()
            _kernels.newton_radtan(
                xn, yn, xd.contiguous().numpy(), yd.contiguous().numpy(), k1, k2, p1, p2, k3, 40
            )
        elif any(self.k):
            active = None  # all points
            for _ in range(max_steps):
                xa, ya = (x, y) if active is None else (x[active], y[active])
                xda, yda = (xd, yd) if active is None else (xd[active], yd[active])
                fx, fy = radtan(xa, ya, k1, k2, p1, p2, k3)
                ex, ey = fx - xda, fy - yda
                todo = ((ex.abs() > 1e-15) | (ey.abs() > 1e-15)) & torch.isfinite(ex) & torch.isfinite(ey)
                if not bool(todo.any()):
                    break
                idx = todo.nonzero().squeeze(1)
                active = idx if active is None else active[idx]
                xn, yn = self._step(xa[idx], ya[idx], ex[idx], ey[idx])
                x[active], y[active] = xn, yn
        fx, fy = radtan(x, y, k1, k2, p1, p2, k3)
        tol = 1e-9 * (1.0 + rd)
        ok = ((fx - xd).abs() <= tol) & ((fy - yd).abs() <= tol) & (torch.hypot(x, y) <= self.r_max)
        return torch.where(ok, x, torch.nan), torch.where(ok, y, torch.nan)

    def _step(self, x, y, ex, ey):
        """One Newton step of the 2x2 system, given the residuals ``ex, ey`` at ``(x, y)``."""
        k1, k2, p1, p2, k3 = self.k
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        d_radial = 2.0 * (k1 + r2 * (2.0 * k2 + r2 * 3.0 * k3))  # 2 d(radial)/d(r^2)
        j11 = radial + x * x * d_radial + 2.0 * p1 * y + 6.0 * p2 * x
        j12 = x * y * d_radial + 2.0 * p1 * x + 2.0 * p2 * y
        j22 = radial + y * y * d_radial + 6.0 * p1 * y + 2.0 * p2 * x
        det = j11 * j22 - j12 * j12  # the Jacobian is symmetric
        return x - (j22 * ex - j12 * ey) / det, y - (j11 * ey - j12 * ex) / det


__all__ = [
    "MonotoneInverse",
    "RadtanInverse",
    "increasing_limit",
    "polyder",
    "polyval",
    "radial_limit",
    "radtan",
]
