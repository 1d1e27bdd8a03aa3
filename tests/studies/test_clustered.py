"""Flight-clustered statistics: the t distribution against scipy's, Holm against statsmodels' definition."""

from __future__ import annotations

import math

import pytest
from scipy import stats

from airfisheye_bench.studies.clustered import (
    cluster_difference,
    flight_means,
    holm,
    minimum_detectable_effect,
    regularized_beta,
    sign_test_p,
    t_quantile,
    t_two_sided_p,
)
from airfisheye_bench.studies.paired import T975


def test_t_quantiles_equal_the_nist_table() -> None:
    # NIST/SEMATECH e-Handbook 1.3.6.7.2: t(0.975, df), three decimals.
    for df, value in T975.items():
        assert round(t_quantile(0.975, df), 3) == value, df


@pytest.mark.parametrize("df", [1, 2, 3, 5, 9, 17, 40, 200])
def test_t_distribution_agrees_with_scipy(df: int) -> None:
    stats = pytest.importorskip("scipy.stats")
    for t in (0.0, 0.3, 1.0, 2.0, 3.5, 8.0, 40.0):
        assert t_two_sided_p(t, df) == pytest.approx(2 * stats.t.sf(t, df), rel=1e-10, abs=1e-300)
    for q in (0.6, 0.9, 0.975, 0.995, 0.99995):
        assert t_quantile(q, df) == pytest.approx(stats.t.ppf(q, df), rel=1e-9)


def test_regularized_beta_agrees_with_scipy() -> None:
    special = pytest.importorskip("scipy.special")
    for a, b, x in [(0.5, 0.5, 0.2), (4.5, 0.5, 0.9), (20.0, 0.5, 0.999), (1.0, 3.0, 0.01), (7.0, 7.0, 0.5)]:
        assert regularized_beta(a, b, x) == pytest.approx(special.betainc(a, b, x), rel=1e-12)


def test_holm_matches_its_definition() -> None:
    # Holm (1979): sorted p_(1) <= ... <= p_(m); adjusted p_(i) = max_{j<=i} min(1, (m - j + 1) p_(j)).
    p = {"a": 0.001, "b": 0.02, "c": 0.019, "d": 0.5, "e": math.nan}
    adjusted = holm(p)
    assert adjusted["a"] == pytest.approx(0.004)
    assert adjusted["c"] == pytest.approx(0.057)  # 3 x 0.019
    assert adjusted["b"] == pytest.approx(0.057)  # max(0.057, 2 x 0.02 = 0.04): monotone
    assert adjusted["d"] == pytest.approx(0.5)
    assert math.isnan(adjusted["e"])


def test_the_interval_is_over_flights_not_frames() -> None:
    per_frame = {f"town/traj{f:02d}/{k:06d}": float(f) + 0.01 * k for f in range(4) for k in range(6)}
    flights = flight_means(per_frame)
    assert list(flights) == [f"town/traj{f:02d}" for f in range(4)]
    d = cluster_difference(flights, family_size=10)
    assert d["n"] == 4  # 24 frames, 4 flights
    lo, hi = d["ci"]
    flo, fhi = d["ci_family"]
    assert flo < lo < d["mean"] < hi < fhi  # the family's interval is the wider one
    stats = pytest.importorskip("scipy.stats")
    values = list(flights.values())
    expected = stats.ttest_1samp(values, 0.0)
    assert d["p"] == pytest.approx(expected.pvalue, rel=1e-9)


def test_one_flight_has_no_interval() -> None:
    d = cluster_difference({"town/traj00": 1.5})
    assert d["n"] == 1 and math.isnan(d["p"]) and all(math.isnan(b) for b in d["ci"])


@pytest.mark.parametrize(
    ("n", "alpha", "expected"),
    # statsmodels 0.15.0: TTestPower().solve_power(nobs=n, alpha=alpha, power=0.8), the standardised effect.
    [(10, 0.05, 0.9960), (10, 0.05 / 20, 1.6430), (3, 0.05, 3.2640), (50, 0.05 / 20, 0.5735)],
)
def test_the_minimum_detectable_effect_agrees_with_statsmodels(n: int, alpha: float, expected: float) -> None:
    family = round(0.05 / alpha)
    assert minimum_detectable_effect(2.0, n, family_size=family) == pytest.approx(2.0 * expected, abs=2e-4)


def test_the_minimum_detectable_effect_has_its_power_where_statsmodels_gives_nan() -> None:
    """3 flights at a family of 4: the noncentral t's lower tail underflows; statsmodels' solver then returns 5.0009,
    where its own power is NaN. The effect found here has the power asked for."""
    effect = minimum_detectable_effect(1.0, 3, family_size=4)
    critical = stats.t.ppf(1 - 0.05 / 8, 2)
    assert stats.nct.sf(critical, 2, effect * math.sqrt(3)) == pytest.approx(0.8, abs=1e-6)


def test_every_difference_carries_its_minimum_detectable_effects() -> None:
    d = cluster_difference({"a": 1.0, "b": 2.0, "c": 3.0, "d": 2.5}, family_size=20)
    assert d["mde"] == pytest.approx(minimum_detectable_effect(d["std"], 4))
    assert d["mde_family"] == pytest.approx(minimum_detectable_effect(d["std"], 4, family_size=20))
    assert d["mde_family"] > d["mde"] > 0 and d["power"] == 0.8


def test_the_sign_test_is_the_binomial_tail() -> None:
    assert sign_test_p([-0.1] * 10) == pytest.approx(2 * 0.5**10)  # 10 of 10 one way
    assert sign_test_p([1.0] * 8 + [-1.0] * 2) == pytest.approx(2 * (1 + 10 + 45) / 2**10)  # 2 of 10
    assert sign_test_p([0.0, 0.0]) == 1.0
