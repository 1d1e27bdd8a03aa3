"""Paired differences with 95 % t-intervals: a hand-computed example, the t table against its source and scipy."""

from __future__ import annotations

import math

import pytest

from airfisheye_bench.studies.paired import (
    T975,
    paired_difference,
    paired_differences,
    paired_table,
    t_quantile_975,
)


def test_interval_by_hand() -> None:
    # differences 0.2, -0.1, 0.4, 0.3, 0.2: mean 0.2; deviations 0, -0.3, 0.2, 0.1, 0 -> squares sum 0.14,
    # s = sqrt(0.14 / 4) = 0.187083; t(0.975, 4) = 2.776; half-width 2.776 * 0.187083 / sqrt(5) = 2.776 * 0.083666 = 0.232257.
    out = paired_difference([5.2, 4.9, 5.4, 5.3, 5.2], [5.0, 5.0, 5.0, 5.0, 5.0])
    assert out["n"] == 5 and out["t"] == 2.776
    assert out["mean"] == pytest.approx(0.2) and out["std"] == pytest.approx(0.187083, abs=1e-6)
    assert out["ci95"] == pytest.approx([0.2 - 0.232257, 0.2 + 0.232257], abs=1e-6)


def test_single_pair_has_no_interval_and_bad_input_is_refused() -> None:
    out = paired_difference([2.0], [1.5])
    assert out["mean"] == 0.5 and math.isnan(out["std"]) and all(math.isnan(b) for b in out["ci95"])
    with pytest.raises(ValueError, match="equal lengths"):
        paired_difference([1.0, 2.0], [1.0])
    with pytest.raises(ValueError, match="degrees of freedom"):
        t_quantile_975(0)


def test_t_table_golden_values_and_expansion() -> None:
    # NIST/SEMATECH e-Handbook 1.3.6.7.2, upper 0.025 critical values of t.
    assert (T975[1], T975[2], T975[4], T975[9], T975[19], T975[30]) == (
        12.706,
        4.303,
        2.776,
        2.262,
        2.093,
        2.042,
    )
    # The expansion continues the table smoothly: just below t(0.975, 30) and above the normal quantile.
    assert 1.96 < t_quantile_975(31) < T975[30] and t_quantile_975(120) == pytest.approx(1.980, abs=5e-4)


def test_t_quantiles_agree_with_scipy() -> None:
    stats = pytest.importorskip("scipy.stats")  # a live comparison where scipy happens to be installed
    for df in [*range(1, 31), 31, 40, 60, 120, 1000]:
        assert t_quantile_975(df) == pytest.approx(float(stats.t.ppf(0.975, df)), abs=5e-4), df


def test_pairs_follow_the_common_seeds() -> None:
    runs = {
        "none": {0: {"rmse": 5.0}, 1: {"rmse": 6.0}, 2: {"rmse": 7.0}},
        "oracle": {
            0: {"rmse": 4.0},
            2: {"rmse": 6.5},
            3: {"rmse": 1.0},
        },  # seed 3 has no partner, seed 1 is missing
    }
    d = paired_differences(runs)["oracle"]["rmse"]
    assert d["seeds"] == [0, 2] and d["diffs"] == [-1.0, -0.5] and d["t"] == 12.706
    assert "| `oracle` | 2 | -0.7500 [" in paired_table(paired_differences(runs), ["rmse"])
    with pytest.raises(ValueError, match="reference"):
        paired_differences({"oracle": runs["oracle"]})
