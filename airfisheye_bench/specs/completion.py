"""Depth completion (paper IV-C): range from the image and occlusion-corrected sparse LiDAR depth, NLSPN metrics."""

from __future__ import annotations

from airfisheye_bench.metrics import CompletionMetrics
from airfisheye_bench.specs.base import Baseline, ExportSpec, MetricOptions, TaskSpec
from airfisheye_bench.specs.depth import DEPTH_COLUMNS
from airfisheye_bench.specs.formats import RANGE


def _metric(options: MetricOptions) -> CompletionMetrics:
    # NLSPN's own lower bound (COMPLETION_VALID_MIN) applies; min_depth is not an option of this metric.
    return CompletionMetrics(max_depth=options.max_depth)


COMPLETION = TaskSpec(
    name="completion",
    title="Depth completion",
    description="per-pixel range in metres from the fisheye image and the projected LiDAR scan",
    inputs=("image", "sparse_depth"),
    target="depth",
    output="depth",
    metric=_metric,
    columns=tuple(DEPTH_COLUMNS[k] for k in ("abs_rel", "rmse", "mae", "delta1", "delta2", "delta3")),
    primary_metric="rmse",
    prediction=RANGE,
    requires=("lidar",),
    export=ExportSpec(
        metadata=("min_depth", "max_depth", "occlusion"),
        atol=1e-4,
        rtol=1e-3,
        headline=("rmse", "mae", "abs_rel", "delta1"),
    ),
    baselines=(
        Baseline(
            "NLSPN / ResNet34",
            "paper Table II",
            {
                "abs_rel": 0.0834,
                "rmse": 6.971,
                "mae": 2.377,
                "delta1": 0.934,
                "delta2": 0.971,
                "delta3": 0.983,
            },
        ),
    ),
)
