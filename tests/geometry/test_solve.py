"""The shared 1-D solver pieces of ``geometry/cameras/_solve.py`` on their own, with functions written here: the
rounding bound of a polynomial, the monotone inverse of one whose terms cancel, and the chord through the origin
that continues a radius which is off near the axis."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
import torch

from airfisheye_bench.geometry.cameras._solve import (
    MonotoneInverse,
    OriginChord,
    increasing_start,
    origin_chord,
    polyder,
    polyval,
    polyval_error,
)

#: ``-0.6 + 152 t`` plus ``1e-3 T_24(t)`` of [0, 2] (numpy's Chebyshev), in powers of ``x = t - pi/2``: terms of up to
#: ~1e11 that cancel to a few hundred on [0, 2], most at ``t = 0`` (``x = -pi/2``).
_LINE = np.polynomial.Polynomial([-0.6 + 152.0 * math.pi / 2, 152.0])
_WIGGLE = np.polynomial.Chebyshev.basis(24, domain=[-math.pi / 2, 2.0 - math.pi / 2])
CANCELLING = [float(c) for c in (_LINE + 1e-3 * _WIGGLE.convert(kind=np.polynomial.Polynomial)).coef]


def _f(t: torch.Tensor) -> torch.Tensor:
    return polyval(CANCELLING, t - math.pi / 2)


def _df(t: torch.Tensor) -> torch.Tensor:
    return polyval(polyder(CANCELLING), t - math.pi / 2)


def _f_err(t: torch.Tensor) -> torch.Tensor:
    return polyval_error(CANCELLING, t - math.pi / 2)


def _exact(coeffs: list[float], x: float) -> float:
    return float(sum(Fraction(c) * Fraction(x) ** i for i, c in enumerate(coeffs)))


def test_polyval_error_bounds_the_rounding_of_a_cancelling_polynomial() -> None:
    x = torch.linspace(-math.pi / 2, 2.0 - math.pi / 2, 201, dtype=torch.float64)
    got, bound = polyval(CANCELLING, x), polyval_error(CANCELLING, x)
    err = torch.tensor([abs(float(g) - _exact(CANCELLING, float(v))) for g, v in zip(got, x, strict=True)])
    assert (err <= bound).all()
    # Coarser than PIXEL_TOL on the axis: the case the bound is for.
    assert err.max() > 1e-7 and float(bound[0]) > 1e-7
    assert float(polyval_error([1.0, 1.0], torch.tensor([1.0]))[0]) < 1e-15  # a tame one: a few ulps


def test_monotone_inverse_solves_to_the_rounding_of_f_where_it_is_coarser_than_tol() -> None:
    start = increasing_start(_df, 2.0)
    assert start == 0.0
    t_lo = 0.005  # past the zero crossing (-0.6 / 152)
    y = _f(torch.linspace(t_lo, 1.9, 4001, dtype=torch.float64))
    strict = MonotoneInverse(_f, _df, 1.9, t_lo=t_lo, tol=1e-7)
    assert torch.isnan(strict(y)).sum() > 100  # held to 1e-7, most of the axis's side had no answer
    inverse = MonotoneInverse(_f, _df, 1.9, t_lo=t_lo, tol=1e-7, f_err=_f_err)
    t = inverse(y)
    assert torch.isfinite(t).all()
    assert ((_f(t) - y).abs() <= 1e-7 + _f_err(t)).all()
    # As close to the true root as f's rounding lets any t be (both y and f(t) are f's float64 values).
    true = torch.linspace(t_lo, 1.9, 4001, dtype=torch.float64)
    assert ((t - true).abs() <= (1e-7 + 2 * _f_err(t)) / _df(t)).all()
    assert (t - true).abs().max() > 1e-9  # (where f is that coarse: the case)
    # Outside [f(t_lo), f(t_hi)] there is still none.
    assert torch.isnan(inverse(torch.tensor([-1.0, 1e6], dtype=torch.float64))).all()


@pytest.mark.parametrize(
    ("coeffs", "joint"),
    [
        ([0.0, 2.0], 0.0),  # a lens's radius: 0 and increasing on the axis, no chord
        ([-0.5, 2.0], 0.75),  # negative on the axis: to where it reaches 1.0, twice |f(0)|
        ([0.5, 2.0], 0.25),  # positive: to where it reaches 1.0
        ([1.0, -2.0, 4.0], (2.0 + math.sqrt(20.0)) / 8.0),  # decreasing at first (to 0.75 at 0.25): to 2 f(0)
        ([-1.0, -2.0, 4.0], (2.0 + math.sqrt(60.0)) / 8.0),  # a negative dip (-1.25 at 0.25): to 2.5
    ],
)
def test_origin_chord_joins_where_the_radius_reaches_twice_its_offset(
    coeffs: list[float], joint: float
) -> None:
    def f(t: torch.Tensor) -> torch.Tensor:
        return polyval(coeffs, t)

    def df(t: torch.Tensor) -> torch.Tensor:
        return polyval(polyder(coeffs), t)

    start = increasing_start(df, 3.0)
    assert start == pytest.approx(0.25 if coeffs[1] < 0 else 0.0, abs=1e-12)
    assert origin_chord(f, start, 3.0) == pytest.approx(joint, abs=1e-12)
    g = OriginChord(f, df, joint)
    dg = g.derivative
    t = torch.linspace(0.0, 3.0, 30001, dtype=torch.float64)
    assert g(t)[0] == 0 and (torch.diff(g(t)) > 0).all() and (dg(t) > 0).all()  # from 0, increasing, no jump
    # No further from f than f is off on the axis (3 times that where f dips first).
    offset = max(abs(coeffs[0]), abs(float(f(torch.tensor(start, dtype=torch.float64)))))
    assert (g(t) - f(t)).abs().max() <= (3.0 if start > 0 else 1.0) * offset + 1e-12
    if joint > 0:
        with pytest.raises(ValueError, match="never reaches twice"):
            origin_chord(f, start, start + 1e-9)
