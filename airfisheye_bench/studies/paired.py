"""Paired differences between training arms, with 95 % Student-t confidence intervals.

An ablation trains every arm with the same seeds (``trainer.deterministic=true``): seed ``s`` of two arms shares
its initial weights and data order, so the per-seed difference ``arm - reference`` removes what the seed alone
does, and its spread, not the spread of either arm, measures the noise. For ``n`` pairs with differences ``d``:
mean ``d̄``, sample standard deviation ``s`` (``n - 1``), interval ``d̄ ± t(0.975, n - 1) · s / √n``.

The quantile ``t(0.975, df)`` comes from :data:`T975` (df 1-30, three decimals, as in the NIST/SEMATECH
e-Handbook of Statistical Methods, section 1.3.6.7.2, "Critical Values of the Student's t Distribution"), and
beyond df 30 from the Cornish-Fisher expansion of Abramowitz & Stegun 26.7.5 (within 1e-7 of ``scipy.stats.t.ppf`` there); scipy is
not a dependency.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["T975", "paired_difference", "paired_differences", "paired_table", "t_quantile_975"]

#: Two-sided 95 % quantiles of Student's t, ``t(0.975, df)`` for df = 1..30 (NIST/SEMATECH table 1.3.6.7.2).
T975: dict[int, float] = {
    1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262, 10: 2.228,
    11: 2.201, 12: 2.179, 13: 2.160, 14: 2.145, 15: 2.131, 16: 2.120, 17: 2.110, 18: 2.101, 19: 2.093, 20: 2.086,
    21: 2.080, 22: 2.074, 23: 2.069, 24: 2.064, 25: 2.060, 26: 2.056, 27: 2.052, 28: 2.048, 29: 2.045, 30: 2.042,
}  # fmt: skip
_Z975 = 1.959963984540054  # the standard normal's 0.975 quantile


def t_quantile_975(df: int) -> float:
    """``t(0.975, df)``: the table for df <= 30, the Cornish-Fisher expansion (A&S 26.7.5) beyond.

    Example:
        >>> t_quantile_975(4), round(t_quantile_975(60), 3), round(t_quantile_975(10**6), 3)
        (2.776, 2.0, 1.96)
    """
    if isinstance(df, bool) or not isinstance(df, int) or df < 1:
        raise ValueError(f"degrees of freedom must be an integer >= 1, got {df!r}")
    if df in T975:
        return T975[df]
    z = _Z975
    g1 = (z**3 + z) / 4
    g2 = (5 * z**5 + 16 * z**3 + 3 * z) / 96
    g3 = (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / 384
    g4 = (79 * z**9 + 776 * z**7 + 1482 * z**5 - 1920 * z**3 - 945 * z) / 92160
    return z + g1 / df + g2 / df**2 + g3 / df**3 + g4 / df**4


def paired_difference(values: Sequence[float], reference: Sequence[float]) -> dict[str, Any]:
    """Mean of ``values[i] - reference[i]`` with its 95 % t-interval (NaN bounds for a single pair).

    Example:
        >>> out = paired_difference([6.0, 8.0, 10.0], [5.0, 6.0, 7.0])  # differences 1, 2, 3
        >>> out["mean"], out["std"], [round(b, 4) for b in out["ci95"]]
        (2.0, 1.0, [-0.4843, 4.4843])
    """
    if len(values) != len(reference):
        raise ValueError(f"paired values need equal lengths, got {len(values)} and {len(reference)}")
    if not values:
        raise ValueError("no pairs")
    diffs = [float(v) - float(r) for v, r in zip(values, reference, strict=True)]
    n = len(diffs)
    mean = sum(diffs) / n
    if n < 2:
        return {
            "n": n,
            "diffs": diffs,
            "mean": mean,
            "std": math.nan,
            "t": math.nan,
            "ci95": [math.nan, math.nan],
        }
    std = math.sqrt(sum((d - mean) ** 2 for d in diffs) / (n - 1))
    t = t_quantile_975(n - 1)
    half = t * std / math.sqrt(n)
    return {"n": n, "diffs": diffs, "mean": mean, "std": std, "t": t, "ci95": [mean - half, mean + half]}


def paired_differences(
    values: Mapping[str, Mapping[int, Mapping[str, float]]], reference: str = "none"
) -> dict[str, dict[str, dict[str, Any]]]:
    """``arm -> metric -> paired_difference`` against ``reference``, over the seeds both arms have.

    Args:
        values: ``{arm: {seed: {metric: value}}}``.
        reference: The arm every other is compared with.

    Example:
        >>> runs = {"none": {0: {"rmse": 5.0}, 1: {"rmse": 6.0}}, "zbuffer": {0: {"rmse": 4.5}, 1: {"rmse": 5.7}}}
        >>> d = paired_differences(runs)["zbuffer"]["rmse"]
        >>> d["seeds"], [round(x, 2) for x in d["diffs"]], round(d["mean"], 2)
        ([0, 1], [-0.5, -0.3], -0.4)
    """
    if reference not in values:
        raise ValueError(f"no runs of the reference arm {reference!r} (arms: {sorted(values)})")
    ref = values[reference]
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for arm, runs in values.items():
        if arm == reference:
            continue
        seeds = sorted(set(runs) & set(ref))
        metrics = sorted({m for s in seeds for m in runs[s]} & {m for s in seeds for m in ref[s]})
        out[arm] = {}
        for metric in metrics:
            paired = [s for s in seeds if metric in runs[s] and metric in ref[s]]
            if paired:
                result = paired_difference(
                    [runs[s][metric] for s in paired], [ref[s][metric] for s in paired]
                )
                out[arm][metric] = {"seeds": paired, **result}
    return out


def paired_table(
    differences: Mapping[str, Mapping[str, Mapping[str, Any]]],
    metrics: Sequence[str],
    reference: str = "none",
    arm: str = "arm",
) -> str:
    """Markdown: per arm, ``mean [lo, hi]`` of each metric's paired difference against ``reference`` (``n`` pairs);
    ``arm`` names what the rows are (the header reads ``arm − reference``)."""
    present = [m for m in metrics if any(m in d for d in differences.values())]
    lines = [
        f"| {arm} − {reference} | pairs | " + " | ".join(present) + " |",
        "|---|---|" + "---:|" * len(present),
    ]
    for arm, by_metric in differences.items():
        cells, n = [], 0
        for metric in present:
            d = by_metric.get(metric)
            if d is None:
                cells.append("-")
                continue
            n = max(n, d["n"])
            lo, hi = d["ci95"]
            cells.append(
                f"{d['mean']:+.4f}" if math.isnan(lo) else f"{d['mean']:+.4f} [{lo:+.4f}, {hi:+.4f}]"
            )
        lines.append(f"| `{arm}` | {n} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
