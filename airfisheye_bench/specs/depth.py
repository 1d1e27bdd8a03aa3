"""Monocular depth (paper IV-B): range from the image, Eigen metrics up to 120 m."""

from __future__ import annotations

from airfisheye_bench.metrics import DepthMetrics
from airfisheye_bench.specs.base import Baseline, ExportSpec, MetricColumn, MetricOptions, TaskSpec
from airfisheye_bench.specs.formats import RANGE

#: The Eigen depth columns, shared with depth completion (same keys, labels and directions).
DEPTH_COLUMNS: dict[str, MetricColumn] = {
    c.key: c
    for c in (
        MetricColumn("abs_rel", "AbsRel", decimals=4),  # four decimals where the paper prints them (0.0834)
        MetricColumn("sq_rel", "SqRel"),
        MetricColumn("rmse", "RMSE (m)"),
        MetricColumn("rmse_log", "RMSE log"),
        MetricColumn("mae", "MAE (m)"),
        MetricColumn("delta1", "δ1", higher_is_better=True),
        MetricColumn("delta2", "δ2", higher_is_better=True),
        MetricColumn("delta3", "δ3", higher_is_better=True),
    )
}


def _metric(options: MetricOptions) -> DepthMetrics:
    return DepthMetrics(min_depth=options.min_depth, max_depth=options.max_depth)


DEPTH = TaskSpec(
    name="depth",
    title="Monocular depth",
    description="per-pixel range in metres from the fisheye image alone",
    inputs=("image",),
    target="depth",
    output="depth",
    metric=_metric,
    columns=tuple(
        DEPTH_COLUMNS[k] for k in ("abs_rel", "sq_rel", "rmse", "rmse_log", "delta1", "delta2", "delta3")
    ),
    primary_metric="rmse",
    prediction=RANGE,
    export=ExportSpec(
        metadata=("min_depth", "max_depth"),
        atol=1e-4,  # metres: relative, with a small absolute floor for values near 0
        rtol=1e-3,
        headline=("rmse", "abs_rel", "delta1"),
    ),
    baselines=(
        Baseline(
            "AdaBins / ResNet50",
            "paper Table II",
            {
                "abs_rel": 0.132,
                "sq_rel": 2.575,
                "rmse": 13.324,
                "rmse_log": 0.270,
                "delta1": 0.865,
                "delta2": 0.950,
                "delta3": 0.972,
            },
        ),
    ),
)
