"""Paired differences with the flight as the unit, and a Holm correction over a family of them.

The frames of one flight are not independent: neighbouring frames look at the same buildings, so an arm that
does well on one of them does well on its neighbours. A trained ablation is therefore summarised with one number
per test flight (:func:`flight_means`: the mean over the flight's frames, then over the seeds) and a Student-t
interval over the flights (:func:`cluster_difference`): ``n`` is the number of flights, not of frames. Comparing
several arms on several metrics is a family of tests; :func:`holm` adjusts their p-values (Holm 1979, the
step-down Bonferroni: it controls the family-wise error rate at ``alpha`` with no assumption on how the tests
depend on each other), and :func:`cluster_difference` also gives the Bonferroni interval at the family's level,
the interval that goes with a Bonferroni-level decision.

The t distribution is computed here (scipy is not a dependency): the two-sided p-value from the regularised
incomplete beta function, ``p = I_{df/(df+t^2)}(df/2, 1/2)``, evaluated by its continued fraction (Numerical
Recipes, 3rd ed., section 6.4, ``betacf``), and quantiles by bisection on it; the tests compare both with
``scipy.stats.t`` where scipy is installed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = [
    "cluster_difference",
    "flight_means",
    "flight_of",
    "holm",
    "regularized_beta",
    "t_quantile",
    "t_two_sided_p",
]


#: The power at which a comparison's minimum detectable effect is stated.
MDE_POWER = 0.8


def flight_of(sample_id: str) -> str:
    """The flight (``<location>/<trajectory>``) of a sample id ``<location>/<trajectory>/<frame>``.

    Example:
        >>> flight_of("town/traj03/000004")
        'town/traj03'
    """
    parts = str(sample_id).split("/")
    if len(parts) < 2:
        raise ValueError(f"sample id {sample_id!r} is not <location>/<trajectory>/<frame>")
    return "/".join(parts[:-1])


def regularized_beta(a: float, b: float, x: float) -> float:
    """``I_x(a, b)``, the regularised incomplete beta function (continued fraction, modified Lentz).

    Example:
        >>> round(regularized_beta(2.0, 3.0, 0.4), 12)  # 1 - sum_{k<2} C(4,k) 0.4^k 0.6^(4-k)
        0.5248
    """
    if not 0.0 <= x <= 1.0:
        raise ValueError(f"x must be in [0, 1], got {x}")
    if x in (0.0, 1.0):
        return x
    log_front = math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log1p(-x)
    if x > (a + 1.0) / (a + b + 2.0):  # the fraction converges fast below this point: use the symmetry
        return 1.0 - regularized_beta(b, a, 1.0 - x)
    tiny, eps = 1e-300, 1e-15
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 500):
        for numerator in (
            m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m)),
            -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1)),
        ):
            d = 1.0 + numerator * d
            d = 1.0 / (d if abs(d) > tiny else tiny)
            c = 1.0 + numerator / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1.0) < eps:
            break
    return math.exp(log_front) * h / a


def t_two_sided_p(t: float, df: int) -> float:
    """``P(|T| >= |t|)`` for Student's t with ``df`` degrees of freedom.

    Example:
        >>> round(t_two_sided_p(2.262, 9), 4)  # the 97.5 % quantile at df 9
        0.05
    """
    if df < 1:
        raise ValueError(f"degrees of freedom must be >= 1, got {df}")
    if math.isnan(t):
        return math.nan
    if math.isinf(t):
        return 0.0
    return regularized_beta(df / 2.0, 0.5, df / (df + t * t))


def t_quantile(q: float, df: int) -> float:
    """The ``q`` quantile of Student's t (bisection on :func:`t_two_sided_p`; ``0 < q < 1``).

    Example:
        >>> round(t_quantile(0.975, 9), 3), round(t_quantile(0.025, 4), 3)
        (2.262, -2.776)
    """
    if not 0.0 < q < 1.0:
        raise ValueError(f"q must be in (0, 1), got {q}")
    if q == 0.5:
        return 0.0
    tail = 2.0 * min(q, 1.0 - q)  # the two-sided p-value of the quantile's magnitude
    lo, hi = 0.0, 1.0
    while t_two_sided_p(hi, df) > tail:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if t_two_sided_p(mid, df) > tail:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-12 * max(1.0, hi):
            break
    magnitude = 0.5 * (lo + hi)
    return magnitude if q > 0.5 else -magnitude


def minimum_detectable_effect(
    std: float, n: int, level: float = 0.95, power: float = 0.8, family_size: int = 1
) -> float:
    """The smallest true mean difference that a two-sided paired t-test over ``n`` clusters with this ``std``
    detects with probability ``power`` at level ``1 - level`` (Bonferroni-divided over ``family_size``
    comparisons), from the noncentral t distribution (exact for the t-test, not the normal approximation, which
    is optimistic for a handful of clusters). What a study could not have missed: an absence is stated with it.

    Example:
        >>> round(minimum_detectable_effect(1.0, 10), 3)  # 10 flights, 5 %, 80 % power: about one std
        0.996
        >>> round(minimum_detectable_effect(1.0, 10, family_size=20), 3)
        1.643
    """
    # scipy: the noncentral t's distribution function, needed only when a study is summarised
    from scipy.optimize import brentq
    from scipy.stats import nct
    from scipy.stats import t as student_t

    if n < 2 or math.isnan(std):
        return math.nan
    df, alpha = n - 1, (1.0 - level) / max(family_size, 1)
    critical = student_t.ppf(1.0 - alpha / 2.0, df)

    def shortfall(effect: float) -> float:  # power at a standardised effect, minus the target
        shift = effect * math.sqrt(n)
        wrong_side = float(
            nct.cdf(-critical, df, shift)
        )  # rejecting the other way: ~0, NaN where it underflows
        return float(nct.sf(critical, df, shift)) + (wrong_side if math.isfinite(wrong_side) else 0.0) - power

    # The approximation that adds the two t quantiles falls a little short of the power: the root lies above it.
    approximate = (critical + student_t.ppf(power, df)) / math.sqrt(n)
    return brentq(shortfall, approximate / 2.0, 2.0 * approximate, xtol=1e-10) * std


def cluster_difference(
    diffs: Mapping[str, float] | Sequence[float], family_size: int = 1, level: float = 0.95
) -> dict[str, Any]:
    """Mean of per-cluster differences with its t-interval over the clusters, p-value, and family interval.

    Args:
        diffs: One difference per cluster (flight), e.g. from :func:`flight_means`.
        family_size: How many comparisons the family holds (for the Bonferroni interval ``ci_family``).
        level: Confidence level of one interval.

    Returns:
        ``{"n", "mean", "std", "ci", "ci_family", "p", "clusters", "mde", "mde_family", "power"}`` (NaN bounds,
        p and minimum detectable effects for one cluster): ``mde`` is :func:`minimum_detectable_effect` of one
        comparison at 80 % power, ``mde_family`` at the family's Bonferroni level.

    Example:
        >>> d = cluster_difference({"a": 1.0, "b": 2.0, "c": 3.0}, family_size=4)
        >>> d["n"], d["mean"], [round(x, 4) for x in d["ci"]], round(d["p"], 4)
        (3, 2.0, [-0.4841, 4.4841], 0.0742)
    """
    values = list(diffs.values()) if isinstance(diffs, Mapping) else list(diffs)
    clusters = list(diffs) if isinstance(diffs, Mapping) else list(range(len(values)))
    n = len(values)
    if n == 0:
        raise ValueError("no clusters")
    mean = sum(values) / n
    out: dict[str, Any] = {
        "n": n,
        "mean": mean,
        "clusters": clusters,
        "level": level,
        "family_size": family_size,
    }
    if n < 2:
        return {
            **out,
            "std": math.nan,
            "ci": [math.nan] * 2,
            "ci_family": [math.nan] * 2,
            "p": math.nan,
            "mde": math.nan,
            "mde_family": math.nan,
            "power": MDE_POWER,
        }
    std = math.sqrt(sum((v - mean) ** 2 for v in values) / (n - 1))
    se = std / math.sqrt(n)
    alpha = 1.0 - level
    half = t_quantile(1.0 - alpha / 2.0, n - 1) * se
    half_family = t_quantile(1.0 - alpha / (2.0 * max(family_size, 1)), n - 1) * se
    p = t_two_sided_p(mean / se, n - 1) if se > 0 else (0.0 if mean != 0 else 1.0)
    return {
        **out,
        "std": std,
        "ci": [mean - half, mean + half],
        "ci_family": [mean - half_family, mean + half_family],
        "p": p,
        "mde": minimum_detectable_effect(std, n, level, MDE_POWER),
        "mde_family": minimum_detectable_effect(std, n, level, MDE_POWER, family_size),
        "power": MDE_POWER,
    }


def sign_test_p(values: Sequence[float]) -> float:
    """Exact two-sided sign test: the probability, with each nonzero value's sign a fair coin, of a split at least as
    uneven as ``values``' (zeros dropped; 1 when none is left). A secondary reading of a comparison: it counts
    flights, ignoring by how much each differs.

    Example:
        >>> sign_test_p([-1.0] * 10), sign_test_p([1.0, -1.0, 2.0])
        (0.001953125, 1.0)
    """
    signs = [v > 0 for v in values if v != 0]
    n, k = len(signs), sum(signs)
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, i) for i in range(min(k, n - k) + 1)) / 2.0**n
    return min(1.0, 2.0 * tail)


def holm(pvalues: Mapping[str, float]) -> dict[str, float]:
    """Holm's step-down adjusted p-values (``min(1, max over the smaller ones of (m - rank) p)``); NaN stays NaN
    and does not count in the family.

    Example:
        >>> holm({"a": 0.01, "b": 0.04, "c": 0.03})
        {'a': 0.03, 'b': 0.06, 'c': 0.06}
    """
    finite = sorted((p, k) for k, p in pvalues.items() if not math.isnan(p))
    m = len(finite)
    adjusted: dict[str, float] = {k: math.nan for k in pvalues}
    running = 0.0
    for rank, (p, key) in enumerate(finite):
        running = max(running, min(1.0, (m - rank) * p))
        adjusted[key] = round(running, 15)
    return {k: adjusted[k] for k in pvalues}


def flight_means(per_frame: Mapping[str, float]) -> dict[str, float]:
    """``{flight: mean over its frames}`` of per-frame values keyed by sample id.

    Example:
        >>> flight_means({"town/traj00/000001": 1.0, "town/traj00/000002": 3.0, "town/traj01/000001": 5.0})
        {'town/traj00': 2.0, 'town/traj01': 5.0}
    """
    sums: dict[str, list[float]] = {}
    for sample_id, value in per_frame.items():
        sums.setdefault(flight_of(sample_id), []).append(float(value))
    return {flight: sum(v) / len(v) for flight, v in sorted(sums.items())}
