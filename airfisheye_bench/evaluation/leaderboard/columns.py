"""How the leaderboard shows a metric: its title, direction, percent and decimals (from the task specs), and the
ring/range breakdown keys (``ring_80-95/rmse``)."""

from __future__ import annotations

import re
from collections.abc import Mapping

from airfisheye_bench.specs import MetricColumn, all_tasks

__all__ = [
    "BIN_KEY",
    "MISSING",
    "breakdown_bins",
    "format_value",
    "higher_is_better",
    "is_percent",
    "metric_column",
    "metric_label",
    "rim_label",
]

#: A breakdown key: ``ring_<lo>-<hi>/<metric>`` (incidence angle, degrees) or ``range_<lo>-<hi>/<metric>`` (metres).
BIN_KEY = re.compile(r"^(?P<kind>ring|range)_(?P<lo>\d+(?:\.\d+)?)-(?P<hi>\d+(?:\.\d+)?)/(?P<metric>.+)$")
MISSING = "–"


def metric_column(metric: str) -> MetricColumn | None:
    """How the leaderboard shows ``metric``: the first registered task with a headline column of that key."""
    return next((c for spec in all_tasks() if (c := spec.column(metric)) is not None), None)


def metric_label(metric: str) -> str:
    """Column title of a metric (``rmse`` -> ``RMSE (m)``); metrics no task heads show their key."""
    column = metric_column(metric)
    return column.label if column is not None else metric


def higher_is_better(metric: str) -> bool:
    """Whether a larger ``metric`` is better (unknown metrics rank ascending, like errors)."""
    column = metric_column(metric)
    return column is not None and column.higher_is_better


def is_percent(metric: str) -> bool:
    """Whether ``metric`` prints as a percentage (its task column says so; files keep fractions)."""
    column = metric_column(metric)
    return column is not None and column.percent


def format_value(metric: str, value: float | None) -> str:
    """A metric value as the tables print it: percent where the task's column says so, the paper's decimals.

    Example:
        >>> format_value("mIoU", 0.512), format_value("abs_rel", 0.0834), format_value("rmse", None)
        ('51.2', '0.0834', '–')
    """
    if value is None:
        return MISSING
    if is_percent(metric):
        return f"{100.0 * value:.1f}"
    column = metric_column(metric)
    return f"{value:.{column.decimals if column is not None else 3}f}"


def rim_label(rim_key: str) -> str:
    """The column title of a rim ring key, e.g. ``ring_80-95/rmse`` -> ``rim 80-95° RMSE (m)``."""
    match = BIN_KEY.match(rim_key)
    assert match is not None
    return f"rim {match['lo']}-{match['hi']}° {metric_label(match['metric'])}"


def breakdown_bins(
    breakdown: Mapping[str, float | None], kind: str, metric: str
) -> list[tuple[float, float, float | None]]:
    """``(lo, hi, value)`` of ``metric`` in each ``ring`` (incidence angle) or ``range`` (depth) bin, in order.

    Example:
        >>> breakdown_bins({"ring_30-60/rmse": 5.0, "ring_0-30/rmse": 4.0, "range_0-10/rmse": 1.0}, "ring", "rmse")
        [(0.0, 30.0, 4.0), (30.0, 60.0, 5.0)]
    """
    bins = []
    for key, value in breakdown.items():
        match = BIN_KEY.match(key)
        if match and match["kind"] == kind and match["metric"] == metric:
            bins.append((float(match["lo"]), float(match["hi"]), value))
    return sorted(bins, key=lambda b: (b[0], b[1]))
